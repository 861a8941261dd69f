//! The one place where the DDS roles meet `skein_swarm`'s coordinator actor: the
//! [`SwarmAdapter`] implements every role's context ([`ElectionContext`],
//! [`AgentContext`], [`RemoteContext`], [`MirrorContext`], [`VehiclesContext`],
//! [`TfContext`]) with
//! messages to the coordinator (`CoordinatorMsg`, `DistributedMsg`), its swarm context (the
//! frame), its event bus and its metrics. When the coordinator's messages or its view
//! change, this file changes; the roles do not.

use crate::agent::AgentContext;
use crate::counters::DdsCounters;
use crate::lease::{ElectionContext, RoleChange};
use crate::mirror::MirrorContext;
use crate::reframe::{FrameSource, SwarmFrame};
use crate::remote::{RemoteContext, RemoteJoin};
use crate::tf::TfContext;
use crate::vehicles::VehiclesContext;
use ractor::ActorRef;
use ractor::rpc::CallResult;
use skein_model::geo::{GeoPoint, NedFrame};
use skein_model::vehicle::VehicleSnapshot;
use skein_swarm::SwarmContext;
use skein_swarm::coordinator::missions::MissionMirror;
use skein_swarm::election::CoordinatorRole;
use skein_swarm::formation::FormationMirror;
use skein_swarm::load::{LoadMonitor, ShedWork};
use skein_swarm::metrics::Metrics;
use skein_swarm::protocol::{FromVehicle, ToVehicle, VehicleReport};
use skein_swarm::tracks::TrackView;
use skein_swarm::{
    AdminMsg, Command, CommandMsg, CoordinatorMsg, DistributedMsg, FleetMsg, RemoteVehicle,
    SwarmEvent, TrackingMsg,
};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::{broadcast, mpsc};

/// How long a coordinator query may take before the role's tick is skipped.
const COORDINATOR_TIMEOUT: Duration = Duration::from_secs(1);

/// How long a command from `/skein/<vehicle>/command` may wait for the coordinator.
const COMMAND_TIMEOUT: Duration = Duration::from_secs(5);

/// The roles' contexts on this process's coordinator actor (see the module docs).
pub struct SwarmAdapter {
    coordinator: ActorRef<CoordinatorMsg>,
    metrics: Arc<Metrics>,
    events: broadcast::Sender<SwarmEvent>,
    /// The process's load monitor, asked of the coordinator once.
    load: std::sync::OnceLock<Arc<LoadMonitor>>,
}

impl SwarmAdapter {
    /// The contexts on `coordinator`, its `metrics` and its event bus `events`.
    pub fn new(
        coordinator: ActorRef<CoordinatorMsg>,
        metrics: Arc<Metrics>,
        events: broadcast::Sender<SwarmEvent>,
    ) -> Self {
        SwarmAdapter {
            coordinator,
            metrics,
            events,
            load: std::sync::OnceLock::new(),
        }
    }

    /// Asks the coordinator; `None` when it does not answer within
    /// [`COORDINATOR_TIMEOUT`].
    async fn ask<T: Send + 'static>(
        &self,
        msg: impl FnOnce(ractor::RpcReplyPort<T>) -> CoordinatorMsg,
    ) -> Option<T> {
        match self.coordinator.call(msg, Some(COORDINATOR_TIMEOUT)).await {
            Ok(CallResult::Success(v)) => Some(v),
            _ => None,
        }
    }

    fn distributed(&self, msg: DistributedMsg) {
        let _ = self.coordinator.cast(msg.into());
    }

    /// Copies `counters` into `/metrics` (`skein_dds_samples{what=...}`), and this
    /// process's DDS Security refusals (`skein_dds_security_refusals{reason=...}`, every
    /// reason, zeros too).
    pub fn export_counters(&self, counters: &DdsCounters) {
        for (what, n) in counters.values() {
            self.metrics
                .dds_samples
                .get_or_create(&Metrics::label("what", what))
                .set(n as i64);
        }
        for (reason, n) in crate::security::refusals::counts() {
            self.metrics
                .dds_security_refusals
                .get_or_create(&Metrics::label("reason", reason.name()))
                .set(n as i64);
        }
    }
}

/// The coordinator's swarm context holds this process's frame.
impl SwarmFrame for SwarmContext {
    fn frame(&self) -> Option<NedFrame> {
        SwarmContext::frame(self)
    }

    fn anchor(&self, origin: GeoPoint) -> NedFrame {
        SwarmContext::anchor(self, origin)
    }
}

impl FrameSource for SwarmAdapter {
    async fn swarm_frame(&self) -> Option<Arc<dyn SwarmFrame>> {
        let view: Arc<SwarmContext> = self.ask(|r| DistributedMsg::GetContext(r).into()).await?;
        Some(view)
    }
}

