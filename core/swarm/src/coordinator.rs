//! The `Coordinator` actor: root of the actor tree, registry of the swarm, formation
//! engine (the paper's CoordinatorUAVModel), and supervisor of the Vehicle actors and of
//! services such as the HTTP API.
//!
//! Vehicles join when their first heartbeat reaches an endpoint: the coordinator creates
//! the vehicle's persistent part ([`VehicleShared`], including the link route and setpoint
//! stream) and spawns its [`Vehicle`] actor linked under itself. A failed Vehicle actor is
//! restarted by policy on the same persistent part, so its FSM state, target and stream
//! carry on; when its budget is spent the vehicle is commanded to HOLD (or LAND) through
//! a separate safe-mode `Px4Link` that does not depend on the failing actor, and is
//! marked failed. A service (the API) that keeps failing fails the coordinator itself:
//! the process exits non-zero and its outer supervisor (systemd, Docker) restarts it.
//!
//! The API reaches the swarm only through [`CoordinatorMsg`].

use crate::events::SwarmEvent;
use crate::formation::{
    FormationEngine, FormationSpec, FormationStatus, LeaderMotion, Member, VIRTUAL,
};
use crate::metrics::Metrics;
use crate::payload::{PayloadCommandError, PayloadShared};
use crate::supervision::{self, Decision, Exit, Supervision, TreeNode, VehicleEscalation};
use crate::vehicle::{SlotTarget, Vehicle, VehicleArgs, VehicleCommand, VehicleMsg, VehicleShared};
use crate::view::{SwarmConfig, SwarmServices, SwarmView};
use ractor::{
    Actor, ActorCell, ActorId, ActorProcessingErr, ActorRef, RpcReplyPort, SupervisionEvent,
};
use serde::Serialize;
use skein_link::endpoint::Discovery;
use skein_link::{
    ConnectionAddress, Endpoint, Identity, LinkCommand, Px4Link, Px4LinkArgs, Px4LinkMsg,
    VehicleLink,
};
use skein_mavlink::DecodeCounts;
use skein_model::fsm::VehicleState;
use skein_model::geo::Ned;
use skein_model::px4::Px4Mode;
use skein_model::supervision::{ChildKind, FaultKind};
use skein_model::vehicle::VehicleSnapshot;
use std::collections::{BTreeMap, HashSet};
use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::broadcast;

/// How one configured vehicle on an endpoint is named.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct VehicleSpec {
    /// The id users see; default `uav-<sysid>`.
    pub id: Option<String>,
    /// Only the vehicle with this sysid gets this spec; `None` = the first one heard.
    pub sysid: Option<u8>,
    /// Model name (default `generic`).
    pub model: Option<String>,
}

/// An endpoint to open and the vehicles expected on it.
#[derive(Debug, Clone, PartialEq)]
pub struct EndpointSpec {
    /// Connection string.
    pub connection: ConnectionAddress,
    /// Names and models for vehicles heard there (others get defaults).
    pub vehicles: Vec<VehicleSpec>,
    /// True when the endpoint leads to the in-process simulator.
    pub simulated: bool,
}

/// The outcome of a command accepted for processing (HTTP 202).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CommandOutcome {
    /// Id of the command; results arrive on the stream as `command_result` events.
    pub command_id: u64,
    /// Vehicles that accepted it.
    pub accepted: Vec<String>,
    /// Vehicles that refused it, with the reason (naming their state).
    pub refused: Vec<Refused>,
}

/// A vehicle's refusal.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Refused {
    /// Vehicle id.
    pub id: String,
    /// Why.
    pub reason: String,
}

/// Per-endpoint link statistics.
#[derive(Debug, Clone, Serialize)]
pub struct EndpointStats {
    /// Connection string.
    pub connection: String,
    /// Bound local address (UDP).
    pub local_addr: Option<String>,
    /// Decoder counters (malformed input).
    pub decode: DecodeCounts,
    /// Send counters.
    pub send: skein_link::endpoint::SendCounts,
}

/// Swarm health for `GET /api/v1/health`.
#[derive(Debug, Clone, Serialize)]
pub struct Health {
    /// Always `"ok"` while the coordinator answers.
    pub status: &'static str,
    /// Vehicles known.
    pub vehicles: usize,
    /// Vehicles with a live link.
    pub connected: usize,
    /// Seconds since the coordinator started.
    pub uptime_s: f64,
    /// The swarm origin, once anchored.
    pub swarm_origin: Option<skein_model::geo::GeoPoint>,
    /// True when `POST /api/v1/faults` is enabled.
    pub fault_injection: bool,
}

/// Why a formation request was refused: the field and the reason.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FieldError {
    /// The offending field (`"spacing_m"`).
    pub field: String,
    /// What is wrong with it.
    pub error: String,
}

/// Why a fault could not be injected.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum FaultError {
    /// Fault injection is off (`--enable-fault-injection` absent).
    Disabled,
    /// No actor at that path; the message names it and lists the known paths.
    UnknownTarget(String),
    /// The target exists but could not be reached.
    Unreachable(String),
}

/// Messages of a supervised service actor (the HTTP API): what the coordinator needs to
/// supervise something it does not otherwise know.
pub enum ServiceMsg {
    /// Watchdog probe.
    Ping(RpcReplyPort<()>),
    /// Fault injection.
    Fault(FaultKind),
}

/// Starts a service actor linked under the given supervisor.
pub type ServiceSpawner = Arc<
    dyn Fn(
            ActorCell,
        )
            -> Pin<Box<dyn Future<Output = Result<ActorRef<ServiceMsg>, ActorProcessingErr>> + Send>>
        + Send
        + Sync,
>;

/// A service for the coordinator to start and supervise.
#[derive(Clone)]
pub struct ServiceSpec {
    /// Name in the tree (`"api"`).
    pub name: String,
    /// Its kind (its restart policy).
    pub kind: ChildKind,
    /// How to (re)start it.
    pub spawn: ServiceSpawner,
}

