//! What the coordinator publishes for readers that must not wait in its mailbox: the
//! API's pure reads (issue 48). A read of the vehicles, the formation, the supervision
//! tree or the air picture takes the latest published value; it never queues behind the
//! formation tick, `/metrics` or an operator's write. Writes still go through the actor.
//!
//! - **Vehicles**: the list of vehicles (each a [`VehicleReadout`], the `watch`
//!   channels its actor or its agent's carrier writes), published when a vehicle joins; a
//!   read takes each vehicle's snapshot as it is now.
//! - **Formation** ([`FormationStatus`]) and the coordinator's part of the **air
//!   picture** (who observes what, the stations): published after every message the
//!   coordinator handles that may change them (every one but the distributed roles'
//!   high-rate traffic, see [`CoordinatorMsg::may_change_reads`]), the formation tick
//!   included, so at least at the formation rate.
//! - The **supervision tree** and the tracker's **tracks and swarms** are registries of
//!   their own ([`Supervision`], [`TrackingShared`]), read directly.
//!
//! Read after write: a write's answer comes from inside the coordinator's handler, before
//! it publishes. The API therefore asks the coordinator once more (a `Ping`, behind the
//! write in the mailbox) before it answers a write ([`SwarmReads`] docs), so a client
//! that was answered a write reads what the write did.
//!
//! Not here, on purpose: `GET /api/v1/health` asks the coordinator (its `ok` says that
//! the coordinator answers), and `/metrics`, link counters, the geofence, a payload's
//! view, a vehicle's link and the simulator's truth are computed on demand from state
//! only the actor holds.

use super::messages::CoordinatorMsg;
use super::proxy::VehicleReadout;
use super::stations::StationsView;
use crate::formation::FormationStatus;
use crate::supervision::{Supervision, TreeNode};
use crate::tracking::TrackingShared;
use crate::tracks::{SwarmView, TrackView};
use skein_model::vehicle::VehicleSnapshot;
use std::collections::BTreeMap;
use std::sync::Arc;
use tokio::sync::watch;

/// Who observes what: (vehicle id, track or swarm id) pairs, and the observations flown
/// on stations.
#[derive(Debug, Clone, Default)]
pub struct Observations {
    /// Which vehicle observes which track or swarm (vehicle id, target id).
    pub observing: Vec<(String, String)>,
    /// The observations flown on stations.
    pub stations: Vec<StationsView>,
}

/// The air picture as `GET /api/v1/tracks` and `GET /api/v1/swarms` show it.
#[derive(Debug, Clone, Default)]
pub struct AirPicture {
    /// The tracks, with their forecasts and swarms.
    pub tracks: Vec<TrackView>,
    /// The hostile swarms.
    pub swarms: Vec<SwarmView>,
    /// Who observes what, and from which stations.
    pub observations: Arc<Observations>,
}

/// The API's side: the latest published values (see the module docs). Cheap to clone.
#[derive(Clone)]
pub struct SwarmReads {
    vehicles: watch::Receiver<Arc<BTreeMap<String, VehicleReadout>>>,
    formation: watch::Receiver<Arc<FormationStatus>>,
    observations: watch::Receiver<Arc<Observations>>,
    supervision: Arc<Supervision>,
    tracking: Arc<TrackingShared>,
}

impl SwarmReads {
    /// The reads of a swarm with no vehicle, no formation and no track: a router without
    /// a coordinator (the API's router tests).
    pub fn idle() -> SwarmReads {
        let (events, _) = tokio::sync::broadcast::channel(1);
        let supervision = Supervision::new(
            crate::supervision::SupervisionConfig::default(),
            Arc::new(crate::load::LoadMonitor::default()),
            Arc::new(crate::metrics::Metrics::new()),
            events,
        );
        let formation =
            crate::formation::FormationEngine::new(crate::formation::DEFAULT_SEPARATION_M)
                .status_with(&[], &BTreeMap::new());
        Publisher::new(formation, supervision, Arc::new(TrackingShared::default())).reads()
    }

    /// Every vehicle's snapshot now, sorted by id.
    pub fn vehicles(&self) -> Vec<VehicleSnapshot> {
        let list = self.vehicles.borrow().clone();
        list.values().map(VehicleReadout::snapshot).collect()
    }

    /// Vehicle `id`'s snapshot now; `None` for an unknown id.
    pub fn vehicle(&self, id: &str) -> Option<VehicleSnapshot> {
        let list = self.vehicles.borrow().clone();
        list.get(id).map(VehicleReadout::snapshot)
    }

    /// The formation as last published (at least at the formation rate).
    pub fn formation(&self) -> FormationStatus {
        (**self.formation.borrow()).clone()
    }

    /// The supervision tree now.
    pub fn supervision(&self) -> TreeNode {
        self.supervision.tree()
    }

