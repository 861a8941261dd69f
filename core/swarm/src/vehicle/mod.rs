//! The `Vehicle` actor: one per UAV, owner of its FSM and of what its setpoint stream
//! carries.
//!
//! It speaks the swarm protocol ([`crate::protocol`]): it obeys [`ToVehicle`] messages
//! and says what happened through its [`Uplink`](crate::protocol::Uplink) closure and its
//! published [`VehicleReport`](crate::protocol::VehicleReport); it holds no reference to
//! the coordinator, so the same actor runs under the single-process coordinator or under
//! an agent whose coordinator is across DDS.
//!
//! - [`messages`]: arguments, messages, children's names;
//! - [`shared`]: what outlives the actor ([`VehicleShared`]): FSM memory, snapshot,
//!   report;
//! - [`commands`]: operator commands and link events into the FSM;
//! - [`procedures`]: multi-step operations (arm, enter OFFBOARD, land) as tasks;
//! - [`control`]: the control loop feeding the setpoint stream: a direct call on the
//!   process's control clock ([`crate::ticker::Ticker::run_every`]) with the
//!   [`VehicleCore`], not a message to the actor, so it runs on time whatever the actor
//!   is busy with;
//! - [`fence`]: the geofence the setpoints are clamped into, skein's breach check;
//! - [`slot_correction`]: the outer loop that cancels PX4's lag behind a formation slot;
//! - [`fleet`]: the coordinator's registry of this process's vehicles, and its readers;
//! - [`payload_host`]: what a payload driver reaches of its vehicle and the swarm;
//! - [`children`]: supervision of its `Px4Link` and payloads;
//! - [`payloads`]: payload slots waiting for plugins, plugin loads and unloads, run-time
//!   attach and detach.

pub mod control;
pub mod fence;
pub mod fleet;
pub mod fsm_events;
pub mod messages;
pub mod payload_host;
mod payloads;
pub mod procedures;
pub mod shared;
pub mod slot_correction;
mod supervisor;

pub use control::ARRIVAL_TOLERANCE_M;
pub use messages::{AfterStop, Child, ProcedureStep, VehicleArgs, VehicleMsg};
pub use procedures::OFFBOARD_PRESTREAM;
pub use shared::{PayloadMap, VehicleShared, payload_json};

use crate::context::SwarmContext;
use crate::events::SwarmEvent;
use crate::neighbours::{NeighbourSlot, Neighbours};
use crate::payload::PayloadMsg;
use crate::protocol::{FromVehicle, PayloadCommandError, ToVehicle, Uplink};
use crate::supervision::{Children, Supervision};
use crate::ticker::TickGate;
use fleet::Fleet;
use ractor::{Actor, ActorProcessingErr, ActorRef, SupervisionEvent};
use skein_link::Px4LinkMsg;
use skein_model::supervision::{ChildStatus, FaultKind};
use std::collections::{BTreeMap, BTreeSet};
use std::panic::AssertUnwindSafe;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;
use tokio::sync::broadcast;

/// The `Vehicle` actor (see module docs).
pub struct Vehicle;

/// What a vehicle's control step and its actor share: the handles of the vehicle's
/// persistent part and of the swarm, no actor state. The control step runs on the
/// process's control clock while the actor handles its messages; both change the FSM
/// memory only under its lock ([`VehicleShared::memory`]).
pub struct VehicleCore {
    shared: Arc<VehicleShared>,
    context: Arc<SwarmContext>,
    neighbours: Neighbours,
    position: NeighbourSlot,
    events: broadcast::Sender<SwarmEvent>,
    uplink: Uplink,
    supervision: Arc<Supervision>,
    /// The test fault `panic` at `<vehicle>/control` ([`CONTROL_FAULT_TARGET`]): the next
    /// control step panics.
    control_fault: AtomicBool,
}

/// The fault-injection target of a vehicle's control step, under the vehicle's path
/// (`coordinator/uav-1/control`). Only `panic` is injected there: the step runs on the
/// process's control clock beside every other vehicle's, so a hang would hold up the
/// whole swarm's control.
pub const CONTROL_FAULT_TARGET: &str = "control";

impl VehicleCore {
    /// Fault injection into the control step (see [`CONTROL_FAULT_TARGET`]).
    fn inject_control(&self, kind: FaultKind) -> Result<(), String> {
        match kind {
            FaultKind::Panic => {
                tracing::warn!(id = %self.shared.id, "fault injected: the next control step panics");
                self.control_fault.store(true, Ordering::Release);
                Ok(())
            }
            other => Err(format!(
                "{}/{}/{CONTROL_FAULT_TARGET} takes only `panic`, not `{}`: the control step \
                 runs beside every other vehicle's, a {} there would hold up the swarm's control",
                crate::supervision::ROOT,
                self.shared.id,
                other.name(),
                other.name()
            )),
        }
    }
}

