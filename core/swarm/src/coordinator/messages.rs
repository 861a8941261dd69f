//! What the coordinator is told: its message enum (the API reaches the swarm only
//! through it), routing to one message enum per concept (each defined next to its
//! handler), the service actors it supervises, and the shapes of its answers.

pub use super::admin::AdminMsg;
pub use super::counter_uas::TrackingMsg;
pub use super::distributed::DistributedMsg;
pub use super::fan_out::CommandMsg;
pub use super::fleet::FleetMsg;
pub use super::formation_control::FormationMsg;
pub use super::geofence::GeofenceMsg;
pub use super::missions::MissionMsg;
pub use super::payloads::PayloadMsg;
use ractor::{ActorCell, ActorProcessingErr, ActorRef, RpcReplyPort};
use serde::Serialize;
use skein_mavlink::DecodeCounts;
use skein_model::supervision::{ChildKind, FaultKind};
use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;

/// Per-endpoint link statistics.
#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
pub struct EndpointStats {
    /// Connection string.
    pub connection: String,
    /// Bound local address (UDP).
    pub local_addr: Option<String>,
    /// Decoder counters (malformed input), by name (`bad_crc`, `unknown_message` …).
    #[schema(value_type = std::collections::BTreeMap<String, u64>)]
    pub decode: DecodeCounts,
    /// Send counters, by name (`frames_sent`, `send_errors`, `no_route`).
    #[schema(value_type = std::collections::BTreeMap<String, u64>)]
    pub send: skein_link::endpoint::SendCounts,
    /// MAVLink 2 signing counters summed over the endpoint's signing vehicles (frames
    /// accepted signed, dropped unsigned / badly signed / replayed / too old, sent signed);
    /// absent when no vehicle there signs.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<std::collections::BTreeMap<String, u64>>)]
    pub signing: Option<skein_mavlink::signing::SigningCounts>,
    /// On the ground-station forwarder's entry (`[gcs] forward`): frames forwarded each
    /// way and dropped (setpoints, unknown target sysid).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<std::collections::BTreeMap<String, u64>>)]
    pub gcs_forward: Option<skein_link::gcs::ForwardCounts>,
}

/// Swarm health for `GET /api/v1/health`.
#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
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
    /// `active` or `standby` in a `skein coordinator` candidate (set by the API from the
    /// election, see `GET /api/v1/coordinator`); `null` in `skein up`, which has no
    /// election.
    pub coordinator_role: Option<crate::election::CoordinatorRole>,
    /// How late the process runs and what optional work it sheds ([`crate::load`]).
    pub load: crate::load::LoadStatus,
}

/// The tracks now, and which vehicle observes which track (vehicle id, track id).
pub type TracksAnswer = (Vec<crate::tracks::TrackView>, Vec<(String, String)>);

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

impl ServiceMsg {
    /// What every service does with its messages: answers the watchdog's `Ping`, and
    /// carries out an injected `Fault` as the actor at `path` (`"coordinator/api"`).
    ///
    /// # Errors
    /// The injected fault, when it is an error (a panic panics; a hang never returns).
    pub async fn serve(
        self,
        myself: &ActorRef<ServiceMsg>,
        path: &str,
    ) -> Result<(), ActorProcessingErr> {
        match self {
            ServiceMsg::Ping(reply) => {
                let _ = reply.send(());
                Ok(())
            }
            ServiceMsg::Fault(kind) => skein_link::fault::inject(kind, myself, path).await,
        }
    }
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

/// Messages of [`Coordinator`]: one variant per concept, each carrying that concept's
/// own message enum, handled in the concept's file (`Coordinator::handle` only routes).
/// Each concept enum converts `.into()` a `CoordinatorMsg`
/// (`FormationMsg::GetFormation(reply).into()`).
///
/// [`Coordinator`]: super::Coordinator
pub enum CoordinatorMsg {
    /// Vehicles and their links: discovery, the vehicles' protocol messages, listings,
    /// link counters, the ground-station forwarder ([`super::fleet`]).
    Fleet(FleetMsg),
    /// Commands fanned out to one vehicle or to all, and their timeouts
    /// ([`super::fan_out`]).
    Command(CommandMsg),
    /// The formation, its leader's motion, its hazards and its tick
    /// ([`super::formation_control`]).
    Formation(FormationMsg),
    /// The geofence in force and changes to it ([`super::geofence`]).
    Geofence(GeofenceMsg),
    /// Vehicles' payloads and the payload plugins ([`super::payloads`]).
    Payload(PayloadMsg),
    /// The counter-UAS air picture and the vehicles observing it ([`super::counter_uas`]).
    Tracking(TrackingMsg),
    /// Supervision, faults, health, metrics and load ([`super::admin`]).
    Admin(AdminMsg),
    /// What the DDS carrier of the distributed roles asks ([`super::distributed`]).
    Distributed(DistributedMsg),
    /// Missions: plans stored, started, flown, paused, aborted ([`super::missions`]).
    Mission(MissionMsg),
}

/// `From<concept enum> for CoordinatorMsg`, one per concept.
macro_rules! route {
    ($($concept:ident => $variant:ident),* $(,)?) => {
        $(
            impl From<$concept> for CoordinatorMsg {
                fn from(msg: $concept) -> Self {
                    CoordinatorMsg::$variant(msg)
                }
            }
        )*
    };
}

route! {
    FleetMsg => Fleet,
    CommandMsg => Command,
    FormationMsg => Formation,
    GeofenceMsg => Geofence,
    PayloadMsg => Payload,
    TrackingMsg => Tracking,
    AdminMsg => Admin,
    DistributedMsg => Distributed,
    MissionMsg => Mission,
}
