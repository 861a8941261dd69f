//! `skein coordinator`: a coordinator candidate with no vehicles of its own. It runs the
//! coordinator actor, the API and dashboard, and the DDS link, and takes part in the
//! coordinator election on `/skein/coordinator` (`skein_swarm::election`): the live
//! candidate of highest priority is active; a standby's API answers reads and refuses
//! writes with a 409 naming the active one.
//!
//! The composition of [`crate::compose`] in its [`Role::Coordinator`] role: `skein up`'s
//! options at their defaults, then this command's.

use crate::compose::{Candidate, Role, UpArgs, hostname, run};
use clap::Args;
use std::net::{IpAddr, SocketAddr};
use std::path::PathBuf;
use std::process::ExitCode;

/// Command line of `skein coordinator`.
#[derive(Args, Debug)]
pub struct CoordinatorArgs {
    /// Election priority: the live candidate with the highest is active (equal: the
    /// smaller id).
    #[arg(long, value_name = "P", default_value_t = 1, env = "SKEIN_PRIORITY")]
    priority: u32,
    /// Id on `/skein/coordinator` (default `<hostname>-<pid>`).
    #[arg(long, value_name = "ID", env = "SKEIN_ID")]
    id: Option<String>,
    /// Configuration file (TOML): `[http]` tokens and TLS, `[dds]`, swarm settings.
    #[arg(long, value_name = "FILE", env = "SKEIN_CONFIG")]
    config: Option<PathBuf>,
    /// Listen address of the HTTP API and dashboard (port 0 picks a free port).
    #[arg(long, value_name = "ADDR:PORT", env = "SKEIN_HTTP")]
    http: Option<SocketAddr>,
    /// The DDS domain, 0 to 232 (default `[dds] domain_id`, else `ROS_DOMAIN_ID`, else 0).
    #[arg(long, value_name = "D", value_parser = skein_dds::parse_domain_id)]
    domain_id: Option<u16>,
    /// Use only the interface with this local address for DDS (repeatable).
    #[arg(long, value_name = "ADDR")]
    dds_network: Vec<IpAddr>,
    #[command(flatten)]
    dds_security: super::dds::DdsSecurityArgs,
    /// Listen on a non-loopback address without any `[[http.tokens]]` (refused without
    /// this flag).
    #[arg(long)]
    insecure_no_auth: bool,
}

/// Runs a coordinator candidate until a signal or the coordinator's failure.
///
/// # Errors
/// As `skein up`: a bad config, a port in use, DDS that cannot start.
pub async fn coordinator(args: CoordinatorArgs) -> Result<ExitCode, String> {
    let id = match args.id {
        Some(id) if id.trim().is_empty() => return Err("--id: empty".into()),
        Some(id) => id,
        None => format!("{}-{}", hostname(), std::process::id()),
    };
    // `skein up`'s options at their defaults, then this role's.
    let mut up_args = UpArgs::for_role(
        args.config,
        args.http,
        args.domain_id,
        args.dds_network,
        args.dds_security,
    )?;
    up_args.insecure_no_auth = args.insecure_no_auth;
    let candidate = Candidate {
        id,
        priority: args.priority,
    };
    run(Role::Coordinator(candidate), up_args).await
}
