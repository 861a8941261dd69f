//! The air picture: the tracker's tracks with their forecasts and the hostile swarms they
//! form, made at every tracker step, in the live service and in the bench's replay alike.

use super::forecast::Forecaster;
use super::swarms::{GroupingConfig, SwarmRecognizer};
use skein_protocol::tracks::{HostileSwarmEvent, SwarmView, TrackView};

/// Forecasts and swarm recognition over a tracker's tracks.
#[derive(Debug)]
pub struct AirPicture {
    forecaster: Forecaster,
    recognizer: SwarmRecognizer,
}

impl AirPicture {
    /// An empty picture with this grouping.
    pub fn new(grouping: GroupingConfig) -> Self {
        AirPicture {
            forecaster: Forecaster::default(),
            recognizer: SwarmRecognizer::new(grouping),
        }
    }

    /// The tracks as of `now_us` (wall-clock µs) get their `forecast` and `swarm`;
    /// returns the swarms now and what happened to them.
    pub fn update(
        &mut self,
        now_us: u64,
        tracks: &mut [TrackView],
    ) -> (Vec<SwarmView>, Vec<HostileSwarmEvent>) {
        self.forecaster.update(now_us, tracks);
        let events = self.recognizer.step(now_us, tracks);
        (self.recognizer.swarms(), events)
    }
}