/// Messages of [`Coordinator`].
pub enum CoordinatorMsg {
    /// An endpoint heard an autopilot it has no route for.
    Discovered {
        /// Index of the endpoint.
        endpoint: usize,
        /// What it heard.
        discovery: Discovery,
    },
    /// A vehicle's FSM state changed.
    VehicleState {
        /// Vehicle id.
        id: String,
        /// New state.
        state: VehicleState,
    },
    /// A command for every vehicle.
    SwarmCommand(VehicleCommand, RpcReplyPort<CommandOutcome>),
    /// A command for one vehicle; `Err(None)` when the vehicle does not exist.
    VehicleCommand(
        String,
        VehicleCommand,
        RpcReplyPort<Result<CommandOutcome, Option<String>>>,
    ),
    /// All vehicles, sorted by id.
    ListVehicles(RpcReplyPort<Vec<VehicleSnapshot>>),
    /// One vehicle.
    GetVehicle(String, RpcReplyPort<Option<VehicleSnapshot>>),
    /// The formation.
    GetFormation(RpcReplyPort<FormationStatus>),
    /// Set the formation.
    SetFormation(
        FormationSpec,
        RpcReplyPort<Result<FormationStatus, FieldError>>,
    ),
    /// Stop flying the formation (vehicles hold where they are).
    ClearFormation(RpcReplyPort<FormationStatus>),
    /// Move the formation's reference point (leader go-to, waypoints, orbit).
    LeaderMotion(
        LeaderMotion,
        RpcReplyPort<Result<FormationStatus, FieldError>>,
    ),
    /// Health.
    Health(RpcReplyPort<Health>),
    /// Link statistics per endpoint.
    LinkStats(RpcReplyPort<Vec<EndpointStats>>),
    /// A vehicle's actor ref (tests, fault injection).
    GetVehicleActor(String, RpcReplyPort<Option<ActorRef<VehicleMsg>>>),
    /// A vehicle's payload (state, frames); `Err` names what is missing.
    GetPayload(
        String,
        String,
        RpcReplyPort<Result<Arc<PayloadShared>, String>>,
    ),
    /// A command for a vehicle's payload; the payload's answer or why there is none.
    PayloadCommand(
        String,
        String,
        serde_json::Value,
        RpcReplyPort<Result<serde_json::Value, PayloadCommandError>>,
    ),
    /// Payload instances (vehicle id, slot) whose plugin was reloaded at this instant: their
    /// vehicles re-create them on the new build (those created since are left alone).
    RefreshPayloads(Vec<(String, String)>, Instant),
    /// The supervision tree.
    GetSupervision(RpcReplyPort<TreeNode>),
    /// The metrics in Prometheus text format.
    RenderMetrics(RpcReplyPort<String>),
    /// Start and supervise a service (the HTTP API).
    AddService(ServiceSpec, RpcReplyPort<Result<(), String>>),
    /// Inject a fault at an actor path (`"coordinator/uav-1/px4link"`).
    InjectFault(String, FaultKind, RpcReplyPort<Result<(), FaultError>>),
    /// Watchdog probe (the process watchdog pings the coordinator).
    Ping(RpcReplyPort<()>),
    /// Fault injection into the coordinator itself.
    Fault(FaultKind),
    /// Formation loop tick.
    FormationTick,
    /// Time to ping the children.
    WatchTick,
    /// A child did not answer the watchdog.
    ChildHung(String, ActorId),
    /// A child's backoff has passed.
    RestartChild(String, Instant, String),
}

struct Entry {
    shared: Arc<VehicleShared>,
    /// `None` while restarting or after an escalation.
    actor: Option<ActorRef<VehicleMsg>>,
    /// The budget is spent: the vehicle was commanded to HOLD/LAND and stays failed.
    failed: bool,
    /// The link actor that carried the escalation, kept for the vehicle's telemetry.
    safe_link: Option<ActorRef<Px4LinkMsg>>,
}

struct Service {
    spec: ServiceSpec,
    actor: Option<ActorRef<ServiceMsg>>,
}

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
}

/// State of [`Coordinator`].
pub struct CoordinatorState {
    view: Arc<SwarmView>,
    endpoints: Vec<(Arc<Endpoint>, EndpointSpec)>,
    vehicles: BTreeMap<String, Entry>,
    services: BTreeMap<String, Service>,
    formation: FormationEngine,
    events: broadcast::Sender<SwarmEvent>,
    metrics: Arc<Metrics>,
    supervision: Arc<Supervision>,
    hung: HashSet<ActorId>,
    next_command_id: u64,
    started: Instant,
    last_formation_tick: Instant,
}

/// The `Coordinator` actor (see module docs).
pub struct Coordinator;

/// Timeout of a vehicle's answer to a command check.
const VEHICLE_CALL_TIMEOUT: Duration = Duration::from_secs(2);

impl CoordinatorState {
    fn emit(&self, ev: SwarmEvent) {
        let _ = self.events.send(ev);
    }

    fn path(id: &str) -> String {
        format!("{}/{id}", supervision::ROOT)
    }

    async fn spawn_vehicle(
        &self,
        myself: &ActorRef<CoordinatorMsg>,
        shared: Arc<VehicleShared>,
    ) -> Result<ActorRef<VehicleMsg>, ActorProcessingErr> {
        let path = Self::path(&shared.id);
        let (actor, _) = Actor::spawn_linked(
            None,
            Vehicle,
            VehicleArgs {
                shared,
                view: self.view.clone(),
                events: self.events.clone(),
                coordinator: myself.clone(),
                supervision: self.supervision.clone(),
            },
            myself.get_cell(),
        )
        .await?;
        self.supervision.started(&path, ChildKind::Vehicle);
        Ok(actor)
    }

