//! The `Vehicle` actor: one per UAV, owner of its FSM and of what its setpoint stream
//! carries.
//!
//! It supervises its `Px4Link` child (restarting it on failure with the same
//! [`VehicleLink`], so the socket, telemetry and setpoint stream are untouched), turns
//! link events into FSM events, checks every operator command against the FSM, and runs
//! the multi-step operations (takeoff, hold, go-to) as tasks that post their outcome
//! back as messages, so the actor never blocks.
//!
//! Its control loop ([`SwarmConfig::control_rate_hz`]) shapes the current target through
//! the [`SetpointShaper`] (speed and acceleration limits, geofence, separation), converts
//! the result from the swarm frame to the vehicle's own local NED frame through geodetic
//! coordinates, and hands it to the stream.
//!
//! Everything a restarted Vehicle actor must resume with (FSM state, target, slot, shaper)
//! lives in [`VehicleShared`], owned by the coordinator.

use crate::coordinator::CoordinatorMsg;
use crate::events::SwarmEvent;
use crate::payload::{PayloadActor, PayloadArgs, PayloadMsg, PayloadShared, VehiclePayloadHost};
use crate::supervision::{self, Decision, Exit, Supervision};
use crate::view::{SwarmConfig, SwarmView, VehicleModel};
use ractor::{
    Actor, ActorCell, ActorId, ActorProcessingErr, ActorRef, RpcReplyPort, SupervisionEvent,
};
use skein_link::px4link::LinkEvent;
use skein_link::{LinkCommand, LocalSetpoint, Px4Link, Px4LinkArgs, Px4LinkMsg, VehicleLink};
use skein_model::fsm::{self, Command, Event, Observed, VehicleState};
use skein_model::geo::{Ned, NedFrame, wrap_deg_360};
use skein_model::px4::Px4Mode;
use skein_model::safety::{FenceViolation, SetpointShaper};
use skein_model::supervision::{ChildKind, ChildStatus, FaultKind};
use std::collections::{BTreeMap, HashSet};
use std::sync::{MutexGuard, PoisonError};

use skein_model::vehicle::{
    Battery, FormationSlot, LinkStatus, Position, VehicleSnapshot, Velocity,
};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::{broadcast, watch};

/// Distance to a takeoff altitude or go-to point that counts as arrived, metres.
pub const ARRIVAL_TOLERANCE_M: f64 = 0.5;
/// How long PX4 must have seen setpoints before OFFBOARD is requested (PX4 needs > 1 s).
pub const OFFBOARD_PRESTREAM: Duration = Duration::from_millis(1100);

/// An operator command with its parameters.
#[derive(Debug, Clone, PartialEq)]
pub enum VehicleCommand {
    /// Arm on the ground.
    Arm,
    /// Disarm (forced: in any state, stops the motors).
    Disarm {
        /// Emergency disarm.
        force: bool,
    },
    /// Arm if needed, enter offboard, climb to `altitude_m` above home.
    Takeoff {
        /// Altitude above home, metres; `None` = the configured default.
        altitude_m: Option<f64>,
    },
    /// Land where it is.
    Land,
    /// Return to launch.
    Rtl,
    /// Hold the current position under offboard control.
    Hold,
    /// Fly to a swarm-frame point under offboard control.
    GoTo {
        /// Target, swarm-frame NED metres.
        target: Ned,
    },
    /// Track the formation slot the coordinator gives.
    JoinFormation,
    /// Stop tracking the slot and hold.
    LeaveFormation,
}

impl VehicleCommand {
    /// The FSM's view of the command.
    pub fn fsm(&self) -> Command {
        match self {
            VehicleCommand::Arm => Command::Arm,
            VehicleCommand::Disarm { force } => Command::Disarm { force: *force },
            VehicleCommand::Takeoff { .. } => Command::Takeoff,
            VehicleCommand::Land => Command::Land,
            VehicleCommand::Rtl => Command::Rtl,
            VehicleCommand::Hold => Command::Hold,
            VehicleCommand::GoTo { .. } => Command::GoTo,
            VehicleCommand::JoinFormation => Command::JoinFormation,
            VehicleCommand::LeaveFormation => Command::LeaveFormation,
        }
    }

    /// The API name (`"takeoff"`).
    pub fn name(&self) -> &'static str {
        self.fsm().name()
    }
}

/// A formation slot target from the coordinator (swarm frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlotTarget {
    /// Slot index (0 = leader).
    pub slot: usize,
    /// True for the leader.
    pub leader: bool,
    /// Where the member should be now, swarm-frame NED metres: the slot, or its planned
    /// place on the way there during a formation change.
    pub position: Ned,
    /// The slot itself (where a formation change ends), swarm-frame NED metres.
    pub goal: Ned,
    /// Velocity (feed-forward) of `position`, NED m/s.
    pub velocity: Ned,
    /// Heading to hold, radians clockwise from north.
    pub yaw_rad: f64,
}

/// What the streamed setpoint is aiming at.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Target {
    /// Hold a point.
    Hold(Ned),
    /// Track a moving point (formation slot), known at `at`: between the formation's
    /// updates it moves on at its velocity.
    Track {
        position: Ned,
        velocity: Ned,
        at: Instant,
    },
}

/// Longest a moving target is extrapolated from its last update (the formation loop
/// updates it ten times a second; after this, hold where it would be).
const TRACK_EXTRAPOLATION: Duration = Duration::from_millis(500);

impl Target {
    fn position(&self) -> Ned {
        match self {
            Target::Hold(p) => *p,
            Target::Track { position, .. } => *position,
        }
    }

    /// Position and velocity feed-forward now.
    fn now(&self, now: Instant) -> (Ned, Ned) {
        match *self {
            Target::Hold(p) => (p, Ned::ZERO),
            Target::Track {
                position,
                velocity,
                at,
            } => {
                let age = now.saturating_duration_since(at);
                if age > TRACK_EXTRAPOLATION {
                    (
                        position + velocity * TRACK_EXTRAPOLATION.as_secs_f64(),
                        Ned::ZERO,
                    )
                } else {
                    (position + velocity * age.as_secs_f64(), velocity)
                }
            }
        }
    }
}

#[derive(Debug)]
struct Memory {
    state: VehicleState,
    target: Option<Target>,
    shaper: Option<SetpointShaper>,
    slot: Option<SlotTarget>,
    yaw_rad: f64,
    /// Generation of the running procedure; results of older ones are ignored.
    procedure: u64,
    /// The takeoff procedure has PX4 in OFFBOARD and the climb target is set.
    offboard_engaged: bool,
    takeoff_altitude_m: f64,
    goto_target: Option<Ned>,
    last_fence: Option<FenceViolation>,
}

