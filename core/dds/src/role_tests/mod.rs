//! Scenario tests of the distributed roles on the in-memory carrier
//! ([`crate::carrier::memory::MemoryBus`]): several "processes" (coordinator candidates,
//! agents) wired together in one test, on tokio's paused clock, so each runs in
//! milliseconds of wall time whatever the seconds of protocol time it covers. A
//! [`Process`] stands for the rest of a process (its coordinator actor): it answers the
//! roles' contexts from fixed vehicles and records every call the roles make ([`Calls`]).
//!
//! The end-to-end tests (`tests/e2e_distributed.rs`, `e2e_failover.rs`, `e2e_dds.rs`)
//! prove the same roles on real DDS, between processes and hosts.

mod agent_role_tests;
mod mirror_role_tests;
mod mission_mirror_role_tests;
mod remote_role_tests;
mod rtcm_role_tests;

use crate::agent::AgentContext;
use crate::carrier::TopicWriter;
use crate::carrier::memory::MemoryBus;
use crate::counters::DdsCounters;
use crate::envelope::Envelope;
use crate::lease::{self, ElectionContext, RoleChange};
use crate::mirror::MirrorContext;
use crate::msgs::{CoordinatorLease, SwarmMessage};
use crate::reframe::{AnchoredFrame, FrameSource, SwarmFrame};
use crate::remote::{RemoteContext, RemoteJoin};
use crate::topics::{self, TopicSpec};
use serde::Serialize;
use skein_model::fsm::VehicleState;
use skein_model::geo::{GeoPoint, Ned, NedFrame};
use skein_model::vehicle::VehicleSnapshot;
use skein_swarm::SwarmEvent;
use skein_swarm::coordinator::missions::MissionMirror;
use skein_swarm::election::Lease;
use skein_swarm::formation::FormationMirror;
use skein_swarm::protocol::{FromVehicle, ToVehicle, VehicleReport, wall_us};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;
use tokio::sync::{broadcast, mpsc};

/// The origin of process A's swarm frame.
pub(super) fn origin_a() -> GeoPoint {
    GeoPoint::new(47.397742, 8.545594, 488.0)
}

/// The origin of process B's swarm frame: 30 m north and 10 m east of A's.
pub(super) fn origin_b() -> GeoPoint {
    NedFrame::new(origin_a()).to_geo(Ned::new(30.0, 10.0, 0.0))
}

/// What a role did to its process.
#[derive(Debug)]
pub(super) enum Call {
    /// `AgentContext::to_vehicle`.
    ToVehicle(String, ToVehicle),
    /// `AgentContext::neighbour`.
    Neighbour(String, VehicleReport),
    /// `RemoteContext::joined`.
    Joined(RemoteJoin),
    /// `RemoteContext::answer`.
    Answer(FromVehicle),
    /// `RemoteContext::event`.
    Event(SwarmEvent),
    /// `MirrorContext::resume`.
    Resume(FormationMirror, String),
    /// `MirrorContext::resume` of a mission.
    ResumeMission(Box<MissionMirror>, String),
    /// `ElectionContext::role_changed`.
    RoleChanged(RoleChange),
}

/// The calls a [`Process`]'s roles made, in order.
pub(super) struct Calls(mpsc::UnboundedReceiver<Call>);

impl Calls {
    /// The next call `pick` takes (others are skipped) within `within` of protocol time;
    /// panics naming `what` if none comes.
    pub(super) async fn next<T>(
        &mut self,
        within: Duration,
        what: &str,
        pick: impl FnMut(Call) -> Option<T>,
    ) -> T {
        match self.within(within, pick).await {
            Some(v) => v,
            None => panic!("no {what} within {within:?}"),
        }
    }

    /// The next call `pick` takes within `within`, if one comes.
    pub(super) async fn within<T>(
        &mut self,
        within: Duration,
        mut pick: impl FnMut(Call) -> Option<T>,
    ) -> Option<T> {
        let deadline = tokio::time::Instant::now() + within;
        loop {
            match tokio::time::timeout_at(deadline, self.0.recv()).await {
                Ok(Some(call)) => {
                    if let Some(v) = pick(call) {
                        return Some(v);
                    }
                }
                Ok(None) | Err(_) => return None,
            }
        }
    }
}