    async fn on_discovered(
        &mut self,
        myself: &ActorRef<CoordinatorMsg>,
        endpoint_index: usize,
        d: Discovery,
    ) -> Result<(), ActorProcessingErr> {
        let Some((endpoint, spec)) = self.endpoints.get(endpoint_index) else {
            return Ok(());
        };
        let endpoint = endpoint.clone();
        let simulated = spec.simulated;
        let taken: Vec<&str> = self.vehicles.keys().map(String::as_str).collect();
        let vspec = spec
            .vehicles
            .iter()
            .find(|s| s.sysid == Some(d.sysid))
            .or_else(|| {
                spec.vehicles.iter().find(|s| {
                    s.sysid.is_none() && s.id.as_deref().is_none_or(|id| !taken.contains(&id))
                })
            })
            .cloned()
            .unwrap_or_default();
        let mut id = vspec.id.unwrap_or_else(|| format!("uav-{}", d.sysid));
        if self.vehicles.contains_key(&id) {
            id = format!("{id}-{endpoint_index}");
        }
        if self.vehicles.contains_key(&id) {
            return Ok(());
        }
        let model = self
            .view
            .config
            .model(vspec.model.as_deref().unwrap_or("generic"));
        let link = VehicleLink::new(
            endpoint.clone(),
            d.sysid,
            d.compid,
            self.view.config.stream_rate_hz,
            self.view.config.link_setup.clone(),
        );
        let shared = VehicleShared::new(id.clone(), model, link, simulated);
        self.view.add_vehicle(shared.clone());
        let actor = self.spawn_vehicle(myself, shared.clone()).await?;
        tracing::info!("{id} joined (sysid {}, {})", d.sysid, endpoint.address());
        self.emit(SwarmEvent::VehicleJoined {
            id: id.clone(),
            sysid: d.sysid,
            connection: endpoint.address().to_string(),
        });
        self.vehicles.insert(
            id,
            Entry {
                shared,
                actor: Some(actor),
                failed: false,
                safe_link: None,
            },
        );
        self.metrics.vehicles.set(self.vehicles.len() as i64);
        Ok(())
    }

    async fn command_vehicle(
        &self,
        id: &str,
        cmd: VehicleCommand,
        command_id: u64,
    ) -> Result<(), String> {
        let entry = &self.vehicles[id];
        let Some(actor) = &entry.actor else {
            return Err(if entry.failed {
                format!(
                    "{} refused: vehicle {id} has failed (its actor kept failing and it was commanded to {:?})",
                    cmd.name(),
                    self.view.config.supervision.vehicle_escalation
                )
            } else {
                format!(
                    "{} refused: vehicle {id} is restarting, try again",
                    cmd.name()
                )
            });
        };
        match ractor::call_t!(
            actor,
            VehicleMsg::Command,
            VEHICLE_CALL_TIMEOUT.as_millis() as u64,
            cmd,
            command_id
        ) {
            Ok(r) => r,
            Err(e) => Err(format!("vehicle {id} did not answer: {e}")),
        }
    }

    async fn run_command(&mut self, targets: Vec<String>, cmd: VehicleCommand) -> CommandOutcome {
        self.next_command_id += 1;
        let command_id = self.next_command_id;
        let mut outcome = CommandOutcome {
            command_id,
            accepted: vec![],
            refused: vec![],
        };
        for id in targets {
            if !self.vehicles.contains_key(&id) {
                continue;
            }
            match self.command_vehicle(&id, cmd.clone(), command_id).await {
                Ok(()) => outcome.accepted.push(id),
                Err(reason) => outcome.refused.push(Refused { id, reason }),
            }
        }
        outcome
    }

    fn positions(&self) -> Vec<(String, VehicleState, Option<Ned>, bool)> {
        let frame = self.view.frame();
        self.vehicles
            .iter()
            .map(|(id, e)| {
                let p = frame.and_then(|f| e.shared.position(&f));
                (id.clone(), e.shared.state(), p, e.failed)
            })
            .collect()
    }

    fn formation_status(&self) -> FormationStatus {
        let airborne: Vec<Ned> = self
            .positions()
            .into_iter()
            .filter(|(_, s, _, _)| s.is_airborne())
            .filter_map(|(_, _, p, _)| p)
            .collect();
        self.formation.status(&airborne)
    }

    async fn join_hovering(&mut self) {
        if !self.formation.is_active() {
            return;
        }
        let hovering: Vec<String> = self
            .vehicles
            .iter()
            .filter(|(_, e)| !e.failed && e.shared.state() == VehicleState::Hovering)
            .map(|(id, _)| id.clone())
            .collect();
        for id in hovering {
            if let Err(e) = self
                .command_vehicle(&id, VehicleCommand::JoinFormation, 0)
                .await
            {
                tracing::debug!("{id} could not join the formation: {e}");
            }
        }
    }