/// The part of a vehicle that outlives its actor: identity, link, FSM memory and the
/// published snapshot.
pub struct VehicleShared {
    /// User-facing id (`uav-<sysid>` by default).
    pub id: String,
    /// Vehicle model.
    pub model: VehicleModel,
    /// The link state (endpoint route, telemetry, setpoint stream).
    pub link: Arc<VehicleLink>,
    /// True for a vehicle of the in-process simulator.
    pub simulated: bool,
    /// The payload slots of its model, with what each published.
    pub payloads: Arc<BTreeMap<String, Arc<PayloadShared>>>,
    memory: Mutex<Memory>,
    snapshot: watch::Sender<VehicleSnapshot>,
}

impl std::fmt::Debug for VehicleShared {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VehicleShared")
            .field("id", &self.id)
            .finish_non_exhaustive()
    }
}

impl VehicleShared {
    /// A vehicle never heard from, in [`VehicleState::Disconnected`].
    pub fn new(
        id: String,
        model: VehicleModel,
        link: Arc<VehicleLink>,
        simulated: bool,
    ) -> Arc<Self> {
        let payloads = Arc::new(
            model
                .payloads
                .iter()
                .map(|p| (p.slot.clone(), PayloadShared::new(p.clone())))
                .collect(),
        );
        let snapshot = VehicleSnapshot {
            id: id.clone(),
            sysid: link.sysid,
            model: model.name.clone(),
            state: VehicleState::Disconnected,
            armed: false,
            px4_mode: "UNKNOWN".into(),
            landed_state: Default::default(),
            position: None,
            velocity: Velocity::default(),
            heading_deg: 0.0,
            battery: None,
            link: LinkStatus {
                connected: false,
                last_seen_ms: 0,
            },
            formation: None,
            payloads: vec![],
        };
        Arc::new(VehicleShared {
            id,
            model,
            link,
            simulated,
            payloads,
            memory: Mutex::new(Memory {
                state: VehicleState::Disconnected,
                target: None,
                shaper: None,
                slot: None,
                yaw_rad: 0.0,
                procedure: 0,
                offboard_engaged: false,
                takeoff_altitude_m: 0.0,
                goto_target: None,
                last_fence: None,
            }),
            snapshot: watch::channel(snapshot).0,
        })
    }

    /// The FSM memory, recovered if a panic poisoned its lock (the state it guards is
    /// what a restarted actor must resume from).
    fn memory(&self) -> MutexGuard<'_, Memory> {
        self.memory.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The latest published snapshot.
    pub fn snapshot(&self) -> VehicleSnapshot {
        self.snapshot.borrow().clone()
    }

    /// The FSM state.
    pub fn state(&self) -> VehicleState {
        self.memory().state
    }

    /// Current swarm-frame position (from the vehicle's local position through its origin
    /// and the swarm frame), if known, moved on by its velocity for the age of the sample
    /// (at most 200 ms: PX4 streams it at 10–30 Hz, and a vehicle at 5 m/s covers 17 cm
    /// between two samples).
    pub fn position(&self, swarm: &NedFrame) -> Option<Ned> {
        self.link
            .with_telemetry(|t| match (t.local, t.local_frame()) {
                (Some(l), Some(local)) => {
                    let age = t
                        .local_received
                        .map_or(0.0, |at| at.elapsed().as_secs_f64().min(0.2));
                    Some(local.convert_to(swarm, l.position + l.velocity_m_s * age))
                }
                _ => t.global.map(|g| swarm.to_ned(&g.geo)),
            })
    }

    /// Heading, radians clockwise from north (`ATTITUDE.yaw`).
    pub fn heading_rad(&self) -> f64 {
        self.link
            .with_telemetry(|t| t.attitude.map(|a| a.yaw_rad))
            .unwrap_or(0.0)
    }

    /// Publishes a fresh snapshot from the telemetry, the FSM state, the formation slot
    /// and the payloads' supervision status and state.
    pub fn publish(
        &self,
        frame: Option<NedFrame>,
        slot: Option<SlotTarget>,
        supervision: &Supervision,
    ) {
        let state = self.state();
        let current = frame.and_then(|f| self.position(&f));
        let link = &self.link;
        let silence = link.silence();
        let vehicle_path = format!("{}/{}", supervision::ROOT, self.id);
        let payloads = self
            .payloads
            .iter()
            .map(|(slot, p)| {
                let path = Child::Payload(slot.clone()).path(&vehicle_path);
                let status = supervision.record(&path).map(|r| r.status);
                serde_json::json!({
                    "slot": slot,
                    "kind": p.spec.kind,
                    "plugin": p.spec.plugin,
                    "status": status,
                    "state": p.state(),
                    "frames": p.frames_published(),
                })
            })
            .collect();
        let snap = link.with_telemetry(|t| {
            let position = frame.and_then(|frame| {
                t.global.map(|g| {
                    let mut p = Position::from_geo(g.geo, g.relative_alt_m, &frame);
                    if let Some(c) = current {
                        p.north_m = c.north_m;
                        p.east_m = c.east_m;
                        p.down_m = c.down_m;
                    }
                    p
                })
            });
            let slot = slot.map(|s| FormationSlot {
                slot: s.slot,
                leader: s.leader,
                target: s.goal,
                error_m: current.map_or(f64::NAN, |c| (c - s.goal).norm()),
            });
            let vel = t
                .local
                .map(|l| l.velocity_m_s)
                .or(t.global.map(|g| g.velocity_m_s))
                .unwrap_or(Ned::ZERO);
            VehicleSnapshot {
                id: self.id.clone(),
                sysid: link.sysid,
                model: self.model.name.clone(),
                state,
                armed: t.heartbeat.is_some_and(|h| h.armed),
                px4_mode: t.heartbeat.map_or("UNKNOWN", |h| h.mode.name()).to_string(),
                landed_state: t.landed_state,
                position,
                velocity: Velocity {
                    north_m_s: vel.north_m,
                    east_m_s: vel.east_m,
                    down_m_s: vel.down_m,
                },
                heading_deg: t.heading_deg().map_or(0.0, wrap_deg_360),
                battery: t.battery.map(|b| Battery {
                    percent: b.percent.unwrap_or(f64::NAN),
                    voltage_v: b.voltage_v.unwrap_or(f64::NAN),
                }),
                link: LinkStatus {
                    connected: t.heartbeat.is_some() && !link.is_lost(),
                    last_seen_ms: silence.map_or(0, |s| s.as_millis() as u64),
                },
                formation: slot,
                payloads,
            }
        });
        self.snapshot.send_replace(snap);
    }

