//! `skein up`: the single-process swarm (coordinator, local vehicles, the simulator,
//! plugins, the API and dashboard, and with `--dds` the ROS 2 topics): the composition
//! of [`crate::compose`] in its [`Role::Up`] role, every option a flag ([`UpArgs`]).

use crate::compose::{Role, run};
use std::process::ExitCode;

pub(crate) use crate::compose::UpArgs;

/// Runs the single-process swarm until a signal or its coordinator's failure.
///
/// # Errors
/// A bad config or option (named), a port in use, a part that cannot start.
pub async fn up(args: UpArgs) -> Result<ExitCode, String> {
    run(Role::Up, args).await
}