/// State of [`Vehicle`]. Reads through to its [`VehicleCore`].
pub struct VehicleActorState {
    core: Arc<VehicleCore>,
    fleet: Fleet,
    children: Children<Child>,
    /// The watchdog tick from the process's [`crate::ticker::Ticker`].
    watch_gate: TickGate,
    /// Slots being attached, with the request to answer once the driver exists.
    attaching: BTreeMap<String, u64>,
    /// Slots whose payload is being stopped on purpose (unload, detach).
    stopping: BTreeSet<String>,
}

impl std::ops::Deref for VehicleActorState {
    type Target = VehicleCore;

    fn deref(&self) -> &VehicleCore {
        &self.core
    }
}

/// Registers `core`'s control step on the process's control clock at the control rate:
/// it runs until the core is dropped (only the actor's state holds it: the step stops
/// with its actor, and a replacement brings its own). A panic in the step is the actor's
/// failure: `actor` is told ([`VehicleMsg::ControlFailed`]) and fails, and its
/// supervisor restarts it with a fresh step.
fn start_control(core: &Arc<VehicleCore>, actor: ActorRef<VehicleMsg>) {
    let period = Duration::from_secs_f64(1.0 / core.context.config.control_rate_hz.max(1.0));
    let weak = Arc::downgrade(core);
    let clock = Mutex::new(control::ControlClock::new());
    core.context.ticker.run_every(period, move || {
        let Some(core) = weak.upgrade() else {
            return false;
        };
        let mut clock = clock.lock().unwrap_or_else(PoisonError::into_inner);
        match std::panic::catch_unwind(AssertUnwindSafe(|| core.tick(&mut clock))) {
            Ok(()) => true,
            Err(panic) => {
                let why = crate::supervision::panic_text(panic.as_ref());
                let _ = actor.cast(VehicleMsg::ControlFailed(why));
                false
            }
        }
    });
}

impl VehicleActorState {
    /// Carries out a protocol message from the coordinator.
    async fn on_protocol(
        &mut self,
        myself: &ActorRef<VehicleMsg>,
        msg: ToVehicle,
    ) -> Result<(), ActorProcessingErr> {
        match msg {
            ToVehicle::Command {
                command_id,
                command,
            } => {
                let result = self.command(myself, command, command_id);
                (self.uplink)(FromVehicle::CommandAck {
                    id: self.shared.id.clone(),
                    command_id,
                    result,
                });
            }
            ToVehicle::Slot { target } => self.on_slot(target),
            ToVehicle::PayloadCommand {
                request_id,
                slot,
                command,
            } => self.payload_command(request_id, slot, command),
            ToVehicle::AttachPayload { request_id, spec } => {
                self.attach_payload(myself, request_id, spec).await?;
            }
            ToVehicle::DetachPayload { request_id, slot } => {
                self.detach_payload(myself, request_id, slot).await?;
            }
        }
        Ok(())
    }