    /// With no Vehicle actor (escalated), the FSM state follows telemetry alone.
    pub fn settle_from_telemetry(&self) {
        if let Some(o) = self.link.with_telemetry(|t| t.observed()) {
            self.memory().state = fsm::settle(o);
        }
    }

    /// Where the vehicle is being held or sent (swarm frame), if skein is steering it.
    pub fn target_position(&self) -> Option<Ned> {
        self.memory
            .lock()
            .expect("memory lock")
            .target
            .map(|t| t.position())
    }

    /// Current velocity, NED m/s.
    pub fn velocity(&self) -> Option<Ned> {
        self.link.with_telemetry(|t| {
            t.local
                .map(|l| l.velocity_m_s)
                .or(t.global.map(|g| g.velocity_m_s))
        })
    }
}

/// Arguments of [`Vehicle`].
pub struct VehicleArgs {
    /// The vehicle's persistent part.
    pub shared: Arc<VehicleShared>,
    /// The shared swarm view.
    pub view: Arc<SwarmView>,
    /// Event bus.
    pub events: broadcast::Sender<SwarmEvent>,
    /// The coordinator (told about state changes).
    pub coordinator: ActorRef<CoordinatorMsg>,
    /// The supervision registry (this actor supervises its link and payloads).
    pub supervision: Arc<Supervision>,
}

/// A child of a Vehicle actor.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum Child {
    /// The `Px4Link`.
    Link,
    /// The payload in this slot.
    Payload(String),
}

impl Child {
    fn kind(&self) -> ChildKind {
        match self {
            Child::Link => ChildKind::Px4Link,
            Child::Payload(_) => ChildKind::Payload,
        }
    }

    /// The child's path under `vehicle_path` (`coordinator/uav-1`).
    pub fn path(&self, vehicle_path: &str) -> String {
        match self {
            Child::Link => format!("{vehicle_path}/px4link"),
            Child::Payload(slot) => format!("{vehicle_path}/payload/{slot}"),
        }
    }
}

/// Messages of [`Vehicle`].
pub enum VehicleMsg {
    /// An event from the `Px4Link` child.
    Link(LinkEvent),
    /// An operator command with its command id; the reply says whether the FSM accepted
    /// it (the outcome follows as a [`SwarmEvent::CommandResult`]).
    Command(VehicleCommand, u64, RpcReplyPort<Result<(), String>>),
    /// A new formation slot target (or `None` to drop the slot).
    Slot(Option<SlotTarget>),
    /// Control loop tick.
    Tick,
    /// A procedure task finished.
    ProcedureDone {
        /// Generation of the procedure.
        generation: u64,
        /// Command id it carries out.
        command_id: u64,
        /// Command name.
        command: &'static str,
        /// What it reached, or why it failed.
        result: Result<ProcedureStep, String>,
    },
    /// The current `Px4Link` child (for supervision tooling and tests).
    GetLink(RpcReplyPort<Option<ActorRef<Px4LinkMsg>>>),
    /// A MAVLink frame from one of the vehicle's other components (or a gimbal/camera
    /// message from the autopilot), for the payloads.
    Component(Box<skein_mavlink::Frame>),
    /// An operator command for the payload in a slot; the payload's answer goes back.
    PayloadCommand(
        String,
        serde_json::Value,
        RpcReplyPort<Result<serde_json::Value, crate::payload::PayloadCommandError>>,
    ),
    /// The plugin of the payload in this slot was reloaded at this instant: re-create the
    /// payload's driver on the new build (see [`PayloadMsg::Refresh`]).
    RefreshPayload(String, Instant),
    /// Watchdog probe.
    Ping(RpcReplyPort<()>),
    /// Time to ping the children.
    WatchTick,
    /// A child did not answer the watchdog in time.
    ChildHung(Child, ActorId),
    /// A child's backoff has passed: start it again.
    RestartChild(Child, Instant, String),
    /// Fault injection into this actor (`""`) or a child (`"px4link"`, `"payload/<slot>"`).
    InjectFault(String, FaultKind, RpcReplyPort<Result<(), String>>),
    /// Fault injection into this actor itself.
    Fault(FaultKind),
}

/// What a procedure task reached.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ProcedureStep {
    /// PX4 acknowledged the command (arm, disarm, land, RTL).
    Acknowledged,
    /// PX4 is in OFFBOARD following the stream.
    OffboardEngaged,
}

/// The `Vehicle` actor (see module docs).
pub struct Vehicle;

/// State of [`Vehicle`].
pub struct VehicleActorState {
    shared: Arc<VehicleShared>,
    view: Arc<SwarmView>,
    events: broadcast::Sender<SwarmEvent>,
    coordinator: ActorRef<CoordinatorMsg>,
    supervision: Arc<Supervision>,
    link_actor: Option<ActorRef<Px4LinkMsg>>,
    payload_actors: BTreeMap<String, ActorRef<PayloadMsg>>,
    /// Children the watchdog found hung and that are being killed.
    hung: HashSet<ActorId>,
    others: Vec<skein_model::safety::Obstacle>,
    last_tick: Instant,
    ticks: u64,
}

impl VehicleActorState {
    fn config(&self) -> &SwarmConfig {
        &self.view.config
    }

    fn emit(&self, ev: SwarmEvent) {
        let _ = self.events.send(ev);
    }

    /// Applies an FSM event; emits and reports a state change.
    fn apply(&self, mem: &mut Memory, event: Event) -> Result<VehicleState, fsm::Refusal> {
        let before = mem.state;
        let after = fsm::transition(before, event)?;
        if after != before {
            mem.state = after;
            self.on_state_change(mem, before, after);
        }
        Ok(after)
    }

    fn on_state_change(&self, mem: &mut Memory, from: VehicleState, to: VehicleState) {
        tracing::info!(id = %self.shared.id, "{from} -> {to}");
        if to != VehicleState::InFormation {
            mem.slot = None;
        }
        if to != VehicleState::TakingOff {
            mem.offboard_engaged = false;
        }
        if to != VehicleState::GoTo {
            mem.goto_target = None;
        }
        self.emit(SwarmEvent::StateChanged {
            id: self.shared.id.clone(),
            from,
            to,
        });
        let _ = self.coordinator.cast(CoordinatorMsg::VehicleState {
            id: self.shared.id.clone(),
            state: to,
        });
    }

