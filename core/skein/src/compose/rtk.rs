//! RTK corrections (`[rtk]`, `PUT /api/v1/rtk`): every role runs a corrections service
//! for the vehicles of its process, idle until a source is configured; with `[rtk]` it
//! connects at start. The API serves it ([`skein_api::rtk`]).

use crate::config::ConfigFile;
use skein_rtk::RtkService;
use skein_swarm::Swarm;
use std::sync::Arc;

/// Starts the corrections service for `swarm`'s vehicles, connecting to `[rtk] source`
/// when the config has one.
///
/// # Errors
/// A bad `[rtk]` (checked when the config was read; named again here).
pub(super) fn start(file: &ConfigFile, swarm: &Swarm) -> Result<Arc<RtkService>, String> {
    let fleet = swarm.fleet.clone();
    let rtk = Arc::new(RtkService::start(Arc::new(move || fleet.links())));
    if let Some(config) = &file.rtk {
        rtk.configure(Some(config))
            .map_err(|e| format!("rtk.{}: {}", e.field, e.error))?;
        println!("skein: RTK corrections from {}", config_source(config));
    }
    Ok(rtk)
}

/// The configured source with its password hidden.
fn config_source(config: &skein_rtk::RtkConfig) -> String {
    config
        .source
        .parse::<skein_rtk::Source>()
        .map_or_else(|_| "an unreadable source".into(), |s| s.redacted())
}