    fn formation_tick(&mut self) {
        // Vehicles without an actor still show their telemetry.
        let frame = self.view.frame();
        for e in self.vehicles.values().filter(|e| e.failed) {
            e.shared.settle_from_telemetry();
            e.shared.publish(frame, None, &self.supervision);
        }
        let status = self.formation_status();
        self.metrics
            .formation_rms_error_m
            .set(status.rms_error_m.unwrap_or(f64::NAN));
        self.metrics
            .min_separation_m
            .set(status.min_separation_m.unwrap_or(f64::NAN));
        for m in &status.members {
            self.metrics
                .slot_error_m
                .get_or_create(&Metrics::label("vehicle", &m.id))
                .set(m.error_m);
        }
        let now = Instant::now();
        let dt = now
            .duration_since(self.last_formation_tick)
            .as_secs_f64()
            .min(0.5);
        self.last_formation_tick = now;
        if !self.formation.is_active() {
            return;
        }
        let Some(frame) = frame else { return };
        let members: BTreeMap<String, Member> = self
            .vehicles
            .iter()
            .filter(|(_, e)| !e.failed && e.shared.state() == VehicleState::InFormation)
            .filter_map(|(id, e)| {
                Some((
                    id.clone(),
                    Member {
                        position: e.shared.position(&frame)?,
                        velocity: e.shared.velocity().unwrap_or(Ned::ZERO),
                        heading_rad: e.shared.heading_rad(),
                        silence: e.shared.link.silence().unwrap_or(Duration::MAX),
                        target: e.shared.target_position(),
                    },
                ))
            })
            .collect();
        let slots = self
            .formation
            .tick(&members, dt, &self.view.config.geofence);
        if self.formation.take_pending_applied() {
            let status = serde_json::to_value(self.formation_status()).unwrap_or_default();
            self.emit(SwarmEvent::FormationChanged { formation: status });
        }
        for change in self.formation.take_leader_changes() {
            tracing::info!(
                "formation leader {} -> {} ({})",
                change.from.as_deref().unwrap_or("none"),
                change.to,
                change.reason
            );
            self.emit(SwarmEvent::LeaderChanged {
                from: change.from,
                to: change.to,
                reason: change.reason,
            });
        }
        for (id, s) in slots {
            if let Some(actor) = self.vehicles.get(&id).and_then(|e| e.actor.as_ref()) {
                let _ = actor.cast(VehicleMsg::Slot(Some(SlotTarget {
                    slot: s.slot,
                    leader: s.leader,
                    position: s.position,
                    goal: s.goal,
                    velocity: s.velocity,
                    yaw_rad: s.yaw_rad,
                })));
            }
        }
    }

    fn validate_motion(&self, motion: &LeaderMotion) -> Result<(), FieldError> {
        let err = |field: &str, error: String| {
            Err(FieldError {
                field: field.into(),
                error,
            })
        };
        let max = self
            .view
            .config
            .models
            .values()
            .map(|m| m.limits.max_speed_m_s)
            .fold(f64::INFINITY, f64::min)
            .min(skein_model::safety::MotionLimits::default().max_speed_m_s);
        let speed = match motion {
            LeaderMotion::Hold => return Ok(()),
            LeaderMotion::GoTo { speed_m_s, .. }
            | LeaderMotion::Waypoints { speed_m_s, .. }
            | LeaderMotion::Orbit { speed_m_s, .. } => *speed_m_s,
        };
        if !(speed.is_finite() && speed > 0.0 && speed <= max) {
            return err(
                "speed_m_s",
                format!(
                    "speed_m_s {speed} outside (0, {max}] m/s (the slowest vehicle model's limit)"
                ),
            );
        }
        let fence = &self.view.config.geofence;
        let inside = |p: &Ned| fence.contains(*p);
        match motion {
            LeaderMotion::GoTo { target, .. } if !inside(target) => err(
                "north_m",
                format!(
                    "the point ({:.1}, {:.1}, {:.1}) is outside the geofence",
                    target.north_m, target.east_m, target.down_m
                ),
            ),
            LeaderMotion::Waypoints { points, .. } => {
                if points.is_empty() {
                    return err("waypoints", "waypoints is empty".into());
                }
                match points.iter().position(|p| !inside(p)) {
                    Some(i) => err(
                        "waypoints",
                        format!("waypoints[{i}] is outside the geofence"),
                    ),
                    None => Ok(()),
                }
            }
            LeaderMotion::Orbit {
                centre, radius_m, ..
            } => {
                if !(radius_m.is_finite() && *radius_m >= self.view.config.setpoint_separation_m())
                {
                    return err(
                        "radius_m",
                        format!(
                            "radius_m {radius_m} must be at least the minimum separation plus margin ({} m)",
                            self.view.config.setpoint_separation_m()
                        ),
                    );
                }
                if !inside(centre) || centre.horizontal_norm() + radius_m > fence.radius_m {
                    return err("radius_m", "the orbit leaves the geofence".into());
                }
                Ok(())
            }
            _ => Ok(()),
        }
    }

    fn validate_formation(&self, spec: &FormationSpec) -> Result<(), FieldError> {
        let err = |field: &str, error: String| {
            Err(FieldError {
                field: field.into(),
                error,
            })
        };
        let min_sep = self.view.config.min_separation_m;
        let custom = spec.shape == skein_model::formation::Shape::Custom;
        if !custom && (!spec.spacing_m.is_finite() || spec.spacing_m <= 0.0) {
            return err(
                "spacing_m",
                format!(
                    "spacing_m must be a positive number of metres, got {}",
                    spec.spacing_m
                ),
            );
        }
        let margin = self.view.config.separation_margin_m;
        // Transitions keep members 1/√2 of the slot distance apart (see `formation`).
        let needed = self.view.config.min_slot_distance_m();
        if !custom && spec.spacing_m < needed - 1e-9 {
            return err(
                "spacing_m",
                format!(
                    "spacing_m {} is below √2 × (the minimum separation of {min_sep} m + the {margin} m tracking margin) = {needed:.2} m, what formation changes need to keep the separation",
                    spec.spacing_m
                ),
            );
        }
        if let Some(leader) = &spec.leader
            && leader != VIRTUAL
            && !self.vehicles.contains_key(leader)
        {
            return err(
                "leader",
                format!("unknown leader `{leader}` (a vehicle id, or \"virtual\")"),
            );
        }
        if spec.shape == skein_model::formation::Shape::Custom {
            if spec.offsets.is_empty() {
                return err("offsets", "a custom formation needs offsets".into());
            }
            if let Some(i) = spec.offsets.iter().position(|o| !o.is_finite()) {
                return err("offsets", format!("offsets[{i}] must be finite numbers"));
            }
            let all = skein_model::formation::custom_offsets(&spec.offsets);
            if let Some(d) = skein_model::formation::min_slot_distance(&all)
                && d < needed
            {
                return err(
                    "offsets",
                    format!(
                        "two slots are {d:.2} m apart, below √2 × (the minimum separation of {min_sep} m + the {margin} m tracking margin) = {needed:.2} m"
                    ),
                );
            }
        } else if !spec.offsets.is_empty() {
            return err(
                "offsets",
                format!(
                    "offsets are for shape `custom`, not `{}`",
                    spec.shape.name()
                ),
            );
        }
        if !spec.heading_deg.is_finite() {
            return err("heading_deg", "heading_deg must be a number".into());
        }
        if let Some(a) = spec.altitude_m
            && !(a.is_finite() && a > 0.0 && a <= self.view.config.geofence.max_altitude_m)
        {
            return err(
                "altitude_m",
                format!(
                    "altitude_m {a} outside (0, {}] m",
                    self.view.config.geofence.max_altitude_m
                ),
            );
        }
        // The vehicles that would fly it: the airborne healthy ones, or every connected
        // one when the formation is set before takeoff.
        let usable = |s: VehicleState| {
            matches!(
                s,
                VehicleState::Hovering | VehicleState::InFormation | VehicleState::GoTo
            )
        };
        let airborne = self
            .vehicles
            .values()
            .filter(|e| !e.failed && usable(e.shared.state()))
            .count();
        let n = if airborne > 0 {
            airborne
        } else {
            self.vehicles
                .values()
                .filter(|e| !e.failed && e.shared.state().is_connected())
                .count()
        };
        if n < spec.shape.min_vehicles() {
            return err(
                "shape",
                format!(
                    "shape `{}` needs at least {} vehicles, {n} can fly it",
                    spec.shape.name(),
                    spec.shape.min_vehicles()
                ),
            );
        }
        Ok(())
    }