    fn observed(&self) -> Option<Observed> {
        self.shared.link.with_telemetry(|t| t.observed())
    }

    fn swarm_frame(&self) -> Option<NedFrame> {
        self.view.frame().or_else(|| {
            let home = self.shared.link.with_telemetry(|t| t.home)?;
            Some(self.view.anchor(home.geo))
        })
    }

    fn start_procedure(
        &self,
        myself: &ActorRef<VehicleMsg>,
        mem: &mut Memory,
        command_id: u64,
        command: &'static str,
        work: Procedure,
    ) {
        mem.procedure += 1;
        let generation = mem.procedure;
        let link = self.shared.link.clone();
        let Some(actor) = self.link_actor.clone() else {
            let _ = myself.cast(VehicleMsg::ProcedureDone {
                generation,
                command_id,
                command,
                result: Err("link actor not running".into()),
            });
            return;
        };
        let me = myself.clone();
        tokio::spawn(async move {
            let result = work.run(&link, &actor).await;
            let _ = me.cast(VehicleMsg::ProcedureDone {
                generation,
                command_id,
                command,
                result,
            });
        });
    }

    /// Points the stream at `target`, re-anchoring the shaper at the current position when
    /// the vehicle was not being shaped.
    fn set_target(&self, mem: &mut Memory, target: Target, current: Ned) {
        if mem.shaper.is_none() {
            mem.shaper = Some(SetpointShaper::new(
                current,
                self.shared.model.limits,
                self.config().geofence.clone(),
                self.config().setpoint_separation_m(),
            ));
        }
        mem.target = Some(target);
    }

    fn command(
        &self,
        myself: &ActorRef<VehicleMsg>,
        cmd: VehicleCommand,
        command_id: u64,
    ) -> Result<(), String> {
        let mut mem = self.shared.memory();
        let name = cmd.name();
        // Checks that need telemetry, before the FSM: a clear reason, state unchanged.
        let needs_position = matches!(
            cmd,
            VehicleCommand::Takeoff { .. } | VehicleCommand::Hold | VehicleCommand::GoTo { .. }
        );
        let frame = self.swarm_frame();
        let current = frame.and_then(|f| self.shared.position(&f));
        let has_local_frame = self
            .shared
            .link
            .with_telemetry(|t| t.local_frame().is_some());
        if needs_position && (current.is_none() || !has_local_frame) {
            return Err(format!(
                "{name} refused: vehicle {} has no position and home yet (waiting for GLOBAL_POSITION_INT and HOME_POSITION)",
                self.shared.id
            ));
        }
        if let VehicleCommand::Takeoff {
            altitude_m: Some(a),
        } = cmd
            && !(a.is_finite() && a > 0.0 && a <= self.config().geofence.max_altitude_m)
        {
            return Err(format!(
                "takeoff refused: altitude_m {a} outside (0, {}] m",
                self.config().geofence.max_altitude_m
            ));
        }
        self.apply(&mut mem, Event::Command(cmd.fsm()))
            .map_err(|r| r.reason)?;
        let yaw = self
            .shared
            .link
            .with_telemetry(|t| t.attitude.map(|a| a.yaw_rad))
            .unwrap_or(0.0);
        match cmd {
            VehicleCommand::Arm => self.start_procedure(
                myself,
                &mut mem,
                command_id,
                name,
                Procedure::Link(LinkCommand::Arm),
            ),
            VehicleCommand::Disarm { force } => self.start_procedure(
                myself,
                &mut mem,
                command_id,
                name,
                Procedure::Link(LinkCommand::Disarm { force }),
            ),
            VehicleCommand::Land => self.start_procedure(
                myself,
                &mut mem,
                command_id,
                name,
                Procedure::Link(LinkCommand::Land),
            ),
            VehicleCommand::Rtl => self.start_procedure(
                myself,
                &mut mem,
                command_id,
                name,
                Procedure::Link(LinkCommand::SetMode(Px4Mode::Rtl)),
            ),
            VehicleCommand::Takeoff { altitude_m } => {
                let current = current.expect("checked above");
                mem.yaw_rad = yaw;
                mem.takeoff_altitude_m =
                    altitude_m.unwrap_or(self.config().default_takeoff_altitude_m);
                mem.shaper = None;
                self.set_target(&mut mem, Target::Hold(current), current);
                let armed = self.observed().is_some_and(|o| o.armed);
                self.start_procedure(
                    myself,
                    &mut mem,
                    command_id,
                    name,
                    Procedure::EnterOffboard { arm: !armed },
                );
            }
            VehicleCommand::Hold | VehicleCommand::GoTo { .. } => {
                let current = current.expect("checked above");
                let offboard = self.observed().is_some_and(|o| o.mode == Px4Mode::Offboard);
                if !offboard {
                    mem.shaper = None;
                    mem.yaw_rad = yaw;
                }
                let target = match cmd {
                    VehicleCommand::GoTo { target } => {
                        mem.goto_target = Some(target);
                        Target::Hold(target)
                    }
                    _ => {
                        // Hold where the setpoint is now (no jump back), or here.
                        let here = mem.shaper.as_ref().map_or(current, |s| s.carrot());
                        Target::Hold(here)
                    }
                };
                self.set_target(&mut mem, target, current);
                if offboard {
                    self.emit_result(command_id, name, Ok(()));
                } else {
                    self.start_procedure(
                        myself,
                        &mut mem,
                        command_id,
                        name,
                        Procedure::EnterOffboard { arm: false },
                    );
                }
            }
            VehicleCommand::JoinFormation => {
                // The slot arrives with the next formation tick; hold until then.
                self.emit_result(command_id, name, Ok(()));
            }
            VehicleCommand::LeaveFormation => {
                let here = mem.shaper.as_ref().map(|s| s.carrot());
                if let (Some(here), Some(cur)) = (here, current) {
                    self.set_target(&mut mem, Target::Hold(here), cur);
                }
                self.emit_result(command_id, name, Ok(()));
            }
        }
        Ok(())
    }

    fn emit_result(&self, command_id: u64, command: &str, result: Result<(), String>) {
        if command_id == 0 {
            return; // internal command (the coordinator's formation joins)
        }
        self.emit(SwarmEvent::CommandResult {
            command_id,
            id: self.shared.id.clone(),
            command: command.to_string(),
            ok: result.is_ok(),
            error: result.err(),
        });
    }