impl ElectionContext for SwarmAdapter {
    fn role_changed(&self, change: RoleChange) {
        if change.role == CoordinatorRole::Standby {
            let reason = change.reason.clone().unwrap_or_default();
            self.distributed(DistributedMsg::SteppedDown(reason));
        }
        let _ = self.events.send(SwarmEvent::CoordinatorRoleChanged {
            coordinator_id: change.coordinator_id,
            role: change.role,
            epoch: change.epoch,
            reason: change.reason,
        });
    }
}

impl AgentContext for SwarmAdapter {
    async fn reports(&self) -> Option<Vec<(String, VehicleReport)>> {
        self.ask(|r| DistributedMsg::ListReports(r).into()).await
    }

    async fn snapshots(&self) -> Option<Vec<VehicleSnapshot>> {
        self.ask(|r| FleetMsg::ListVehicles(r).into()).await
    }

    fn to_vehicle(&self, vehicle_id: String, msg: ToVehicle) {
        self.distributed(DistributedMsg::ToLocalVehicle(vehicle_id, msg));
    }

    fn neighbour(&self, vehicle_id: String, report: VehicleReport) {
        self.distributed(DistributedMsg::Neighbour(vehicle_id, report));
    }

    fn tap_uplink(&self) -> mpsc::UnboundedReceiver<FromVehicle> {
        let (tap, uplink) = mpsc::unbounded_channel();
        self.distributed(DistributedMsg::TapUplink(tap));
        uplink
    }

    fn vehicle_events(&self) -> broadcast::Receiver<SwarmEvent> {
        self.events.subscribe()
    }

    async fn geofence(&self) -> Option<skein_model::safety::Geofence> {
        let view: Arc<SwarmContext> = self.ask(|r| DistributedMsg::GetContext(r).into()).await?;
        Some(view.geofence().fence.clone())
    }
}

impl RemoteContext for SwarmAdapter {
    fn joined(&self, v: RemoteJoin) {
        self.distributed(DistributedMsg::AddRemoteVehicle(RemoteVehicle {
            id: v.id,
            port: v.port,
            snapshots: v.snapshots,
            reports: v.reports,
            agent: v.agent,
        }));
    }

    fn answer(&self, msg: FromVehicle) {
        let _ = self.coordinator.cast(FleetMsg::FromVehicle(msg).into());
    }

    fn event(&self, event: SwarmEvent) {
        let _ = self.events.send(event);
    }
}

impl MirrorContext<FormationMirror> for SwarmAdapter {
    async fn current(&self) -> Option<Option<FormationMirror>> {
        self.ask(|r| DistributedMsg::GetFormationMirror(r).into())
            .await
    }

    fn resume(&self, mirror: FormationMirror, from: String) {
        self.distributed(DistributedMsg::ResumeFormation(mirror, from));
    }
}

impl MirrorContext<MissionMirror> for SwarmAdapter {
    async fn current(&self) -> Option<Option<MissionMirror>> {
        self.ask(|r| DistributedMsg::GetMissionMirror(r).into())
            .await
    }

    fn resume(&self, mirror: MissionMirror, from: String) {
        self.distributed(DistributedMsg::ResumeMission(Box::new(mirror), from));
    }
}

impl VehiclesContext for SwarmAdapter {
    async fn vehicles(&self) -> Option<Vec<VehicleSnapshot>> {
        self.ask(|r| FleetMsg::ListVehicles(r).into()).await
    }

    async fn keep_round(&self, round: u64) -> bool {
        if self.load.get().is_none()
            && let Some(l) = self.ask(|r| AdminMsg::GetLoad(r).into()).await
        {
            let _ = self.load.set(l);
        }
        self.load.get().is_none_or(|l| l.keep(ShedWork::Dds, round))
    }

    async fn tracks(&self) -> Option<Vec<TrackView>> {
        self.ask(|r| TrackingMsg::GetTracks(r).into())
            .await
            .map(|(views, _)| views)
    }

    async fn command(&self, vehicle_id: String, command: Command) -> Result<u64, String> {
        let id = vehicle_id.clone();
        match self
            .coordinator
            .call(
                move |r| CommandMsg::VehicleCommand(id, command, r).into(),
                Some(COMMAND_TIMEOUT),
            )
            .await
        {
            Ok(CallResult::Success(Ok(outcome))) => Ok(outcome.command_id),
            Ok(CallResult::Success(Err(Some(reason)))) => Err(reason),
            Ok(CallResult::Success(Err(None))) => Err(format!("no vehicle `{vehicle_id}`")),
            _ => Err("the coordinator did not answer in 5 s".into()),
        }
    }
}

impl TfContext for SwarmAdapter {
    async fn vehicles(&self) -> Option<Vec<VehicleSnapshot>> {
        self.ask(|r| FleetMsg::ListVehicles(r).into()).await
    }

    async fn keep_round(&self, round: u64) -> bool {
        VehiclesContext::keep_round(self, round).await
    }
}
