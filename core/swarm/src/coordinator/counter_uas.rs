//! What the coordinator is told about the counter-UAS air picture ([`TrackingMsg`]): the
//! tracks and hostile swarms, the vehicles observing them ([`super::observe`],
//! [`super::stations`]), and the embedded simulator's ground truth to compare them with.

use super::CoordinatorState;
use super::messages::TracksAnswer;
use super::observe::{ObserveRefusal, ObserveSpec};
use ractor::RpcReplyPort;

/// Messages about tracking and observation (inside [`super::CoordinatorMsg::Tracking`]).
pub enum TrackingMsg {
    /// The counter-UAS tracks now and which vehicle observes which track (the DDS
    /// tracks topic; the API reads them from [`super::SwarmReads`]).
    GetTracks(RpcReplyPort<TracksAnswer>),
    /// Point the gimbals of the vehicles (default: all with a gimbal) at a track or swarm
    /// and keep them on it, and with `stations` fly them to the stations that fix it
    /// best; answers the observing vehicles.
    Observe(
        ObserveSpec,
        RpcReplyPort<Result<Vec<String>, ObserveRefusal>>,
    ),
    /// Stop observing a track or swarm; answers the vehicles released.
    StopObserving(String, RpcReplyPort<Vec<String>>),
    /// The in-process simulator's ground truth (`GET /api/v1/sim/truth`); `None` when no
    /// simulator is embedded.
    GetSimTruth(RpcReplyPort<Option<serde_json::Value>>),
}

impl CoordinatorState {
    /// Handles a [`TrackingMsg`].
    pub(super) fn handle_tracking(&mut self, msg: TrackingMsg) {
        match msg {
            TrackingMsg::GetTracks(reply) => {
                let _ = reply.send((self.tracking.shared().tracks(), self.observations()));
            }
            TrackingMsg::Observe(spec, reply) => {
                let _ = reply.send(self.observe(spec));
            }
            TrackingMsg::StopObserving(track, reply) => {
                let _ = reply.send(self.stop_observing(&track));
            }
            TrackingMsg::GetSimTruth(reply) => {
                let truth = self
                    .context
                    .simulator()
                    .map(|sim| sim.truth(self.context.frame().as_ref()))
                    .filter(|v| !v.is_null());
                let _ = reply.send(truth);
            }
        }
    }
}