    fn procedure_done(
        &self,
        generation: u64,
        command_id: u64,
        command: &'static str,
        result: Result<ProcedureStep, String>,
    ) {
        let mut mem = self.shared.memory();
        if generation != mem.procedure {
            // A later command took over the vehicle: report what this one achieved, but
            // don't act on it (e.g. no climb from a takeoff that was cancelled).
            drop(mem);
            self.emit_result(command_id, command, result.map(|_| ()));
            return;
        }
        match &result {
            Ok(ProcedureStep::OffboardEngaged) if mem.state == VehicleState::TakingOff => {
                // Climb from where the vehicle is to the takeoff altitude above home.
                let frame = self.swarm_frame();
                let home_down = self.shared.link.with_telemetry(|t| {
                    let home = t.home?;
                    Some(frame?.to_ned(&home.geo).down_m)
                });
                if let (Some(home_down), Some(target)) = (home_down, mem.target) {
                    let mut p = target.position();
                    p.down_m = home_down - mem.takeoff_altitude_m;
                    mem.target = Some(Target::Hold(p));
                    mem.offboard_engaged = true;
                } else {
                    drop(mem);
                    self.fail_procedure(command_id, command, "home position lost".into());
                    return;
                }
            }
            Ok(_) => {}
            Err(e) => {
                let e = e.clone();
                drop(mem);
                self.fail_procedure(command_id, command, e);
                return;
            }
        }
        drop(mem);
        self.emit_result(command_id, command, result.map(|_| ()));
    }

    fn fail_procedure(&self, command_id: u64, command: &'static str, error: String) {
        let mut mem = self.shared.memory();
        if let Some(o) = self.observed() {
            let _ = self.apply(&mut mem, Event::ProcedureFailed(o));
        }
        drop(mem);
        tracing::warn!(id = %self.shared.id, "{command} failed: {error}");
        self.emit_result(command_id, command, Err(error));
    }

    fn on_link_event(&self, ev: LinkEvent) {
        let mut mem = self.shared.memory();
        let id = self.shared.id.clone();
        match ev {
            LinkEvent::Observed(o) => {
                let event = if mem.state == VehicleState::Disconnected {
                    Event::Connected(o)
                } else {
                    Event::Observed(o)
                };
                let _ = self.apply(&mut mem, event);
            }
            LinkEvent::Lost => {
                let _ = self.apply(&mut mem, Event::LinkLost);
                self.emit(SwarmEvent::LinkLost { id });
            }
            LinkEvent::Restored(o) => {
                let _ = self.apply(&mut mem, Event::LinkRestored(o));
                self.emit(SwarmEvent::LinkRestored { id });
            }
            LinkEvent::Rebooted => {
                if let Some(o) = self.observed() {
                    let _ = self.apply(&mut mem, Event::ProcedureFailed(o));
                }
                self.emit(SwarmEvent::Rebooted { id });
            }
            LinkEvent::StatusText { severity, text } => {
                self.emit(SwarmEvent::StatusText { id, severity, text });
            }
        }
    }

    fn on_slot(&self, slot: Option<SlotTarget>) {
        let mut mem = self.shared.memory();
        if mem.state != VehicleState::InFormation {
            return;
        }
        mem.slot = slot;
        if let Some(s) = slot {
            let current = self
                .swarm_frame()
                .and_then(|f| self.shared.position(&f))
                .unwrap_or(s.position);
            mem.yaw_rad = s.yaw_rad;
            self.set_target(
                &mut mem,
                Target::Track {
                    position: s.position,
                    velocity: s.velocity,
                    at: Instant::now(),
                },
                current,
            );
        }
    }

    /// The control loop.
    fn tick(&mut self) {
        let now = Instant::now();
        let dt = now
            .duration_since(self.last_tick)
            .as_secs_f64()
            .clamp(0.0, 0.2);
        self.last_tick = now;
        self.ticks += 1;
        let Some(frame) = self.swarm_frame() else {
            self.shared.publish(None, None, &self.supervision);
            return;
        };
        let current = self.shared.position(&frame);
        let local_frame = self.shared.link.with_telemetry(|t| t.local_frame());
        let stream = self.shared.link.stream();
        let mut mem = self.shared.memory();
        let state = mem.state;
        // Where this vehicle is, for the others' separation (the setpoint is added below
        // when skein steers it; a Lost vehicle stays where it was last seen).
        let measured = current.map(|p| (p, self.shared.velocity().unwrap_or(Ned::ZERO)));
        // A member flying its slot (the leader vehicle included) is on the formation's
        // transition plan.
        let planned = state == VehicleState::InFormation && mem.slot.is_some();
        self.view
            .set_position(&self.shared.id, measured, None, planned);
        match state {
            VehicleState::TakingOff
            | VehicleState::Hovering
            | VehicleState::InFormation
            | VehicleState::GoTo => {
                if let (Some(target), Some(local), Some(cur)) = (mem.target, local_frame, current) {
                    let (tp, tv) = target.now(now);
                    self.view.others(&self.shared.id, planned, &mut self.others);
                    let yaw = mem.yaw_rad;
                    let limits = self.shared.model.limits;
                    let config = &self.view.config;
                    let shaper = mem.shaper.get_or_insert_with(|| {
                        SetpointShaper::new(
                            cur,
                            limits,
                            config.geofence.clone(),
                            config.setpoint_separation_m(),
                        )
                        .with_planned_separation(config.planned_separation_m())
                    });
                    // The floor binds where the vehicle is meant to fly, not on the way up.
                    shaper.enforce_floor(state != VehicleState::TakingOff);
                    let sp = shaper.step(tp, tv, yaw, dt, &self.others);
                    self.view.set_position(
                        &self.shared.id,
                        measured,
                        Some((sp.position, sp.velocity)),
                        planned,
                    );
                    if let Some(v) = sp.fence
                        && mem.last_fence != sp.fence
                    {
                        self.emit(SwarmEvent::GeofenceClamp {
                            id: self.shared.id.clone(),
                            violation: v.name().into(),
                        });
                    }
                    mem.last_fence = sp.fence;
                    let local_pos = frame.convert_to(&local, sp.position);
                    stream.set(Some(LocalSetpoint::position_velocity(
                        local_pos,
                        sp.velocity,
                        sp.yaw_rad,
                    )));
                    // Progress of the running procedure.
                    let mode = self.observed().map(|o| o.mode);
                    if state == VehicleState::TakingOff && mem.offboard_engaged {
                        if mode.is_some_and(|m| m != Px4Mode::Offboard) {
                            if let Some(o) = self.observed() {
                                let _ = self.apply(&mut mem, Event::ProcedureFailed(o));
                            }
                        } else if (cur.down_m - tp.down_m).abs() < ARRIVAL_TOLERANCE_M {
                            let _ = self.apply(&mut mem, Event::TakeoffComplete);
                        }
                    }
                    if state == VehicleState::GoTo
                        && mem
                            .goto_target
                            .is_some_and(|g| (cur - g).norm() < ARRIVAL_TOLERANCE_M)
                    {
                        let _ = self.apply(&mut mem, Event::GoToReached);
                    }
                }
            }
            VehicleState::Landing | VehicleState::ReturnToLaunch | VehicleState::Failsafe => {
                // PX4 flies; keep a hold at the current position in the stream so that
                // a switch back to OFFBOARD holds where the vehicle is.
                if let (Some(local), Some(cur)) = (local_frame, current) {
                    if let Some(s) = mem.shaper.as_mut() {
                        s.reset(cur);
                    }
                    if stream.current().is_some() {
                        stream.set(Some(LocalSetpoint::position(
                            frame.convert_to(&local, cur),
                            mem.yaw_rad,
                        )));
                    }
                }
            }
            VehicleState::Lost => {} // keep streaming the last setpoint
            VehicleState::Landed | VehicleState::Armed | VehicleState::Disconnected => {
                if stream.current().is_some() {
                    stream.set(None);
                }
                mem.shaper = None;
                mem.target = None;
            }
        }
        let slot = mem.slot;
        drop(mem);
        let publish_every = (self.config().control_rate_hz / 10.0).round().max(1.0) as u64;
        if self.ticks.is_multiple_of(publish_every) {
            self.shared.publish(Some(frame), slot, &self.supervision);
        }
    }
}