/// The rest of one process, as its roles see it (see the module docs).
pub(super) struct Process {
    frame: Arc<AnchoredFrame>,
    /// Its vehicles: report (stamped when asked) and snapshot.
    vehicles: Mutex<Vec<(VehicleReport, VehicleSnapshot)>>,
    /// The formation its coordinator flies (for the mirror).
    formation: Mutex<Option<FormationMirror>>,
    /// The mission its coordinator flies (for the mirror).
    mission: Mutex<Option<MissionMirror>>,
    events: broadcast::Sender<SwarmEvent>,
    /// The agent role's tap of its vehicles' answers.
    uplink: Mutex<Option<mpsc::UnboundedSender<FromVehicle>>>,
    calls: mpsc::UnboundedSender<Call>,
}

impl Process {
    /// A process whose swarm frame is about `origin` (`None`: anchored at the first
    /// origin it hears), with no vehicles.
    pub(super) fn new(origin: Option<GeoPoint>) -> (Arc<Process>, Calls) {
        let (calls, rx) = mpsc::unbounded_channel();
        let process = Process {
            frame: Arc::new(AnchoredFrame::new(origin)),
            vehicles: Mutex::new(Vec::new()),
            formation: Mutex::new(None),
            mission: Mutex::new(None),
            events: broadcast::channel(64).0,
            uplink: Mutex::new(None),
            calls,
        };
        (Arc::new(process), Calls(rx))
    }

    /// Adds vehicle `id` in `state`, at `position` (its swarm frame).
    pub(super) fn with_vehicle(
        self: Arc<Self>,
        id: &str,
        state: VehicleState,
        position: Ned,
    ) -> Arc<Self> {
        let frame = self
            .frame
            .frame()
            .expect("a process with vehicles has a frame");
        self.vehicles
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .push((
                report(state, position),
                snapshot(id, state, position, frame),
            ));
        self
    }

    /// Makes its coordinator fly `formation`.
    pub(super) fn flying(&self, formation: FormationMirror) {
        *self
            .formation
            .lock()
            .unwrap_or_else(PoisonError::into_inner) = Some(formation);
    }

    /// Makes its coordinator fly `mission`.
    pub(super) fn flying_mission(&self, mission: MissionMirror) {
        *self.mission.lock().unwrap_or_else(PoisonError::into_inner) = Some(mission);
    }

    /// One of its vehicles answers `msg` (to the agent role's tap).
    pub(super) fn answer(&self, msg: FromVehicle) {
        let tap = self.uplink.lock().unwrap_or_else(PoisonError::into_inner);
        tap.as_ref()
            .expect("an agent taps the uplink")
            .send(msg)
            .unwrap();
    }

    /// Puts `event` on its event bus.
    pub(super) fn emit(&self, event: SwarmEvent) {
        let _ = self.events.send(event);
    }

    /// Its swarm frame.
    pub(super) fn frame(&self) -> Option<NedFrame> {
        self.frame.frame()
    }

    fn call(&self, call: Call) {
        let _ = self.calls.send(call);
    }

    fn vehicles(&self) -> Vec<(VehicleReport, VehicleSnapshot)> {
        self.vehicles
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }
}

/// A report in `state` at `position`, stamped now.
pub(super) fn report(state: VehicleState, position: Ned) -> VehicleReport {
    VehicleReport {
        state,
        position: Some(position),
        link_silence_s: Some(0.0),
        stamp_us: wall_us(),
        ..VehicleReport::disconnected()
    }
}

/// A snapshot of vehicle `id` in `state` at `position` (swarm frame `frame`).
pub(super) fn snapshot(
    id: &str,
    state: VehicleState,
    position: Ned,
    frame: NedFrame,
) -> VehicleSnapshot {
    VehicleSnapshot {
        model: "generic".into(),
        state,
        armed: state != VehicleState::Landed,
        ..VehicleSnapshot::hovering_at(id, 1, &frame, position)
    }
}

impl FrameSource for Process {
    async fn swarm_frame(&self) -> Option<Arc<dyn SwarmFrame>> {
        Some(self.frame.clone())
    }
}

impl AgentContext for Process {
    async fn reports(&self) -> Option<Vec<(String, VehicleReport)>> {
        let now = wall_us();
        Some(
            self.vehicles()
                .into_iter()
                .map(|(r, s)| (s.id, VehicleReport { stamp_us: now, ..r }))
                .collect(),
        )
    }

    async fn snapshots(&self) -> Option<Vec<VehicleSnapshot>> {
        Some(self.vehicles().into_iter().map(|(_, s)| s).collect())
    }

    fn to_vehicle(&self, vehicle_id: String, msg: ToVehicle) {
        self.call(Call::ToVehicle(vehicle_id, msg));
    }

    fn neighbour(&self, vehicle_id: String, report: VehicleReport) {
        self.call(Call::Neighbour(vehicle_id, report));
    }

