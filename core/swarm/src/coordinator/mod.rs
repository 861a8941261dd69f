//! The `Coordinator` actor: root of the actor tree, registry of the swarm, formation
//! engine (the paper's CoordinatorUAVModel), and, in `skein up`, supervisor of the
//! Vehicle actors of this process and of services such as the HTTP API.
//!
//! It reaches vehicles only through the swarm protocol ([`crate::protocol`]): each
//! vehicle is a [`VehicleProxy`] (a port for [`ToVehicle`](crate::protocol::ToVehicle)
//! messages and the vehicle's latest report). Commands fan out to every target at once
//! and are answered from the acknowledgements as they come ([`commands`]); nothing in
//! `handle` waits for a vehicle.
//!
//! A failed Vehicle actor is restarted by policy on the same persistent part, so its FSM
//! state, target and stream carry on; when its budget is spent the vehicle is commanded
//! to HOLD (or LAND) through a separate safe-mode link ([`escalation`]). A service (the
//! API) that keeps failing fails the coordinator itself: the process exits non-zero and
//! its outer supervisor (systemd, Docker) restarts it.
//!
//! - [`messages`]: what the API and vehicles tell the coordinator;
//! - [`discovery`]: vehicles joining from their first heartbeat;
//! - [`proxy`]: the coordinator's view of a vehicle;
//! - [`commands`]: fan-out of commands and payload requests;
//! - [`formation_loop`]: the formation tick;
//! - [`hazards`]: lost vehicles the formation plans around;
//! - [`validation`]: formation and leader-motion requests, checked;
//! - [`geofence`]: changing the geofence, tried on every autopilot, then committed;
//! - [`children`]: supervision of vehicles and services, fault routing;
//! - [`escalation`]: what happens to a vehicle whose actor keeps failing;
//! - [`remote`]: vehicles of other processes, and an agent's carrier;
//! - [`swarm`]: starting and stopping it all;
//! - [`status`]: health, metrics and link counters it reports.

pub mod children;
pub mod commands;
pub mod discovery;
pub mod escalation;
pub mod formation_loop;
pub mod geofence;
pub mod hazards;
pub mod messages;
pub mod observe;
pub mod proxy;
pub mod remote;
pub mod stations;
pub mod status;
pub mod swarm;
pub mod track_leader;
pub mod validation;

pub use children::Node;
pub use commands::{CommandOutcome, Refused};
pub use discovery::{EndpointSpec, VehicleSpec};
pub use messages::{
    AirPictureAnswer, CoordinatorMsg, EndpointStats, FaultError, FieldError, Health, ServiceMsg,
    ServiceSpawner, ServiceSpec,
};
pub use proxy::VehicleProxy;
pub use remote::{DistributedMsg, RemoteVehicle};
pub use swarm::{StartError, Swarm};

use crate::config::SwarmConfig;
use crate::context::SwarmContext;
use crate::events::SwarmEvent;
use crate::formation::{FormationEngine, LeaderMotion};
use crate::load::LoadMonitor;
use crate::metrics::Metrics;
use crate::neighbours::NeighbourBoard;
use crate::protocol::{Command, FromVehicle, PayloadCommandError, ToVehicle};
use crate::services::SwarmServices;
use crate::supervision::{self, Children, Supervision};
use crate::ticker::TickGate;
use crate::vehicle::fleet::FleetRegistry;
use commands::{CommandReply, InFlight};
use ractor::{Actor, ActorProcessingErr, ActorRef, SupervisionEvent};
use skein_link::{Endpoint, Px4LinkMsg};
use skein_model::fsm::VehicleState;
use skein_model::geo::Ned;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::broadcast;

/// Arguments of [`Coordinator`].
pub struct CoordinatorArgs {
    /// Swarm configuration.
    pub config: SwarmConfig,
    /// Payload factory, simulator hooks.
    pub services: SwarmServices,
    /// Opened endpoints with their specs.
    pub endpoints: Vec<(Arc<Endpoint>, EndpointSpec)>,
    /// Event bus.
    pub events: broadcast::Sender<SwarmEvent>,
    /// Metrics registry.
    pub metrics: Arc<Metrics>,
    /// How late the process runs ([`crate::load`]).
    pub load: Arc<LoadMonitor>,
}