/// A multi-step operation run as a task against the link actor.
enum Procedure {
    /// One command, acknowledged.
    Link(LinkCommand),
    /// Wait until the stream has run long enough, arm if asked, switch to OFFBOARD and
    /// see it confirmed.
    EnterOffboard { arm: bool },
}

/// Longest wait for one link command (ACK retries plus mode confirmation).
const LINK_CALL_TIMEOUT: Duration = Duration::from_secs(10);

async fn link_call(actor: &ActorRef<Px4LinkMsg>, cmd: LinkCommand) -> Result<(), String> {
    match ractor::call_t!(
        actor,
        Px4LinkMsg::Command,
        LINK_CALL_TIMEOUT.as_millis() as u64,
        cmd
    ) {
        Ok(Ok(())) => Ok(()),
        Ok(Err(e)) => Err(e.to_string()),
        Err(e) => Err(format!("link actor unavailable: {e}")),
    }
}

/// PX4 stays in LAND (or RTL) after touching down and refuses to arm there: on the
/// ground, switch to HOLD first.
async fn leave_landing_modes(
    link: &VehicleLink,
    actor: &ActorRef<Px4LinkMsg>,
) -> Result<(), String> {
    let on_ground_in_landing_mode = link.with_telemetry(|t| {
        t.observed().is_some_and(|o| {
            !o.airborne() && matches!(o.mode, Px4Mode::Land | Px4Mode::Rtl | Px4Mode::Precland)
        })
    });
    if on_ground_in_landing_mode {
        link_call(actor, LinkCommand::SetMode(Px4Mode::Hold)).await?;
    }
    Ok(())
}

impl Procedure {
    async fn run(
        self,
        link: &VehicleLink,
        actor: &ActorRef<Px4LinkMsg>,
    ) -> Result<ProcedureStep, String> {
        match self {
            Procedure::Link(cmd) => {
                if cmd == LinkCommand::Arm {
                    leave_landing_modes(link, actor).await?;
                }
                link_call(actor, cmd).await?;
                Ok(ProcedureStep::Acknowledged)
            }
            Procedure::EnterOffboard { arm } => {
                let deadline = Instant::now() + Duration::from_secs(5);
                loop {
                    let since = link.stream().streaming_since();
                    if since.is_some_and(|s| s.elapsed() >= OFFBOARD_PRESTREAM) {
                        break;
                    }
                    if Instant::now() > deadline {
                        return Err("setpoint stream did not start".into());
                    }
                    tokio::time::sleep(Duration::from_millis(20)).await;
                }
                if arm {
                    leave_landing_modes(link, actor).await?;
                    link_call(actor, LinkCommand::Arm).await?;
                }
                link_call(actor, LinkCommand::SetMode(Px4Mode::Offboard)).await?;
                Ok(ProcedureStep::OffboardEngaged)
            }
        }
    }
}

impl VehicleActorState {
    /// `coordinator/<id>`.
    fn path(&self) -> String {
        format!("{}/{}", supervision::ROOT, self.shared.id)
    }

    /// Which child an actor is.
    fn child_of(&self, id: ActorId) -> Option<Child> {
        if self.link_actor.as_ref().is_some_and(|l| l.get_id() == id) {
            return Some(Child::Link);
        }
        self.payload_actors
            .iter()
            .find(|(_, a)| a.get_id() == id)
            .map(|(slot, _)| Child::Payload(slot.clone()))
    }

    fn child_cell(&self, child: &Child) -> Option<ActorCell> {
        match child {
            Child::Link => self.link_actor.as_ref().map(|a| a.get_cell()),
            Child::Payload(slot) => self.payload_actors.get(slot).map(|a| a.get_cell()),
        }
    }

    async fn spawn_child(
        &mut self,
        myself: &ActorRef<VehicleMsg>,
        child: &Child,
    ) -> Result<(), ActorProcessingErr> {
        match child {
            Child::Link => {
                self.link_actor = Some(spawn_link(myself, &self.shared).await?);
            }
            Child::Payload(slot) => {
                let spec = self.shared.payloads[slot].spec.clone();
                let host = VehiclePayloadHost::new(
                    self.shared.clone(),
                    self.view.clone(),
                    self.events.clone(),
                    self.shared.payloads.clone(),
                    slot,
                );
                let (actor, _) = Actor::spawn_linked(
                    None,
                    PayloadActor,
                    PayloadArgs {
                        spec,
                        factory: self.view.services.payloads.clone(),
                        host,
                        // Half the watchdog's deadline: a stuck driver call fails the
                        // payload naming the call before the watchdog calls it hung.
                        call_deadline: self.supervision.config.watchdog_deadline() / 2,
                    },
                    myself.get_cell(),
                )
                .await?;
                self.payload_actors.insert(slot.clone(), actor);
            }
        }
        self.supervision
            .started(&child.path(&self.path()), child.kind());
        Ok(())
    }