    // ------------------------------------------------------------------ supervision

    /// The vehicle id or service name an actor belongs to.
    fn child_of(&self, id: ActorId) -> Option<String> {
        self.vehicles
            .iter()
            .find(|(_, e)| e.actor.as_ref().is_some_and(|a| a.get_id() == id))
            .map(|(name, _)| name.clone())
            .or_else(|| {
                self.services
                    .iter()
                    .find(|(_, s)| s.actor.as_ref().is_some_and(|a| a.get_id() == id))
                    .map(|(name, _)| name.clone())
            })
    }

    fn kind_of(&self, name: &str) -> ChildKind {
        self.services
            .get(name)
            .map_or(ChildKind::Vehicle, |s| s.spec.kind)
    }

    fn cell_of(&self, name: &str) -> Option<ActorCell> {
        self.vehicles
            .get(name)
            .and_then(|e| e.actor.as_ref().map(|a| a.get_cell()))
            .or_else(|| {
                self.services
                    .get(name)
                    .and_then(|s| s.actor.as_ref().map(|a| a.get_cell()))
            })
    }

    async fn start_child(
        &mut self,
        myself: &ActorRef<CoordinatorMsg>,
        name: &str,
    ) -> Result<(), ActorProcessingErr> {
        if let Some(entry) = self.vehicles.get(name) {
            let actor = self.spawn_vehicle(myself, entry.shared.clone()).await?;
            self.vehicles.get_mut(name).expect("present").actor = Some(actor);
        } else if let Some(svc) = self.services.get(name) {
            let spec = svc.spec.clone();
            let actor = (spec.spawn)(myself.get_cell()).await?;
            self.supervision.started(&Self::path(name), spec.kind);
            self.services.get_mut(name).expect("present").actor = Some(actor);
        }
        Ok(())
    }

    async fn restart_child(
        &mut self,
        myself: &ActorRef<CoordinatorMsg>,
        name: String,
        noticed: Instant,
        reason: String,
    ) -> Result<(), ActorProcessingErr> {
        let kind = self.kind_of(&name);
        match self.start_child(myself, &name).await {
            Ok(()) => {
                let sup = self.supervision.clone();
                let path = Self::path(&name);
                let deadline = Some(self.supervision.config.watchdog_deadline());
                let vehicle = self.vehicles.get(&name).and_then(|e| e.actor.clone());
                let service = self.services.get(&name).and_then(|s| s.actor.clone());
                tokio::spawn(async move {
                    let answered = match (vehicle, service) {
                        (Some(v), _) => matches!(
                            v.call(VehicleMsg::Ping, deadline).await,
                            Ok(ractor::rpc::CallResult::Success(()))
                        ),
                        (_, Some(s)) => matches!(
                            s.call(ServiceMsg::Ping, deadline).await,
                            Ok(ractor::rpc::CallResult::Success(()))
                        ),
                        _ => false,
                    };
                    if answered {
                        sup.restarted(&path, kind, &reason, noticed.elapsed());
                    }
                });
                Ok(())
            }
            Err(e) => {
                Box::pin(self.child_ended(
                    myself,
                    name,
                    Exit::Failed(format!("restart failed: {e}")),
                ))
                .await
            }
        }
    }

    async fn child_ended(
        &mut self,
        myself: &ActorRef<CoordinatorMsg>,
        name: String,
        exit: Exit,
    ) -> Result<(), ActorProcessingErr> {
        let noticed = Instant::now();
        let kind = self.kind_of(&name);
        if let Some(e) = self.vehicles.get_mut(&name) {
            e.actor = None;
        }
        if let Some(s) = self.services.get_mut(&name) {
            s.actor = None;
        }
        let path = Self::path(&name);
        let reason = exit.reason();
        match self.supervision.exit(&path, kind, exit) {
            Decision::Restart(d) if d.is_zero() => {
                self.restart_child(myself, name, noticed, reason).await?;
            }
            Decision::Restart(d) => {
                myself.send_after(d, move || {
                    CoordinatorMsg::RestartChild(name, noticed, reason)
                });
            }
            Decision::Escalate | Decision::Leave if kind == ChildKind::Vehicle => {
                // A vehicle left without its actor must not fly on unattended.
                self.escalate_vehicle(myself, &name).await;
            }
            Decision::Escalate => {
                return Err(format!(
                    "{path} keeps failing ({reason}): the coordinator gives up so that the \
                     process exits and its supervisor restarts it"
                )
                .into());
            }
            Decision::Leave => {}
        }
        Ok(())
    }

