//! Forwarding every vehicle's MAVLink to a ground station and its commands back
//! (`--gcs-forward` over `[gcs] forward`; setpoints from the ground station are dropped).

use super::options::UpArgs;
use crate::config::ConfigFile;
use skein_swarm::Swarm;
use std::sync::Arc;

/// Starts the forward `args` or `file` asks for (`None` without one); dropping the
/// forwarder stops it.
///
/// # Errors
/// The ground station's connection cannot be opened.
pub(super) async fn forward(
    args: &UpArgs,
    file: &ConfigFile,
    swarm: &Swarm,
) -> Result<Option<Arc<skein_link::GcsForwarder>>, String> {
    let Some(addr) = args
        .gcs_forward
        .clone()
        .or(file.gcs.forward.clone().map(|c| c.0))
    else {
        return Ok(None);
    };
    let fwd = swarm
        .forward_to_gcs(addr)
        .await
        .map_err(|e| e.to_string())?;
    println!(
        "skein: forwarding MAVLink to the ground station at {}",
        fwd.address()
    );
    Ok(Some(fwd))
}
