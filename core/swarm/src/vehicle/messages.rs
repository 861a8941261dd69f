//! What a Vehicle actor is given and told: its arguments, its message enum, and its
//! children's names.

use super::fleet::Fleet;
use super::shared::VehicleShared;
use crate::context::SwarmContext;
use crate::events::SwarmEvent;
use crate::neighbours::{NeighbourSlot, Neighbours};
use crate::protocol::{ToVehicle, Uplink};
use crate::supervision::{ChildKey, Supervision};
use ractor::{ActorId, RpcReplyPort};
use skein_link::Px4LinkMsg;
use skein_link::px4link::LinkEvent;
use skein_model::supervision::{ChildKind, FaultKind};
use std::sync::Arc;
use std::time::Instant;
use tokio::sync::broadcast;

/// Arguments of [`super::Vehicle`].
pub struct VehicleArgs {
    /// The vehicle's persistent part.
    pub shared: Arc<VehicleShared>,
    /// Configuration, services, the swarm frame.
    pub context: Arc<SwarmContext>,
    /// The vehicles of this process (what its payloads' drivers see of the swarm).
    pub fleet: Fleet,
    /// The other vehicles' places, for the separation check.
    pub neighbours: Neighbours,
    /// Where this vehicle publishes its own place (the same slot across restarts).
    pub position: NeighbourSlot,
    /// Event bus.
    pub events: broadcast::Sender<SwarmEvent>,
    /// Where the vehicle's protocol messages ([`crate::protocol::FromVehicle`]) go.
    pub uplink: Uplink,
    /// The supervision registry (this actor supervises its link and payloads).
    pub supervision: Arc<Supervision>,
}

/// A child of a Vehicle actor.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Child {
    /// The `Px4Link`.
    Link,
    /// The payload in this slot.
    Payload(String),
}

impl ChildKey for Child {
    /// `<vehicle>/px4link` or `<vehicle>/payload/<slot>`.
    fn path(&self, vehicle_path: &str) -> String {
        match self {
            Child::Link => format!("{vehicle_path}/px4link"),
            Child::Payload(slot) => format!("{vehicle_path}/payload/{slot}"),
        }
    }

    fn kind(&self) -> ChildKind {
        match self {
            Child::Link => ChildKind::Px4Link,
            Child::Payload(_) => ChildKind::Payload,
        }
    }
}

/// Messages of [`super::Vehicle`].
pub enum VehicleMsg {
    /// A message of the swarm protocol from the coordinator.
    Protocol(ToVehicle),
    /// An event from the `Px4Link` child.
    Link(LinkEvent),
    /// The control step panicked (the message): the actor fails, and its supervisor
    /// restarts it.
    ControlFailed(String),
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
    /// The current `Px4Link` child (parameters, supervision tooling and tests).
    GetLink(RpcReplyPort<Option<ractor::ActorRef<Px4LinkMsg>>>),
    /// A MAVLink frame from one of the vehicle's other components (or a gimbal/camera
    /// message from the autopilot), for the payloads.
    Component(Box<skein_mavlink::Frame>),
    /// The plugin of the payload in this slot was reloaded at this instant: re-create the
    /// payload's driver on the new build (see [`crate::payload::PayloadMsg::Refresh`]).
    RefreshPayload(String, Instant),
    /// A payload plugin was loaded or unloaded in this process: start waiting slots a
    /// provider now offers, stop payloads whose library is gone (local to the vehicle's
    /// process, not part of the swarm protocol; see [`super::payloads`]).
    PluginsChanged,
    /// The driver of a slot being attached exists: answer the attach.
    PayloadReady(String),
    /// A payload stopped on purpose (unload, detach) is gone: what comes next.
    PayloadStopped(String, AfterStop),
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

/// Why a payload was stopped on purpose, i.e. what follows once it is gone.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AfterStop {
    /// Its library was unloaded: the slot waits again, or starts from another provider.
    Reevaluate,
    /// A detach (its request id): the slot is removed and the detach answered.
    Detach(u64),
}

/// What a procedure task reached.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ProcedureStep {
    /// PX4 acknowledged the command (arm, disarm, land, RTL).
    Acknowledged,
    /// PX4 is in OFFBOARD following the stream.
    OffboardEngaged,
}