    /// Commands the vehicle to HOLD or LAND through a fresh link actor (the Vehicle actor
    /// and its own link are gone), stops its setpoint stream once PX4 has switched, and
    /// marks it failed.
    async fn escalate_vehicle(&mut self, myself: &ActorRef<CoordinatorMsg>, name: &str) {
        let Some(entry) = self.vehicles.get_mut(name) else {
            return;
        };
        entry.failed = true;
        entry.actor = None;
        let shared = entry.shared.clone();
        let action = self.view.config.supervision.vehicle_escalation;
        let events: skein_link::EventSink = Arc::new(|_| {});
        let spawned = Actor::spawn_linked(
            None,
            Px4Link,
            Px4LinkArgs {
                link: shared.link.clone(),
                events,
                components: None,
            },
            myself.get_cell(),
        )
        .await;
        let path = Self::path(name);
        let mode = match action {
            VehicleEscalation::Hold => Px4Mode::Hold,
            VehicleEscalation::Land => Px4Mode::Land,
        };
        match spawned {
            Ok((link, _)) => {
                entry.safe_link = Some(link.clone());
                let sup = self.supervision.clone();
                tokio::spawn(async move {
                    let r = ractor::call_t!(
                        link,
                        Px4LinkMsg::Command,
                        15_000,
                        LinkCommand::SetMode(mode)
                    );
                    match r {
                        Ok(Ok(())) => {
                            // PX4 flies on its own now: the stream may stop.
                            shared.link.stream().set(None);
                            sup.escalated(
                                &path,
                                &format!("vehicle commanded to {mode} through a safe-mode link"),
                            );
                        }
                        other => {
                            let why = match other {
                                Ok(Err(e)) => e.to_string(),
                                Err(e) => e.to_string(),
                                Ok(Ok(())) => unreachable!(),
                            };
                            // Keep streaming the last (held) setpoint: PX4 stays in
                            // OFFBOARD holding position rather than failing safe.
                            sup.escalated(
                                &path,
                                &format!(
                                    "{mode} not confirmed ({why}); the stream keeps holding the last setpoint"
                                ),
                            );
                        }
                    }
                });
            }
            Err(e) => {
                self.supervision.escalated(
                    &path,
                    &format!("no safe-mode link ({e}); the stream keeps holding the last setpoint"),
                );
            }
        }
    }

    fn watch_children(&self, myself: &ActorRef<CoordinatorMsg>) {
        let deadline = self.supervision.config.watchdog_deadline();
        for (name, e) in &self.vehicles {
            if let Some(a) = &e.actor {
                let me = myself.clone();
                let (name, id) = (name.clone(), a.get_id());
                supervision::watch(a.clone(), VehicleMsg::Ping, deadline, move || {
                    let _ = me.cast(CoordinatorMsg::ChildHung(name, id));
                });
            }
        }
        for (name, s) in &self.services {
            if let Some(a) = &s.actor {
                let me = myself.clone();
                let (name, id) = (name.clone(), a.get_id());
                supervision::watch(a.clone(), ServiceMsg::Ping, deadline, move || {
                    let _ = me.cast(CoordinatorMsg::ChildHung(name, id));
                });
            }
        }
    }