    /// The tracker's tracks and swarms now, and the observations as last published.
    pub fn air_picture(&self) -> AirPicture {
        AirPicture {
            tracks: self.tracking.tracks(),
            swarms: self.tracking.swarms(),
            observations: self.observations.borrow().clone(),
        }
    }
}

/// The coordinator's side: publishes what [`SwarmReads`] read.
pub(super) struct Publisher {
    vehicles: watch::Sender<Arc<BTreeMap<String, VehicleReadout>>>,
    formation: watch::Sender<Arc<FormationStatus>>,
    observations: watch::Sender<Arc<Observations>>,
    reads: SwarmReads,
}

impl Publisher {
    /// A publisher whose formation reads `formation` until the first publication.
    pub(super) fn new(
        formation: FormationStatus,
        supervision: Arc<Supervision>,
        tracking: Arc<TrackingShared>,
    ) -> Publisher {
        let (vehicles, vehicles_rx) = watch::channel(Arc::new(BTreeMap::new()));
        let (formation, formation_rx) = watch::channel(Arc::new(formation));
        let (observations, observations_rx) = watch::channel(Arc::new(Observations::default()));
        Publisher {
            vehicles,
            formation,
            observations,
            reads: SwarmReads {
                vehicles: vehicles_rx,
                formation: formation_rx,
                observations: observations_rx,
                supervision,
                tracking,
            },
        }
    }

    /// A reader of what this publishes.
    pub(super) fn reads(&self) -> SwarmReads {
        self.reads.clone()
    }

    /// The vehicles, after one joined.
    pub(super) fn vehicles(&self, list: BTreeMap<String, VehicleReadout>) {
        self.vehicles.send_replace(Arc::new(list));
    }

    /// The formation and the observations, after a message that may have changed them.
    pub(super) fn state(&self, formation: FormationStatus, observations: Observations) {
        self.formation.send_replace(Arc::new(formation));
        self.observations.send_replace(Arc::new(observations));
    }
}

impl CoordinatorMsg {
    /// False for the distributed roles' high-rate traffic, which changes nothing the
    /// coordinator publishes (a neighbour's report, a message for a local vehicle, the
    /// carrier's own reads): the coordinator publishes after every other message.
    pub(super) fn may_change_reads(&self) -> bool {
        use super::distributed::DistributedMsg as D;
        use super::fleet::FleetMsg as F;
        !matches!(
            self,
            CoordinatorMsg::Distributed(
                D::Neighbour(..)
                    | D::ToLocalVehicle(..)
                    | D::ListReports(..)
                    | D::GetContext(..)
                    | D::GetFormationMirror(..)
            ) | CoordinatorMsg::Fleet(F::ListVehicles(..))
        )
    }
}

#[cfg(test)]
mod tests {
    use crate::coordinator::AdminMsg;
    use crate::coordinator::swarm::tests::{px4_heartbeats, swarm_on_udp};
    use skein_model::supervision::FaultKind;
    use std::time::{Duration, Instant};

    /// The reads answer from what the coordinator published, also while it answers
    /// nothing: a vehicle that joined is listed, and still is, with the formation, the
    /// supervision tree and the air picture, after the coordinator's handler hangs (an
    /// injected fault: its mailbox stuck), when a question through the mailbox times out.
    /// Were a read an `ask`, it would hang with the coordinator.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn reads_answer_what_was_published_while_the_coordinator_hangs() {
        let swarm = swarm_on_udp().await;
        let reads = swarm.reads.clone();
        assert!(reads.vehicles().is_empty());
        let mut heartbeat = px4_heartbeats(&swarm);
        let deadline = Instant::now() + Duration::from_secs(10);
        while reads.vehicles().len() != 1 {
            heartbeat();
            assert!(Instant::now() < deadline, "the vehicle was never published");
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        let id = reads.vehicles()[0].id.clone();
        assert_eq!(reads.vehicle(&id).map(|v| v.id), Some(id.clone()));
        assert!(reads.vehicle("nobody").is_none());

        let before = reads.formation();
        swarm
            .coordinator
            .cast(AdminMsg::Fault(FaultKind::Hang).into())
            .expect("cast");
        let asked = swarm
            .coordinator
            .call(
                |r| AdminMsg::Health(r).into(),
                Some(Duration::from_millis(500)),
            )
            .await;
        assert!(
            !matches!(asked, Ok(ractor::rpc::CallResult::Success(_))),
            "the hung coordinator answered"
        );
        assert_eq!(reads.vehicles().len(), 1);
        assert_eq!(reads.formation(), before);
        assert_eq!(reads.supervision().path, crate::supervision::ROOT);
        assert!(reads.air_picture().tracks.is_empty());
        swarm.coordinator.stop(None);
    }
}