    fn tap_uplink(&self) -> mpsc::UnboundedReceiver<FromVehicle> {
        let (tap, uplink) = mpsc::unbounded_channel();
        *self.uplink.lock().unwrap_or_else(PoisonError::into_inner) = Some(tap);
        uplink
    }

    fn vehicle_events(&self) -> broadcast::Receiver<SwarmEvent> {
        self.events.subscribe()
    }

    async fn geofence(&self) -> Option<skein_model::safety::Geofence> {
        Some(skein_model::safety::Geofence::default())
    }
}

impl RemoteContext for Process {
    fn joined(&self, vehicle: RemoteJoin) {
        self.call(Call::Joined(vehicle));
    }

    fn answer(&self, msg: FromVehicle) {
        self.call(Call::Answer(msg));
    }

    fn event(&self, event: SwarmEvent) {
        self.call(Call::Event(event));
    }
}

impl MirrorContext<FormationMirror> for Process {
    async fn current(&self) -> Option<Option<FormationMirror>> {
        Some(
            self.formation
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .clone(),
        )
    }

    fn resume(&self, mirror: FormationMirror, from: String) {
        self.call(Call::Resume(mirror, from));
    }
}

impl MirrorContext<MissionMirror> for Process {
    async fn current(&self) -> Option<Option<MissionMirror>> {
        Some(
            self.mission
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .clone(),
        )
    }

    fn resume(&self, mirror: MissionMirror, from: String) {
        self.call(Call::ResumeMission(Box::new(mirror), from));
    }
}

impl ElectionContext for Process {
    fn role_changed(&self, change: RoleChange) {
        self.call(Call::RoleChanged(change));
    }
}

/// A test's own writer of one topic: it plays a process the test does not run.
pub(super) struct Peer<M> {
    writer: TopicWriter<M>,
}

impl Peer<CoordinatorLease> {
    /// A writer of `/skein/coordinator`.
    pub(super) fn leases(bus: &MemoryBus) -> Self {
        Peer::open(bus, &topics::coordinator())
    }

    /// `coordinator_id` active in `epoch` for `periods` lease periods (200 ms), a lease
    /// each period, then silent; returns the instant it fell silent (virtual time).
    pub(super) async fn lease_then_fall_silent(
        &self,
        coordinator_id: &str,
        epoch: u64,
        periods: usize,
    ) -> tokio::time::Instant {
        let mut period = tokio::time::interval(std::time::Duration::from_millis(200));
        for _ in 0..periods {
            period.tick().await;
            self.lease(coordinator_id, epoch, true);
        }
        tokio::time::Instant::now()
    }

    /// Publishes the lease of `coordinator_id` in `epoch`, `active` or not.
    pub(super) fn lease(&self, coordinator_id: &str, epoch: u64, active: bool) {
        let lease = Lease {
            coordinator_id: coordinator_id.into(),
            priority: 1,
            epoch,
            active,
            api_url: String::new(),
        };
        self.writer.publish(lease::to_msg(&lease)).unwrap();
    }
}

impl Peer<SwarmMessage> {
    /// Publishes `body` about `vehicle_id` from `sender_id` in `epoch`, sent from the
    /// frame about `origin`.
    pub(super) fn send<B: Serialize>(
        &self,
        vehicle_id: &str,
        sender_id: &str,
        epoch: u64,
        origin: GeoPoint,
        body: &B,
    ) {
        let m = Envelope::message(
            vehicle_id,
            sender_id,
            epoch,
            Some(NedFrame::new(origin)),
            body,
        )
        .unwrap();
        self.writer.publish(m).unwrap();
    }
}

impl<M: crate::carrier::Sample> Peer<M> {
    /// A writer of `topic`.
    pub(super) fn open(bus: &MemoryBus, topic: &TopicSpec) -> Self {
        Peer {
            writer: TopicWriter::open(bus, topic, &Arc::new(DdsCounters::default())).unwrap(),
        }
    }

    /// A writer of `topic` whose samples carry `identity`, as a secured participant's do.
    pub(super) fn open_as(
        bus: &MemoryBus,
        topic: &TopicSpec,
        identity: crate::carrier::WriterIdentity,
    ) -> Self {
        Peer {
            writer: TopicWriter::from_writer(
                bus.writer_as(topic, identity).unwrap(),
                &Arc::new(DdsCounters::default()),
            ),
        }
    }
}

/// Protocol time since `start`, seconds.
pub(super) fn since(start: tokio::time::Instant) -> f64 {
    start.elapsed().as_secs_f64()
}