/// State of [`Coordinator`].
pub struct CoordinatorState {
    context: Arc<SwarmContext>,
    /// The registry of this process's vehicles (payload hosts and the tracker read it).
    fleet: FleetRegistry,
    /// Every vehicle's place, for the vehicles' separation checks.
    neighbours: NeighbourBoard,
    endpoints: Vec<(Arc<Endpoint>, EndpointSpec)>,
    gcs: Option<Arc<skein_link::GcsForwarder>>,
    vehicles: BTreeMap<String, VehicleProxy>,
    services: BTreeMap<String, ServiceSpec>,
    children: Children<Node>,
    formation: FormationEngine,
    events: broadcast::Sender<SwarmEvent>,
    metrics: Arc<Metrics>,
    supervision: Arc<Supervision>,
    in_flight: InFlight,
    hazards: hazards::Hazards,
    started: Instant,
    last_formation_tick: Instant,
    /// The counter-UAS tracker (its task stops with the coordinator).
    tracking: crate::tracking::TrackingService,
    /// Observing vehicle → (track or swarm id, gimbal slot), see [`observe`].
    observing: BTreeMap<String, (String, String)>,
    /// Target id → its observers' stations, see [`stations`].
    stations: BTreeMap<String, stations::StationTask>,
    /// An agent's carrier: gets a copy of every local vehicle's message ([`remote`]).
    uplink_tap: Option<tokio::sync::mpsc::UnboundedSender<FromVehicle>>,
    /// When hovering remote vehicles were last joined to the formation ([`remote`]).
    last_rejoin: Instant,
    /// The formation tick and the watchdog tick (see [`crate::ticker`]).
    formation_gate: TickGate,
    watch_gate: TickGate,
    /// A geofence change waiting for its vehicles' uploads ([`geofence`]).
    fence_change: Option<geofence::PendingFence>,
}

/// The `Coordinator` actor (see module docs).
pub struct Coordinator;

impl CoordinatorState {
    fn emit(&self, ev: SwarmEvent) {
        let _ = self.events.send(ev);
    }

    fn formation_changed(&self) {
        let status = serde_json::to_value(self.formation_status()).unwrap_or_default();
        self.emit(SwarmEvent::FormationChanged { formation: status });
    }

    fn on_from_vehicle(&mut self, msg: FromVehicle) {
        self.tap(&msg);
        match msg {
            FromVehicle::CommandAck {
                id,
                command_id,
                result,
            } => self.on_ack(id, command_id, result),
            FromVehicle::StateChanged { id, to, .. } => self.on_state_changed(&id, to),
            FromVehicle::PayloadResult {
                request_id, result, ..
            } => self.on_payload_result(request_id, Some(result)),
        }
    }

    fn no_slot(&self, id: &str, slot: &str) -> String {
        let slots = self
            .vehicles
            .get(id)
            .and_then(|v| v.local.as_ref())
            .map(|l| l.shared.payloads().keys().cloned().collect::<Vec<_>>())
            .unwrap_or_default();
        format!(
            "vehicle {id} has no payload slot `{slot}` (slots: {})",
            slots.join(", ")
        )
    }

    /// The `Px4Link` of a vehicle of this process, asked from a task.
    fn get_link(
        &self,
        id: String,
        reply: ractor::RpcReplyPort<Result<ActorRef<Px4LinkMsg>, PayloadCommandError>>,
    ) {
        let Some(v) = self.vehicles.get(&id) else {
            let _ = reply.send(Err(PayloadCommandError::NotFound(format!(
                "no vehicle `{id}`"
            ))));
            return;
        };
        let actor = v.local.as_ref().and_then(|l| l.port.actor());
        tokio::spawn(async move {
            let link = match actor {
                Some(a) => match a
                    .call(
                        crate::vehicle::VehicleMsg::GetLink,
                        Some(Duration::from_secs(2)),
                    )
                    .await
                {
                    Ok(ractor::rpc::CallResult::Success(Some(link))) => Some(link),
                    _ => None,
                },
                None => None,
            };
            let _ = reply.send(link.ok_or_else(|| {
                PayloadCommandError::Unavailable(format!("the link of `{id}` is not running"))
            }));
        });
    }
}

impl Actor for Coordinator {
    type Msg = CoordinatorMsg;
    type State = CoordinatorState;
    type Arguments = CoordinatorArgs;

