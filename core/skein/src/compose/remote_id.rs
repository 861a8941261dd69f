//! Remote ID's operator location from the ground station's own GNSS receiver
//! (`[remote_id] operator_gnss`): one reader per process, started before the swarm and
//! handed to every vehicle link through the swarm's `LinkSetup`, so that each link reads
//! the latest fix without waiting and the receiver is opened once however many vehicles
//! there are.
//!
//! `skein agent` refuses it: an agent runs on an aircraft's companion computer, whose
//! receiver is the aircraft's, so its position sent as the operator's live location
//! would put the remote pilot in the air. An agent sends `operator_location` (FIXED) or
//! each vehicle's takeoff point (TAKEOFF).

use super::role::Role;
use crate::config::ConfigFile;
use skein_gnss::GnssReader;
use skein_swarm::SwarmConfig;

/// Starts the reader of `[remote_id] operator_gnss`, if configured, and gives it to
/// every vehicle's link (`config.link_setup`).
///
/// # Errors
/// `operator_gnss` in an agent's config.
pub(super) fn start_operator_gnss(
    role: &Role,
    file: &ConfigFile,
    config: &mut SwarmConfig,
) -> Result<(), String> {
    let Some(source) = file
        .remote_id
        .as_ref()
        .and_then(|r| r.operator_gnss.clone())
    else {
        return Ok(());
    };
    if role.agent().is_some() {
        return Err(format!(
            "remote_id.operator_gnss = \"{source}\": `skein agent` runs on an aircraft's \
             companion computer, whose GNSS receiver is the aircraft's, not the operator's; \
             sent as the operator's live location (LIVE_GNSS) it would be false. Give the \
             agent `operator_location` (FIXED) or leave both out (each vehicle's takeoff point)"
        ));
    }
    println!("skein: Remote ID operator location from {source} while it has a fix");
    config.link_setup.operator_gnss = Some(GnssReader::start(source));
    Ok(())
}
