//! Recording the run to MCAP: the recorder every role has (`POST
//! /api/v1/recording/start` records on demand), started at once with `--record FILE`,
//! and finished before the process exits.

use super::options::UpArgs;
use crate::config::ConfigFile;
use skein_record::Recorder;
use skein_swarm::Swarm;
use std::path::PathBuf;
use std::sync::Arc;

/// The recorder of `swarm`, writing to `[recording] dir` (default `recordings`); with
/// `--record` it is recording already.
///
/// # Errors
/// The `--record` file cannot be created (it exists, or its directory is not writable).
pub(super) fn start(
    args: &UpArgs,
    file: &ConfigFile,
    swarm: &Swarm,
) -> Result<Arc<Recorder>, String> {
    let recorder = Recorder::new(
        skein_record::Sources {
            coordinator: swarm.coordinator.clone(),
            events: swarm.events.clone(),
            endpoints: swarm.endpoints.clone(),
        },
        file.recording
            .dir
            .clone()
            .unwrap_or_else(|| PathBuf::from("recordings")),
    );
    if let Some(path) = &args.record {
        let info = recorder
            .start(None, Some(path))
            .map_err(|e| format!("--record {}: {e}", path.display()))?;
        println!("skein: recording to {}", info.path.display());
    }
    Ok(recorder)
}

/// Finishes the recording in progress, if any, and prints what it holds.
pub(super) async fn finish(recorder: &Recorder) {
    if recorder.status().is_none() {
        return;
    }
    match recorder.stop().await {
        Ok(s) => println!(
            "skein: recording {} finished: {} messages on {} channels, {:.1} s",
            s.path.display(),
            s.messages,
            s.channels,
            s.duration_s
        ),
        Err(e) => eprintln!("skein: the recording could not be finished: {e}"),
    }
}
