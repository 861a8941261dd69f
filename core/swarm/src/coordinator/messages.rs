//! What the coordinator is told: its message enum (the API reaches the swarm only
//! through it), the service actors it supervises, and the shapes of its answers.

use super::children::Node;
use super::commands::CommandOutcome;
use crate::formation::{FormationSpec, FormationStatus, LeaderMotion};
use crate::payload::PayloadShared;
use crate::protocol::{Command, FromVehicle, PayloadCommandError};
use crate::supervision::TreeNode;
use ractor::{ActorCell, ActorId, ActorProcessingErr, ActorRef, RpcReplyPort};
use serde::Serialize;
use skein_link::Px4LinkMsg;
use skein_link::endpoint::Discovery;
use skein_mavlink::DecodeCounts;
use skein_model::supervision::{ChildKind, FaultKind};
use skein_model::vehicle::VehicleSnapshot;
use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::time::Instant;

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

/// The air picture (`GET /api/v1/tracks`, `GET /api/v1/swarms`).
#[derive(Debug, Clone, Default)]
pub struct AirPictureAnswer {
    /// The tracks, with their forecasts and swarms.
    pub tracks: Vec<crate::tracks::TrackView>,
    /// The hostile swarms.
    pub swarms: Vec<crate::tracks::SwarmView>,
    /// Which vehicle observes which track or swarm (vehicle id, target id).
    pub observing: Vec<(String, String)>,
    /// The observations flown on stations.
    pub stations: Vec<super::stations::StationsView>,
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

/// Messages of [`Coordinator`].
pub enum CoordinatorMsg {
    /// An endpoint heard an autopilot it has no route for.
    Discovered {
        /// Index of the endpoint.
        endpoint: usize,
        /// What it heard.
        discovery: Discovery,
    },
    /// A vehicle's protocol message (acks, state changes, payload answers).
    FromVehicle(FromVehicle),
    /// What the DDS carrier of the distributed roles asks ([`super::remote`]).
    Distributed(super::remote::DistributedMsg),
    /// A command for every vehicle.
    SwarmCommand(Command, RpcReplyPort<CommandOutcome>),
    /// A command for one vehicle; `Err(None)` when the vehicle does not exist.
    VehicleCommand(
        String,
        Command,
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
    /// The operator says vehicle `id` is no longer a hazard; `Err(None)` when there is no
    /// such vehicle, `Err(Some(why))` when it is not a hazard.
    ClearHazard(String, RpcReplyPort<Result<(), Option<String>>>),
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
    /// The ground-station forwarder, for its counters (see `Swarm::forward_to_gcs`).
    SetGcs(Arc<skein_link::GcsForwarder>),
    /// The geofence in force and its version (`GET /api/v1/geofence`).
    GetGeofence(RpcReplyPort<Arc<crate::context::LiveFence>>),
    /// Put a new geofence in force (`PUT /api/v1/geofence`): checked, tried on every
    /// connected autopilot, committed or refused as a whole (see [`super::geofence`]).
    SetGeofence(
        skein_model::geofence::Geofence,
        RpcReplyPort<Result<super::geofence::FenceChange, super::geofence::FenceRefusal>>,
    ),
    /// The vehicles' uploads of a geofence change came back (from its task).
    FenceTried(super::geofence::FenceTrial),
    /// A local vehicle's `Px4Link` actor (parameters); `Err` says why there is none.
    GetLink(
        String,
        RpcReplyPort<Result<ActorRef<Px4LinkMsg>, PayloadCommandError>>,
    ),
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
    /// Attach a payload slot to a vehicle at run time (until restart): the payload as
    /// listed once its driver exists, or why not (naming the field).
    AttachPayload(
        String,
        skein_payload::PayloadSpec,
        RpcReplyPort<Result<serde_json::Value, PayloadCommandError>>,
    ),
    /// Detach a vehicle's payload slot (its driver's `shutdown` runs first).
    DetachPayload(
        String,
        String,
        RpcReplyPort<Result<serde_json::Value, PayloadCommandError>>,
    ),
    /// A payload plugin was loaded or unloaded in this process: every local vehicle starts
    /// the slots now provided and stops the payloads whose library is gone.
    PluginsChanged,
    /// Payload instances (vehicle id, slot) whose plugin was reloaded at this instant: their
    /// vehicles re-create them on the new build (those created since are left alone).
    RefreshPayloads(Vec<(String, String)>, Instant),
    /// The supervision tree.
    GetSupervision(RpcReplyPort<TreeNode>),
    /// The metrics in Prometheus text format.
    RenderMetrics(RpcReplyPort<String>),
    /// The counter-UAS tracks now and which vehicle observes which track
    /// (`GET /api/v1/tracks`).
    GetTracks(RpcReplyPort<TracksAnswer>),
    /// The tracks, the hostile swarms and who observes what.
    GetAirPicture(RpcReplyPort<AirPictureAnswer>),
    /// Point the gimbals of the vehicles (default: all with a gimbal) at a track or swarm
    /// and keep them on it, and with `stations` fly them to the stations that fix it
    /// best; answers the observing vehicles.
    Observe(
        super::observe::ObserveSpec,
        RpcReplyPort<Result<Vec<String>, super::observe::ObserveRefusal>>,
    ),
    /// Stop observing a track or swarm; answers the vehicles released.
    StopObserving(String, RpcReplyPort<Vec<String>>),
    /// The in-process simulator's ground truth (`GET /api/v1/sim/truth`); `None` when no
    /// simulator is embedded.
    GetSimTruth(RpcReplyPort<Option<serde_json::Value>>),
    /// Start and supervise a service (the HTTP API).
    AddService(ServiceSpec, RpcReplyPort<Result<(), String>>),
    /// Inject a fault at an actor path (`"coordinator/uav-1/px4link"`).
    InjectFault(String, FaultKind, RpcReplyPort<Result<(), FaultError>>),
    /// Watchdog probe (the process watchdog pings the coordinator).
    Ping(RpcReplyPort<()>),
    /// The process's load monitor (services ask once, then read it directly to shed
    /// optional work, see [`crate::load`]).
    GetLoad(RpcReplyPort<std::sync::Arc<crate::load::LoadMonitor>>),
    /// Fault injection into the coordinator itself.
    Fault(FaultKind),
    /// Formation loop tick.
    FormationTick,
    /// Time to ping the children.
    WatchTick,
    /// A child did not answer the watchdog.
    ChildHung(Node, ActorId),
    /// A child's backoff has passed.
    RestartChild(Node, Instant, String),
    /// A command's vehicles had their time to answer: the silent ones are refused.
    CommandTimeout(u64),
    /// A payload command's vehicle had its time to answer.
    PayloadTimeout(u64),
}