    /// Starts `child` again after a failure noticed at `noticed`; records the restart
    /// once the replacement answers its first message.
    async fn restart_child(
        &mut self,
        myself: &ActorRef<VehicleMsg>,
        child: Child,
        noticed: Instant,
        reason: String,
    ) -> Result<(), ActorProcessingErr> {
        let path = child.path(&self.path());
        match self.spawn_child(myself, &child).await {
            Ok(()) => {
                let sup = self.supervision.clone();
                let kind = child.kind();
                let probe = move |sup: Arc<Supervision>, r: Result<(), ()>| {
                    if r.is_ok() {
                        sup.restarted(&path, kind, &reason, noticed.elapsed());
                    }
                };
                let deadline = Some(self.supervision.config.watchdog_deadline());
                match &child {
                    Child::Link => {
                        let a = self.link_actor.clone().expect("just spawned");
                        tokio::spawn(async move {
                            let r = a.call(Px4LinkMsg::Ping, deadline).await;
                            probe(sup, ok(r));
                        });
                    }
                    Child::Payload(slot) => {
                        let a = self.payload_actors[slot].clone();
                        tokio::spawn(async move {
                            let r = a.call(PayloadMsg::Ping, deadline).await;
                            probe(sup, ok(r));
                        });
                    }
                }
                Ok(())
            }
            Err(e) => {
                // The replacement did not even start: that is another failure.
                self.child_ended(myself, child, Exit::Failed(format!("restart failed: {e}")))
                    .await
            }
        }
    }

    /// Applies the policy to an ended child.
    async fn child_ended(
        &mut self,
        myself: &ActorRef<VehicleMsg>,
        child: Child,
        exit: Exit,
    ) -> Result<(), ActorProcessingErr> {
        let noticed = Instant::now();
        match &child {
            Child::Link => self.link_actor = None,
            Child::Payload(slot) => {
                self.payload_actors.remove(slot);
            }
        }
        let path = child.path(&self.path());
        let reason = exit.reason();
        match self.supervision.exit(&path, child.kind(), exit) {
            Decision::Restart(d) if d.is_zero() => {
                Box::pin(self.restart_child(myself, child, noticed, reason)).await?
            }
            Decision::Restart(d) => {
                myself.send_after(d, move || VehicleMsg::RestartChild(child, noticed, reason));
            }
            Decision::Escalate => match child {
                // Without its link the vehicle cannot work: fail, and let the coordinator
                // apply the vehicle's own policy (a new Vehicle starts a fresh link).
                Child::Link => {
                    return Err(format!("{path} keeps failing ({reason}): escalating").into());
                }
                Child::Payload(_) => self
                    .supervision
                    .escalated(&path, "payload disabled; the vehicle flies on"),
            },
            Decision::Leave => {}
        }
        Ok(())
    }

    fn watch_children(&self, myself: &ActorRef<VehicleMsg>) {
        let deadline = self.supervision.config.watchdog_deadline();
        if let Some(link) = &self.link_actor {
            let me = myself.clone();
            let id = link.get_id();
            supervision::watch(link.clone(), Px4LinkMsg::Ping, deadline, move || {
                let _ = me.cast(VehicleMsg::ChildHung(Child::Link, id));
            });
        }
        for (slot, actor) in &self.payload_actors {
            let me = myself.clone();
            let id = actor.get_id();
            let child = Child::Payload(slot.clone());
            supervision::watch(actor.clone(), PayloadMsg::Ping, deadline, move || {
                let _ = me.cast(VehicleMsg::ChildHung(child, id));
            });
        }
    }

    fn inject(&self, sub: &str, kind: FaultKind) -> Result<(), String> {
        let unknown = || {
            let mut known = vec![format!("{}/px4link", self.path())];
            known.extend(
                self.payload_actors
                    .keys()
                    .map(|s| format!("{}/payload/{s}", self.path())),
            );
            format!(
                "no actor `{}/{sub}` (known under this vehicle: {})",
                self.path(),
                known.join(", ")
            )
        };
        match sub {
            "px4link" => self
                .link_actor
                .as_ref()
                .ok_or_else(|| format!("{}/px4link is not running", self.path()))?
                .cast(Px4LinkMsg::Fault(kind))
                .map_err(|e| e.to_string()),
            other => match other.strip_prefix("payload/") {
                Some(slot) => self
                    .payload_actors
                    .get(slot)
                    .ok_or_else(unknown)?
                    .cast(PayloadMsg::Fault(kind))
                    .map_err(|e| e.to_string()),
                None => Err(unknown()),
            },
        }
    }
}

fn ok<T, E>(r: Result<ractor::rpc::CallResult<T>, E>) -> Result<(), ()> {
    match r {
        Ok(ractor::rpc::CallResult::Success(_)) => Ok(()),
        _ => Err(()),
    }
}

impl Actor for Vehicle {
    type Msg = VehicleMsg;
    type State = VehicleActorState;
    type Arguments = VehicleArgs;

    async fn pre_start(
        &self,
        myself: ActorRef<Self::Msg>,
        args: VehicleArgs,
    ) -> Result<Self::State, ActorProcessingErr> {
        let period = Duration::from_secs_f64(1.0 / args.view.config.control_rate_hz.max(1.0));
        myself.send_interval(period, || VehicleMsg::Tick);
        myself.send_interval(args.supervision.config.watchdog_period(), || {
            VehicleMsg::WatchTick
        });
        let mut state = VehicleActorState {
            shared: args.shared,
            view: args.view,
            events: args.events,
            coordinator: args.coordinator,
            supervision: args.supervision,
            link_actor: None,
            payload_actors: BTreeMap::new(),
            hung: HashSet::new(),
            others: Vec::new(),
            last_tick: Instant::now(),
            ticks: 0,
        };
        state.spawn_child(&myself, &Child::Link).await?;
        let slots: Vec<String> = state.shared.payloads.keys().cloned().collect();
        for slot in slots {
            let child = Child::Payload(slot);
            // A payload disabled by an escalation stays disabled across vehicle restarts.
            let failed = state
                .supervision
                .record(&child.path(&state.path()))
                .is_some_and(|r| r.status == ChildStatus::Failed);
            if !failed && let Err(e) = state.spawn_child(&myself, &child).await {
                state
                    .child_ended(&myself, child, Exit::Failed(format!("start failed: {e}")))
                    .await?;
            }
        }
        Ok(state)
    }