    async fn pre_start(
        &self,
        myself: ActorRef<Self::Msg>,
        args: CoordinatorArgs,
    ) -> Result<Self::State, ActorProcessingErr> {
        for (i, (endpoint, _)) in args.endpoints.iter().enumerate() {
            let me = myself.clone();
            endpoint.set_discovery(Arc::new(move |d| {
                let _ = me.cast(CoordinatorMsg::Discovered {
                    endpoint: i,
                    discovery: d,
                });
            }));
        }
        let period = Duration::from_secs_f64(1.0 / args.config.formation_rate_hz.max(1.0));
        let supervision = Supervision::new(
            args.config.supervision.clone(),
            args.load.clone(),
            args.metrics.clone(),
            args.events.clone(),
        );
        let watchdog_period = supervision.config.watchdog_period();
        let separation_m = args.config.setpoint_separation_m();
        let mut formation = FormationEngine::new(separation_m);
        formation.set_replan_after_s(args.config.hazards.replan_after_s);
        let control_period = Duration::from_secs_f64(1.0 / args.config.control_rate_hz.max(1.0));
        let context = Arc::new(SwarmContext::new(args.config, args.services));
        args.load.attach_ticker(&context.ticker);
        let me = myself.clone();
        let formation_gate = context.ticker.every(period, move || {
            me.cast(CoordinatorMsg::FormationTick).is_ok()
        });
        let me = myself.clone();
        let watch_gate = context.ticker.every(watchdog_period, move || {
            me.cast(CoordinatorMsg::WatchTick).is_ok()
        });
        let fleet = FleetRegistry::new();
        let tracking = crate::tracking::TrackingService::spawn(
            crate::tracking::TrackerConfig::default(),
            fleet.reader(),
            args.events.clone(),
            args.metrics.clone(),
        );
        Ok(CoordinatorState {
            context,
            fleet,
            neighbours: NeighbourBoard::new(control_period),
            tracking,
            observing: BTreeMap::new(),
            stations: BTreeMap::new(),
            uplink_tap: None,
            last_rejoin: Instant::now(),
            fence_change: None,
            endpoints: args.endpoints,
            gcs: None,
            vehicles: BTreeMap::new(),
            services: BTreeMap::new(),
            children: Children::new(supervision::ROOT, supervision.clone()),
            formation,
            events: args.events,
            metrics: args.metrics,
            supervision,
            in_flight: InFlight::default(),
            hazards: hazards::Hazards::default(),
            started: Instant::now(),
            last_formation_tick: Instant::now(),
            formation_gate,
            watch_gate,
        })
    }