    /// Hands a payload command to the payload's actor and answers through the uplink
    /// from a task (the payload may take its time).
    fn payload_command(&self, request_id: u64, slot: String, command: serde_json::Value) {
        let id = self.shared.id.clone();
        let uplink = self.uplink.clone();
        let actor = self
            .payload_actors()
            .find(|(s, _)| *s == slot)
            .map(|(_, a)| a);
        let Some(actor) = actor else {
            let why = if let Some(p) = self.shared.payload(&slot) {
                PayloadCommandError::Unavailable(match p.waiting() {
                    Some(why) => format!("payload `{slot}` is not running: {why}"),
                    None => {
                        format!("payload `{slot}` is not running (failed, disabled or restarting)")
                    }
                })
            } else {
                PayloadCommandError::NotFound(format!(
                    "vehicle {id} has no payload slot `{slot}` (slots: {})",
                    self.shared
                        .payloads()
                        .keys()
                        .cloned()
                        .collect::<Vec<_>>()
                        .join(", ")
                ))
            };
            uplink(FromVehicle::PayloadResult {
                id,
                request_id,
                result: Err(why),
            });
            return;
        };
        let deadline = Some(self.children.supervision().config.watchdog_deadline());
        tokio::spawn(async move {
            use PayloadCommandError as E;
            let result = match actor
                .call(|r| PayloadMsg::Command(command, r), deadline)
                .await
            {
                Ok(ractor::rpc::CallResult::Success(r)) => r.map_err(E::Refused),
                Ok(ractor::rpc::CallResult::Timeout) => Err(E::Unavailable(format!(
                    "payload `{slot}` did not answer in time"
                ))),
                _ => Err(E::Unavailable(format!(
                    "payload `{slot}` failed while handling the command"
                ))),
            };
            uplink(FromVehicle::PayloadResult {
                id,
                request_id,
                result,
            });
        });
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
        let me = myself.clone();
        let watch_gate = args
            .context
            .ticker
            .every(args.supervision.config.watchdog_period(), move || {
                me.cast(VehicleMsg::WatchTick).is_ok()
            });
        let path = format!("{}/{}", crate::supervision::ROOT, args.shared.id);
        let core = Arc::new(VehicleCore {
            shared: args.shared,
            context: args.context,
            neighbours: args.neighbours,
            position: args.position,
            events: args.events,
            uplink: args.uplink,
            supervision: args.supervision.clone(),
            control_fault: AtomicBool::new(false),
        });
        start_control(&core, myself.clone());
        let mut state = VehicleActorState {
            core,
            fleet: args.fleet,
            children: Children::new(path, args.supervision),
            watch_gate,
            attaching: BTreeMap::new(),
            stopping: BTreeSet::new(),
        };
        state.start_child(&myself, Child::Link).await?;
        let slots: Vec<String> = state.shared.payloads().keys().cloned().collect();
        for slot in slots {
            let child = Child::Payload(slot.clone());
            // A payload disabled by an escalation stays disabled across vehicle restarts.
            let failed = state
                .children
                .supervision()
                .record(&state.children.path(&child))
                .is_some_and(|r| r.status == ChildStatus::Failed);
            // A slot no loaded plugin provides waits for one.
            if !failed && let Err(e) = state.start_payload(&myself, &slot, None).await {
                let exit = crate::supervision::Exit::Failed(format!("start failed: {e}"));
                state.child_ended(&myself, child, exit).await?;
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
            VehicleMsg::Protocol(msg) => state.on_protocol(&myself, msg).await?,
            VehicleMsg::Link(ev) => state.on_link_event(ev),
            VehicleMsg::ControlFailed(why) => {
                return Err(format!("control step failed: {why}").into());
            }
            VehicleMsg::ProcedureDone {
                generation,
                command_id,
                command,
                result,
            } => state.procedure_done(generation, command_id, command, result),
            VehicleMsg::GetLink(reply) => {
                let _ = reply.send(state.children.actor::<Px4LinkMsg>(&Child::Link));
            }
            VehicleMsg::Component(frame) => {
                for (_, actor) in state.payload_actors() {
                    let _ = actor.cast(PayloadMsg::Mavlink(
                        frame.compid,
                        Box::new(frame.msg.clone()),
                    ));
                }
            }
            VehicleMsg::RefreshPayload(slot, at) => {
                // A payload not running now is created from the new build when it starts.
                if let Some(actor) = state.children.actor::<PayloadMsg>(&Child::Payload(slot)) {
                    let _ = actor.cast(PayloadMsg::Refresh(at));
                }
            }
            VehicleMsg::PluginsChanged => state.plugins_changed(&myself).await?,
            VehicleMsg::PayloadReady(slot) => state.payload_ready(&slot),
            VehicleMsg::PayloadStopped(slot, after) => {
                state.payload_stopped(&myself, slot, after).await?;
            }
            VehicleMsg::Ping(reply) => {
                let _ = reply.send(());
            }
            VehicleMsg::WatchTick => {
                state.watch_gate.done();
                let me = myself.clone();
                state.children.watch(move |child, id| {
                    let _ = me.cast(VehicleMsg::ChildHung(child, id));
                });
            }
            VehicleMsg::ChildHung(child, id) => state.children.kill_hung(&child, id),
            VehicleMsg::RestartChild(child, noticed, reason) => {
                // A payload detached (or being stopped) meanwhile is not restarted.
                let gone = match &child {
                    Child::Payload(slot) => {
                        state.shared.payload(slot).is_none() || state.stopping.contains(slot)
                    }
                    Child::Link => false,
                };
                if state.children.get(&child).is_none() && !gone {
                    state.restart_child(&myself, child, noticed, reason).await?;
                }
            }
            VehicleMsg::InjectFault(sub, kind, reply) if sub == CONTROL_FAULT_TARGET => {
                let _ = reply.send(state.inject_control(kind));
            }
            VehicleMsg::InjectFault(sub, FaultKind::BypassGeofence, reply) => {
                let r = if sub.is_empty() {
                    state.bypass_geofence();
                    Ok(())
                } else {
                    Err(format!(
                        "bypass_geofence is the vehicle's fault, not {sub}'s"
                    ))
                };
                let _ = reply.send(r);
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
        // Ends of children already replaced (or never ours) are not news.
        if let Some((child, exit)) = state.children.ended(&evt) {
            state.child_ended(&myself, child, exit).await?;
        }
        Ok(())
    }
}