    /// Routes a fault to the actor at `path`.
    fn inject(
        &self,
        myself: &ActorRef<CoordinatorMsg>,
        path: &str,
        kind: FaultKind,
        reply: RpcReplyPort<Result<(), FaultError>>,
    ) {
        if !self.view.config.fault_injection {
            let _ = reply.send(Err(FaultError::Disabled));
            return;
        }
        let unknown = || {
            FaultError::UnknownTarget(format!(
                "no actor `{path}` (known: {})",
                self.supervision.paths().join(", ")
            ))
        };
        let Some(rest) = path.strip_prefix(supervision::ROOT) else {
            let _ = reply.send(Err(unknown()));
            return;
        };
        if rest.is_empty() {
            let _ = reply.send(Ok(()));
            let _ = myself.cast(CoordinatorMsg::Fault(kind));
            return;
        }
        let rest = rest.trim_start_matches('/');
        let (name, sub) = rest.split_once('/').unwrap_or((rest, ""));
        if let Some(s) = self.services.get(name) {
            let r = match (&s.actor, sub) {
                (Some(a), "") => a
                    .cast(ServiceMsg::Fault(kind))
                    .map_err(|e| FaultError::Unreachable(e.to_string())),
                (None, "") => Err(FaultError::Unreachable(format!("{path} is not running"))),
                _ => Err(unknown()),
            };
            let _ = reply.send(r);
            return;
        }
        match self.vehicles.get(name) {
            Some(e) => match &e.actor {
                Some(a) => {
                    // The vehicle answers (it knows its children).
                    let sub = sub.to_string();
                    let a = a.clone();
                    tokio::spawn(async move {
                        let r = match a
                            .call(
                                |r| VehicleMsg::InjectFault(sub, kind, r),
                                Some(VEHICLE_CALL_TIMEOUT),
                            )
                            .await
                        {
                            Ok(ractor::rpc::CallResult::Success(Ok(()))) => Ok(()),
                            Ok(ractor::rpc::CallResult::Success(Err(why))) => {
                                Err(FaultError::UnknownTarget(why))
                            }
                            _ => Err(FaultError::Unreachable("the vehicle did not answer".into())),
                        };
                        let _ = reply.send(r);
                    });
                }
                None => {
                    let _ = reply.send(Err(FaultError::Unreachable(format!(
                        "{} is not running (restarting or failed)",
                        Self::path(name)
                    ))));
                }
            },
            None => {
                let _ = reply.send(Err(unknown()));
            }
        }
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
        myself.send_interval(period, || CoordinatorMsg::FormationTick);
        let supervision = Supervision::new(
            args.config.supervision.clone(),
            args.metrics.clone(),
            args.events.clone(),
        );
        myself.send_interval(supervision.config.watchdog_period(), || {
            CoordinatorMsg::WatchTick
        });
        let separation_m = args.config.setpoint_separation_m();
        Ok(CoordinatorState {
            view: Arc::new(SwarmView::new(args.config, args.services)),
            endpoints: args.endpoints,
            vehicles: BTreeMap::new(),
            services: BTreeMap::new(),
            formation: FormationEngine::new(separation_m),
            events: args.events,
            metrics: args.metrics,
            supervision,
            hung: HashSet::new(),
            next_command_id: 0,
            started: Instant::now(),
            last_formation_tick: Instant::now(),
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
            CoordinatorMsg::VehicleState { id: _, state: s } => {
                if s == VehicleState::Hovering {
                    state.join_hovering().await;
                }
            }
            CoordinatorMsg::SwarmCommand(cmd, reply) => {
                if matches!(cmd, VehicleCommand::Land | VehicleCommand::Rtl)
                    && state.formation.is_active()
                {
                    state.formation.deactivate();
                    let status = serde_json::to_value(state.formation_status()).unwrap_or_default();
                    state.emit(SwarmEvent::FormationChanged { formation: status });
                }
                let targets = state.vehicles.keys().cloned().collect();
                let outcome = state.run_command(targets, cmd).await;
                let _ = reply.send(outcome);
            }
            CoordinatorMsg::VehicleCommand(id, cmd, reply) => {
                if !state.vehicles.contains_key(&id) {
                    let _ = reply.send(Err(None));
                } else {
                    let outcome = state.run_command(vec![id], cmd).await;
                    let r = match outcome.refused.first() {
                        Some(refused) => Err(Some(refused.reason.clone())),
                        None => Ok(outcome),
                    };
                    let _ = reply.send(r);
                }
            }
            CoordinatorMsg::ListVehicles(reply) => {
                let list = state
                    .vehicles
                    .values()
                    .map(|e| e.shared.snapshot())
                    .collect();
                let _ = reply.send(list);
            }
            CoordinatorMsg::GetVehicle(id, reply) => {
                let _ = reply.send(state.vehicles.get(&id).map(|e| e.shared.snapshot()));
            }
            CoordinatorMsg::GetFormation(reply) => {
                let _ = reply.send(state.formation_status());
            }
            CoordinatorMsg::SetFormation(spec, reply) => match state.validate_formation(&spec) {
                Err(e) => {
                    let _ = reply.send(Err(e));
                }
                Ok(()) => {
                    state.formation.set(spec);
                    state.join_hovering().await;
                    state.formation_tick();
                    let status = state.formation_status();
                    state.emit(SwarmEvent::FormationChanged {
                        formation: serde_json::to_value(&status).unwrap_or_default(),
                    });
                    let _ = reply.send(Ok(status));
                }
            },
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
                let r = state.validate_motion(&motion).and_then(|()| {
                    state.formation.set_motion(motion).map_err(|e| FieldError {
                        field: "formation".into(),
                        error: e,
                    })
                });
                let _ = reply.send(r.map(|()| state.formation_status()));
            }
            CoordinatorMsg::ClearFormation(reply) => {
                state.formation.deactivate();
                let members: Vec<String> = state
                    .vehicles
                    .iter()
                    .filter(|(_, e)| e.shared.state() == VehicleState::InFormation)
                    .map(|(id, _)| id.clone())
                    .collect();
                for id in members {
                    let _ = state
                        .command_vehicle(&id, VehicleCommand::LeaveFormation, 0)
                        .await;
                }
                let status = state.formation_status();
                state.emit(SwarmEvent::FormationChanged {
                    formation: serde_json::to_value(&status).unwrap_or_default(),
                });
                let _ = reply.send(status);
            }
            CoordinatorMsg::Health(reply) => {
                let connected = state
                    .vehicles
                    .values()
                    .filter(|e| e.shared.state().is_connected())
                    .count();
                state.metrics.vehicles_connected.set(connected as i64);
                let _ = reply.send(Health {
                    status: "ok",
                    vehicles: state.vehicles.len(),
                    connected,
                    uptime_s: state.started.elapsed().as_secs_f64(),
                    swarm_origin: state.view.frame().map(|f| f.origin),
                    fault_injection: state.view.config.fault_injection,
                });
            }
            CoordinatorMsg::LinkStats(reply) => {
                let stats = state
                    .endpoints
                    .iter()
                    .map(|(e, _)| EndpointStats {
                        connection: e.address().to_string(),
                        local_addr: e.local_addr().map(|a| a.to_string()),
                        decode: e.decode_counts(),
                        send: e.send_counts(),
                    })
                    .collect();
                let _ = reply.send(stats);
            }
            CoordinatorMsg::GetVehicleActor(id, reply) => {
                let _ = reply.send(state.vehicles.get(&id).and_then(|e| e.actor.clone()));
            }
            CoordinatorMsg::GetPayload(id, slot, reply) => {
                let r = match state.vehicles.get(&id) {
                    None => Err(format!("no vehicle `{id}`")),
                    Some(e) => e.shared.payloads.get(&slot).cloned().ok_or_else(|| {
                        format!(
                            "vehicle {id} has no payload slot `{slot}` (slots: {})",
                            e.shared
                                .payloads
                                .keys()
                                .cloned()
                                .collect::<Vec<_>>()
                                .join(", ")
                        )
                    }),
                };
                let _ = reply.send(r);
            }
            CoordinatorMsg::PayloadCommand(id, slot, cmd, reply) => match state.vehicles.get(&id) {
                None => {
                    let _ = reply.send(Err(PayloadCommandError::NotFound(format!(
                        "no vehicle `{id}`"
                    ))));
                }
                Some(e) if !e.shared.payloads.contains_key(&slot) => {
                    let slots = e
                        .shared
                        .payloads
                        .keys()
                        .cloned()
                        .collect::<Vec<_>>()
                        .join(", ");
                    let _ = reply.send(Err(PayloadCommandError::NotFound(format!(
                        "vehicle {id} has no payload slot `{slot}` (slots: {slots})"
                    ))));
                }
                Some(e) => match &e.actor {
                    None => {
                        let _ = reply.send(Err(PayloadCommandError::Unavailable(format!(
                            "vehicle {id} is not running"
                        ))));
                    }
                    Some(a) => {
                        let a = a.clone();
                        tokio::spawn(async move {
                            let r = match a
                                .call(
                                    |r| VehicleMsg::PayloadCommand(slot, cmd, r),
                                    Some(Duration::from_secs(10)),
                                )
                                .await
                            {
                                Ok(ractor::rpc::CallResult::Success(r)) => r,
                                _ => Err(PayloadCommandError::Unavailable(
                                    "the vehicle did not answer".into(),
                                )),
                            };
                            let _ = reply.send(r);
                        });
                    }
                },
            },
            CoordinatorMsg::RefreshPayloads(instances, at) => {
                for (id, slot) in instances {
                    if let Some(a) = state.vehicles.get(&id).and_then(|e| e.actor.as_ref()) {
                        let _ = a.cast(VehicleMsg::RefreshPayload(slot, at));
                    }
                }
            }
            CoordinatorMsg::GetSupervision(reply) => {
                let _ = reply.send(state.supervision.tree());
            }
            CoordinatorMsg::RenderMetrics(reply) => {
                for (e, _) in &state.endpoints {
                    state
                        .metrics
                        .mavlink_malformed
                        .get_or_create(&Metrics::label("connection", &e.address().to_string()))
                        .set(e.decode_counts().errors() as i64);
                }
                for (id, e) in &state.vehicles {
                    state
                        .metrics
                        .setpoints_sent
                        .get_or_create(&Metrics::label("vehicle", id))
                        .set(e.shared.link.stream().counts().sent as i64);
                }
                let _ = reply.send(state.metrics.render());
            }
            CoordinatorMsg::AddService(spec, reply) => {
                let name = spec.name.clone();
                state
                    .services
                    .insert(name.clone(), Service { spec, actor: None });
                let r = state
                    .start_child(&myself, &name)
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
            CoordinatorMsg::FormationTick => state.formation_tick(),
            CoordinatorMsg::WatchTick => state.watch_children(&myself),
            CoordinatorMsg::ChildHung(name, id) => {
                let current = state.cell_of(&name).filter(|c| c.get_id() == id);
                if let Some(cell) = current
                    && state.hung.insert(id)
                {
                    tracing::warn!("{} hung: killing it", CoordinatorState::path(&name));
                    cell.kill();
                }
            }
            CoordinatorMsg::RestartChild(name, noticed, reason) => {
                if state.cell_of(&name).is_none()
                    && !state.vehicles.get(&name).is_some_and(|e| e.failed)
                {
                    state.restart_child(&myself, name, noticed, reason).await?;
                }
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
        let deadline = state.supervision.config.watchdog_deadline();
        let (id, exit) = match evt {
            SupervisionEvent::ActorFailed(cell, reason) => {
                let id = cell.get_id();
                let exit = if state.hung.remove(&id) {
                    Exit::Hung(deadline)
                } else {
                    Exit::Failed(reason.to_string())
                };
                (id, exit)
            }
            SupervisionEvent::ActorTerminated(cell, _, reason) => {
                let id = cell.get_id();
                let exit = if state.hung.remove(&id) {
                    Exit::Hung(deadline)
                } else {
                    Exit::Stopped(reason)
                };
                (id, exit)
            }
            _ => return Ok(()),
        };
        if let Some(name) = state.child_of(id) {
            state.child_ended(&myself, name, exit).await?;
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

/// A running swarm: the coordinator, its endpoints, the event bus and the metrics.
pub struct Swarm {
    /// The coordinator actor.
    pub coordinator: ActorRef<CoordinatorMsg>,
    /// The event bus (subscribe for the stream).
    pub events: broadcast::Sender<SwarmEvent>,
    /// The opened endpoints, in configuration order.
    pub endpoints: Vec<Arc<Endpoint>>,
    handle: ractor::concurrency::JoinHandle<()>,
}

/// Why the swarm could not start.
#[derive(Debug)]
pub struct StartError(pub String);

impl std::fmt::Display for StartError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for StartError {}

impl Swarm {
    /// Opens every endpoint and starts the coordinator.
    ///
    /// # Errors
    /// An endpoint that cannot be opened (named with its connection string), or the
    /// coordinator failing to start.
    pub async fn start(
        config: SwarmConfig,
        services: SwarmServices,
        identity: Identity,
        endpoints: Vec<EndpointSpec>,
    ) -> Result<Swarm, StartError> {
        let mut opened = Vec::new();
        for spec in endpoints {
            let ep = Endpoint::open(spec.connection.clone(), identity)
                .await
                .map_err(|e| StartError(format!("{}: {e}", spec.connection)))?;
            opened.push((ep, spec));
        }
        let (events, _) = broadcast::channel(4096);
        let endpoints = opened.iter().map(|(e, _)| e.clone()).collect();
        let (coordinator, handle) = Actor::spawn(
            None,
            Coordinator,
            CoordinatorArgs {
                config,
                services,
                endpoints: opened,
                events: events.clone(),
                metrics: Arc::new(Metrics::new()),
            },
        )
        .await
        .map_err(|e| StartError(format!("coordinator did not start: {e}")))?;
        Ok(Swarm {
            coordinator,
            events,
            endpoints,
            handle,
        })
    }

    /// Resolves when the coordinator has stopped or failed (for the process to exit).
    pub async fn stopped(&mut self) {
        let _ = (&mut self.handle).await;
    }

    /// True when the coordinator is still running.
    pub fn is_running(&self) -> bool {
        !self.handle.is_finished()
    }

    /// Stops the coordinator (and with it every actor under it) and waits for it.
    pub async fn stop(self) {
        self.coordinator.stop(None);
        let _ = self.handle.await;
    }
}