    async fn handle(
        &self,
        myself: ActorRef<Self::Msg>,
        msg: Self::Msg,
        state: &mut Self::State,
    ) -> Result<(), ActorProcessingErr> {
        match msg {
            CoordinatorMsg::Discovered {
                endpoint,
                discovery,
            } => state.on_discovered(&myself, endpoint, discovery).await?,
            CoordinatorMsg::FromVehicle(msg) => state.on_from_vehicle(msg),
            CoordinatorMsg::Distributed(msg) => state.on_distributed(msg),
            CoordinatorMsg::SwarmCommand(cmd, reply) => {
                if matches!(cmd, Command::Land | Command::Rtl) && state.formation.is_active() {
                    state.formation.deactivate();
                    state.formation_changed();
                }
                let targets = state.vehicles.keys().cloned().collect();
                state.run_command(&myself, targets, cmd, CommandReply::Swarm(reply));
            }
            CoordinatorMsg::VehicleCommand(id, cmd, reply) => {
                if !state.vehicles.contains_key(&id) {
                    let _ = reply.send(Err(None));
                } else if cmd == Command::ClearHazard {
                    // The formation's, not the vehicle's: done here, nothing to wait for.
                    let _ = reply.send(state.clear_hazard(&id).map(|()| CommandOutcome {
                        command_id: 0,
                        accepted: vec![id],
                        refused: vec![],
                    }));
                } else {
                    state.run_command(&myself, vec![id], cmd, CommandReply::Vehicle(reply));
                }
            }
            CoordinatorMsg::ListVehicles(reply) => {
                let list = state.vehicles.values().map(|v| v.snapshot()).collect();
                let _ = reply.send(list);
            }
            CoordinatorMsg::GetVehicle(id, reply) => {
                let _ = reply.send(state.vehicles.get(&id).map(|v| v.snapshot()));
            }
            CoordinatorMsg::GetFormation(reply) => {
                let _ = reply.send(state.formation_status());
            }
            CoordinatorMsg::SetFormation(spec, reply) => {
                let vehicles: Vec<(&str, VehicleState, bool)> = state
                    .vehicles
                    .iter()
                    .map(|(id, v)| (id.as_str(), v.state(), v.failed))
                    .collect();
                let shared = state.tracking.shared();
                let (tracks, swarms) = (shared.tracks(), shared.swarms());
                let checked = track_leader::validate_track_leader(&spec, &tracks, &swarms)
                    .and_then(|()| {
                        validation::validate_formation(
                            &state.context.config,
                            &state.context.geofence().fence,
                            &spec,
                            &vehicles,
                        )
                    });
                match checked {
                    Err(e) => {
                        let _ = reply.send(Err(e));
                    }
                    Ok(()) => {
                        state.formation.set(spec);
                        state.join_hovering();
                        state.follow_track_tick();
                        state.formation_tick();
                        let status = state.formation_status();
                        state.emit(SwarmEvent::FormationChanged {
                            formation: serde_json::to_value(&status).unwrap_or_default(),
                        });
                        let _ = reply.send(Ok(status));
                    }
                }
            }
            CoordinatorMsg::LeaderMotion(mut motion, reply) => {
                // A point without an altitude keeps the formation's.
                if let Some(down) = state
                    .formation
                    .status(&[])
                    .reference
                    .map(|r| r.position.down_m)
                {
                    fill_altitude(&mut motion, down);
                }
                let r = validation::validate_motion(
                    &state.context.config,
                    &state.context.geofence().fence,
                    &motion,
                )
                .and_then(|()| {
                    state.formation.set_motion(motion).map_err(|e| FieldError {
                        field: "formation".into(),
                        error: e,
                    })
                });
                let _ = reply.send(r.map(|()| state.formation_status()));
            }
            CoordinatorMsg::ClearHazard(id, reply) => {
                let _ = reply.send(state.clear_hazard(&id));
            }
            CoordinatorMsg::ClearFormation(reply) => {
                state.formation.deactivate();
                let members: Vec<String> = state
                    .vehicles
                    .iter()
                    .filter(|(_, v)| v.state() == VehicleState::InFormation)
                    .map(|(id, _)| id.clone())
                    .collect();
                for id in members {
                    state.internal_command(&id, Command::LeaveFormation);
                }
                let status = state.formation_status();
                state.emit(SwarmEvent::FormationChanged {
                    formation: serde_json::to_value(&status).unwrap_or_default(),
                });
                let _ = reply.send(status);
            }
            CoordinatorMsg::Health(reply) => {
                let _ = reply.send(state.health());
            }
            CoordinatorMsg::LinkStats(reply) => {
                let _ = reply.send(state.link_stats());
            }
            CoordinatorMsg::SetGcs(g) => state.gcs = Some(g),
            CoordinatorMsg::GetLink(id, reply) => state.get_link(id, reply),
            CoordinatorMsg::GetGeofence(reply) => {
                let _ = reply.send(state.geofence());
            }
            CoordinatorMsg::SetGeofence(fence, reply) => state.set_geofence(&myself, fence, reply),
            CoordinatorMsg::FenceTried(trial) => state.fence_tried(trial),
            CoordinatorMsg::GetPayload(id, slot, reply) => {
                let r = match state.vehicles.get(&id) {
                    None => Err(format!("no vehicle `{id}`")),
                    Some(v) => v
                        .local
                        .as_ref()
                        .and_then(|l| l.shared.payload(&slot))
                        .ok_or_else(|| state.no_slot(&id, &slot)),
                };
                let _ = reply.send(r);
            }
            CoordinatorMsg::PayloadCommand(id, slot, command, reply) => {
                let make = move |request_id| ToVehicle::PayloadCommand {
                    request_id,
                    slot,
                    command,
                };
                state.payload_request(&myself, id, make, reply);
            }
            CoordinatorMsg::AttachPayload(id, spec, reply) => {
                let make = move |request_id| ToVehicle::AttachPayload { request_id, spec };
                state.payload_request(&myself, id, make, reply);
            }
            CoordinatorMsg::DetachPayload(id, slot, reply) => {
                let make = move |request_id| ToVehicle::DetachPayload { request_id, slot };
                state.payload_request(&myself, id, make, reply);
            }
            CoordinatorMsg::PluginsChanged => {
                // Local to this process: its vehicles create their payloads from the
                // plugin manager of this process.
                for v in state.vehicles.values() {
                    if let Some(a) = v.local.as_ref().and_then(|l| l.port.actor()) {
                        let _ = a.cast(crate::vehicle::VehicleMsg::PluginsChanged);
                    }
                }
            }
            CoordinatorMsg::RefreshPayloads(instances, at) => {
                for (id, slot) in instances {
                    let actor = state
                        .vehicles
                        .get(&id)
                        .and_then(|v| v.local.as_ref())
                        .and_then(|l| l.port.actor());
                    if let Some(a) = actor {
                        let _ = a.cast(crate::vehicle::VehicleMsg::RefreshPayload(slot, at));
                    }
                }
            }
            CoordinatorMsg::GetSupervision(reply) => {
                let _ = reply.send(state.supervision.tree());
            }
            CoordinatorMsg::GetTracks(reply) => {
                let _ = reply.send((state.tracking.shared().tracks(), state.observations()));
            }
            CoordinatorMsg::GetAirPicture(reply) => {
                let shared = state.tracking.shared();
                let _ = reply.send(AirPictureAnswer {
                    tracks: shared.tracks(),
                    swarms: shared.swarms(),
                    observing: state.observations(),
                    stations: state.station_views(),
                });
            }
            CoordinatorMsg::Observe(spec, reply) => {
                let _ = reply.send(state.observe(spec));
            }
            CoordinatorMsg::StopObserving(track, reply) => {
                let _ = reply.send(state.stop_observing(&track));
            }
            CoordinatorMsg::GetSimTruth(reply) => {
                let truth = state
                    .context
                    .simulator()
                    .map(|sim| sim.truth(state.context.frame().as_ref()))
                    .filter(|v| !v.is_null());
                let _ = reply.send(truth);
            }
            CoordinatorMsg::RenderMetrics(reply) => {
                let _ = reply.send(state.render_metrics());
            }
            CoordinatorMsg::AddService(spec, reply) => {
                let name = spec.name.clone();
                let node = Node::Service(name.clone(), spec.kind);
                state.services.insert(name.clone(), spec);
                let r = state
                    .start_child(&myself, node)
                    .await
                    .map_err(|e| format!("service `{name}` did not start: {e}"));
                let _ = reply.send(r);
            }
            CoordinatorMsg::InjectFault(path, kind, reply) => {
                state.inject(&myself, &path, kind, reply);
            }
            CoordinatorMsg::Fault(kind) => {
                skein_link::fault::inject(kind, &myself, supervision::ROOT).await?;
            }
            CoordinatorMsg::Ping(reply) => {
                let _ = reply.send(());
            }
            CoordinatorMsg::GetLoad(reply) => {
                let _ = reply.send(state.supervision.load.clone());
            }
            CoordinatorMsg::FormationTick => {
                state.formation_gate.done();
                state.rejoin_remote_hovering();
                state.follow_track_tick();
                state.formation_tick();
                state.observe_tick();
            }
            CoordinatorMsg::WatchTick => {
                state.watch_gate.done();
                let me = myself.clone();
                state.children.watch(move |node, id| {
                    let _ = me.cast(CoordinatorMsg::ChildHung(node, id));
                });
            }
            CoordinatorMsg::ChildHung(node, id) => state.children.kill_hung(&node, id),
            CoordinatorMsg::RestartChild(node, noticed, reason) => {
                let failed = state.vehicles.get(node.name()).is_some_and(|v| v.failed);
                if state.children.get(&node).is_none() && !failed {
                    state.restart_child(&myself, node, noticed, reason).await?;
                }
            }
            CoordinatorMsg::CommandTimeout(command_id) => state.on_command_timeout(command_id),
            CoordinatorMsg::PayloadTimeout(request_id) => {
                state.on_payload_result(request_id, None);
            }
        }
        Ok(())
    }

    async fn handle_supervisor_evt(
        &self,
        myself: ActorRef<Self::Msg>,
        evt: SupervisionEvent,
        state: &mut Self::State,
    ) -> Result<(), ActorProcessingErr> {
        if let Some((node, exit)) = state.children.ended(&evt) {
            state.child_ended(&myself, node, exit).await?;
        }
        Ok(())
    }
}

/// Gives the points of `motion` that have no altitude (NaN) the altitude `down_m`.
fn fill_altitude(motion: &mut LeaderMotion, down_m: f64) {
    let fill = |p: &mut Ned| {
        if p.down_m.is_nan() {
            p.down_m = down_m;
        }
    };
    match motion {
        LeaderMotion::Hold => {}
        LeaderMotion::GoTo { target, .. } => fill(target),
        LeaderMotion::Waypoints { points, .. } => points.iter_mut().for_each(fill),
        LeaderMotion::Orbit { centre, .. } => fill(centre),
    }
}