    async fn handle(
        &self,
        myself: ActorRef<Self::Msg>,
        msg: Self::Msg,
        state: &mut Self::State,
    ) -> Result<(), ActorProcessingErr> {
        match msg {
            VehicleMsg::Link(ev) => state.on_link_event(ev),
            VehicleMsg::Command(cmd, command_id, reply) => {
                let r = state.command(&myself, cmd, command_id);
                let _ = reply.send(r);
            }
            VehicleMsg::Slot(slot) => state.on_slot(slot),
            VehicleMsg::Tick => state.tick(),
            VehicleMsg::ProcedureDone {
                generation,
                command_id,
                command,
                result,
            } => state.procedure_done(generation, command_id, command, result),
            VehicleMsg::GetLink(reply) => {
                let _ = reply.send(state.link_actor.clone());
            }
            VehicleMsg::Component(frame) => {
                for actor in state.payload_actors.values() {
                    let _ = actor.cast(PayloadMsg::Mavlink(
                        frame.compid,
                        Box::new(frame.msg.clone()),
                    ));
                }
            }
            VehicleMsg::PayloadCommand(slot, cmd, reply) => match state.payload_actors.get(&slot) {
                Some(actor) => {
                    let actor = actor.clone();
                    let deadline = Some(state.supervision.config.watchdog_deadline());
                    tokio::spawn(async move {
                        use crate::payload::PayloadCommandError as E;
                        let r = match actor.call(|r| PayloadMsg::Command(cmd, r), deadline).await {
                            Ok(ractor::rpc::CallResult::Success(r)) => r.map_err(E::Refused),
                            Ok(ractor::rpc::CallResult::Timeout) => Err(E::Unavailable(format!(
                                "payload `{slot}` did not answer in time"
                            ))),
                            _ => Err(E::Unavailable(format!(
                                "payload `{slot}` failed while handling the command"
                            ))),
                        };
                        let _ = reply.send(r);
                    });
                }
                None => {
                    use crate::payload::PayloadCommandError as E;
                    let why = if state.shared.payloads.contains_key(&slot) {
                        E::Unavailable(format!(
                            "payload `{slot}` is not running (failed, disabled or restarting)"
                        ))
                    } else {
                        E::NotFound(format!(
                            "vehicle {} has no payload slot `{slot}` (slots: {})",
                            state.shared.id,
                            state
                                .shared
                                .payloads
                                .keys()
                                .cloned()
                                .collect::<Vec<_>>()
                                .join(", ")
                        ))
                    };
                    let _ = reply.send(Err(why));
                }
            },
            VehicleMsg::RefreshPayload(slot, at) => {
                // A payload not running now is created from the new build when it starts.
                if let Some(actor) = state.payload_actors.get(&slot) {
                    let _ = actor.cast(PayloadMsg::Refresh(at));
                }
            }
            VehicleMsg::Ping(reply) => {
                let _ = reply.send(());
            }
            VehicleMsg::WatchTick => state.watch_children(&myself),
            VehicleMsg::ChildHung(child, id) => {
                let current = state.child_cell(&child).filter(|c| c.get_id() == id);
                if let Some(cell) = current
                    && state.hung.insert(id)
                {
                    tracing::warn!("{} hung: killing it", child.path(&state.path()));
                    cell.kill();
                }
            }
            VehicleMsg::RestartChild(child, noticed, reason) => {
                if state.child_cell(&child).is_none() {
                    state.restart_child(&myself, child, noticed, reason).await?;
                }
            }
            VehicleMsg::InjectFault(sub, kind, reply) => {
                if sub.is_empty() {
                    let _ = reply.send(Ok(()));
                    let who = state.path();
                    skein_link::fault::inject(kind, &myself, &who).await?;
                } else {
                    let _ = reply.send(state.inject(&sub, kind));
                }
            }
            VehicleMsg::Fault(kind) => {
                let who = state.path();
                skein_link::fault::inject(kind, &myself, &who).await?;
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
        let (id, exit) = match evt {
            SupervisionEvent::ActorFailed(cell, reason) => {
                let id = cell.get_id();
                let exit = if state.hung.remove(&id) {
                    Exit::Hung(state.supervision.config.watchdog_deadline())
                } else {
                    Exit::Failed(reason.to_string())
                };
                (id, exit)
            }
            SupervisionEvent::ActorTerminated(cell, _, reason) => {
                let id = cell.get_id();
                let exit = if state.hung.remove(&id) {
                    Exit::Hung(state.supervision.config.watchdog_deadline())
                } else {
                    Exit::Stopped(reason)
                };
                (id, exit)
            }
            _ => return Ok(()),
        };
        // Ends of children already replaced (or never ours) are not news.
        if let Some(child) = state.child_of(id) {
            state.child_ended(&myself, child, exit).await?;
        }
        Ok(())
    }
}

/// Message ids of the gimbal and camera protocols (GIMBAL_MANAGER_* 280–288, CAMERA_*
/// 259–263 and 271–276) that payloads want even when the autopilot sends them.
fn for_payloads(msg: &skein_mavlink::MavMessage) -> bool {
    let id = skein_mavlink::message_id(msg);
    (280..=288).contains(&id) || (259..=263).contains(&id) || (271..=276).contains(&id)
}

async fn spawn_link(
    myself: &ActorRef<VehicleMsg>,
    shared: &Arc<VehicleShared>,
) -> Result<ActorRef<Px4LinkMsg>, ActorProcessingErr> {
    let me = myself.clone();
    let components: Option<skein_link::px4link::FrameSink> = if shared.payloads.is_empty() {
        None
    } else {
        let me = myself.clone();
        let autopilot = shared.link.compid;
        Some(Arc::new(move |f: &skein_mavlink::Frame| {
            if f.compid != autopilot || for_payloads(&f.msg) {
                let _ = me.cast(VehicleMsg::Component(Box::new(f.clone())));
            }
        }))
    };
    let (actor, _) = Actor::spawn_linked(
        None,
        Px4Link,
        Px4LinkArgs {
            link: shared.link.clone(),
            events: Arc::new(move |ev| {
                let _ = me.cast(VehicleMsg::Link(ev));
            }),
            components,
        },
        myself.get_cell(),
    )
    .await?;
    Ok(actor)
}
