//! Events of the swarm, as the WebSocket stream and the dashboard's event log show them.

use serde::{Deserialize, Serialize};
use skein_model::fsm::VehicleState;

/// Something that happened in the swarm. Serialised with a `"type"` tag in snake case
/// (`{"type": "state_changed", "id": "uav-1", "from": "Hovering", "to": "InFormation"}`).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum SwarmEvent {
    /// A vehicle's first heartbeat arrived and it joined the swarm.
    VehicleJoined {
        /// Vehicle id.
        id: String,
        /// MAVLink system id.
        sysid: u8,
        /// Connection string of its endpoint.
        connection: String,
    },
    /// FSM state change.
    StateChanged {
        /// Vehicle id.
        id: String,
        /// Previous state.
        from: VehicleState,
        /// New state.
        to: VehicleState,
    },
    /// Outcome of an accepted command (the API answered 202 with `command_id`).
    CommandResult {
        /// The id the API returned.
        command_id: u64,
        /// Vehicle id.
        id: String,
        /// Command name (`"takeoff"`).
        command: String,
        /// True when the vehicle carried it out.
        ok: bool,
        /// Why not, when `ok` is false.
        error: Option<String>,
    },
    /// `STATUSTEXT` from a vehicle.
    StatusText {
        /// Vehicle id.
        id: String,
        /// `MAV_SEVERITY` (0 emergency … 7 debug).
        severity: u8,
        /// The text.
        text: String,
    },
    /// The link to a vehicle went silent for the link timeout.
    LinkLost {
        /// Vehicle id.
        id: String,
    },
    /// The link came back.
    LinkRestored {
        /// Vehicle id.
        id: String,
    },
    /// The vehicle's autopilot rebooted.
    Rebooted {
        /// Vehicle id.
        id: String,
    },
    /// A mission started (`POST /api/v1/missions/{id}/start`).
    MissionStarted {
        /// Mission id.
        id: String,
    },
    /// A mission's state or step changed: a step began (its index), the mission paused
    /// (by a refusal: `GET /api/v1/missions/{id}` says why), is done or aborted.
    MissionStep {
        /// Mission id.
        id: String,
        /// The mission's state now.
        state: skein_mission::RunState,
        /// The step flown now (or the last one).
        step: usize,
    },
    /// A mission did something by itself (a reaction of its plan: a reserve sent for a
    /// vehicle low on battery, a vehicle sent home).
    MissionReaction {
        /// Mission id.
        id: String,
        /// What happened, in words.
        detail: String,
    },
    /// The operator paused, resumed, skipped a step of or aborted a mission.
    MissionControlled {
        /// Mission id.
        id: String,
        /// `pause`, `resume`, `skip` or `abort`.
        action: String,
    },
    /// The formation was set or changed.
    FormationChanged {
        /// The formation as `GET /api/v1/formation` shows it.
        formation: serde_json::Value,
    },
    /// This coordinator candidate (`skein coordinator`) took or gave up the coordinator
    /// role (see `skein_swarm::election`).
    CoordinatorRoleChanged {
        /// This candidate's id.
        coordinator_id: String,
        /// Its role now.
        role: crate::election::CoordinatorRole,
        /// The epoch it holds the role in (active), or the highest it has heard.
        epoch: u64,
        /// Why it stepped down (names the coordinator it yields to); `None` on a claim.
        reason: Option<String>,
    },
    /// The formation has a new leader (failover, or the first one).
    LeaderChanged {
        /// The previous leader, if any.
        from: Option<String>,
        /// The new leader (a vehicle id or `"virtual"`).
        to: String,
        /// Why.
        reason: String,
    },
    /// A setpoint was moved by the geofence.
    GeofenceClamp {
        /// Vehicle id.
        id: String,
        /// `"radius"`, `"polygon"`, `"exclusion"`, `"ceiling"` or `"floor"`.
        violation: String,
    },
    /// An operator put a new geofence in force (`PUT /api/v1/geofence`): every connected
    /// autopilot already holds it.
    GeofenceChanged {
        /// Its version (the configured fence is 1).
        version: u64,
        /// The fence, as `GET /api/v1/geofence` shows it.
        fence: skein_model::geofence::Geofence,
    },
    /// A vehicle in the air left the geofence (`breached` true; its autopilot's own fence
    /// takes `GF_ACTION`), or is back inside (false).
    GeofenceBreach {
        /// Vehicle id.
        id: String,
        /// Outside now.
        breached: bool,
        /// Where, swarm frame `[north_m, east_m, altitude_m]`.
        position: [f64; 3],
    },
    /// Where a vehicle's autopilot copy of the fence stands changed (uploaded and read
    /// back, refused, different).
    FenceSync {
        /// Vehicle id.
        id: String,
        /// `"pending"`, `"synced"`, `"differs"` or `"failed"`.
        state: String,
        /// The fence version concerned.
        version: u64,
        /// Why (differs, failed).
        reason: Option<String>,
    },
    /// A supervised actor ended (panic, error, hang, stop).
    ActorFailed {
        /// Actor path (`"coordinator/uav-1/px4link"`).
        path: String,
        /// Actor kind (`"px4link"`).
        kind: String,
        /// Panic message, error, hang or stop reason.
        reason: String,
        /// Restarts of this actor so far.
        restarts: u32,
        /// Delay before its restart, ms; `None` when it is not restarted.
        next_backoff_ms: Option<u64>,
        /// True when its restart budget is spent and the failure escalates.
        escalated: bool,
    },
    /// An escalation was carried out (a payload disabled, a vehicle commanded to HOLD …).
    ActorEscalated {
        /// Actor path.
        path: String,
        /// What was done.
        action: String,
    },
    /// A supervised actor was restarted and answers again.
    ActorRestarted {
        /// Actor path (`"coordinator/uav-1/px4link"`).
        path: String,
        /// Why it had ended.
        reason: String,
        /// Restarts of this actor so far.
        restarts: u32,
        /// From the failure being noticed by the supervisor to the replacement answering
        /// its first message, µs.
        latency_us: u64,
    },
    /// The tracker started a (tentative) track of a non-cooperative aircraft.
    TrackCreated {
        /// The track.
        track: crate::tracks::TrackView,
    },
    /// A track was confirmed.
    TrackConfirmed {
        /// The track.
        track: crate::tracks::TrackView,
    },
    /// A confirmed track has not been seen for the tracker's `lost_after_s`.
    TrackLost {
        /// The track.
        track: crate::tracks::TrackView,
    },
    /// A lost track was seen again, under its id.
    TrackRecovered {
        /// The track.
        track: crate::tracks::TrackView,
    },
    /// A track was deleted (aged out, never confirmed, or merged into another).
    TrackDeleted {
        /// The track.
        track: crate::tracks::TrackView,
    },
    /// Confirmed tracks flying together were recognised as a hostile swarm.
    SwarmDetected {
        /// The swarm (as `GET /api/v1/swarms` lists it).
        swarm: crate::tracks::SwarmView,
    },
    /// A hostile swarm's members or shape changed.
    SwarmChanged {
        /// The swarm now.
        swarm: crate::tracks::SwarmView,
        /// Tracks that joined it.
        joined: Vec<String>,
        /// Tracks that left it.
        left: Vec<String>,
    },
    /// Fewer than two of a hostile swarm's tracks fly together any more.
    SwarmLost {
        /// The swarm as last seen.
        swarm: crate::tracks::SwarmView,
    },
    /// An event raised by a payload.
    PayloadEvent {
        /// Vehicle id.
        id: String,
        /// Payload slot.
        slot: String,
        /// Event kind, as the payload names it.
        kind: String,
        /// Event data.
        data: serde_json::Value,
    },
    /// A vehicle that no longer follows its setpoints (lost, or in PX4's failsafe) became
    /// an obstacle the formation plans around.
    HazardAdded {
        /// Vehicle id.
        id: String,
        /// Its last known position, swarm-frame NED metres.
        position: skein_model::geo::Ned,
        /// Why (`"Lost"`, `"Failsafe"`).
        reason: String,
    },
    /// A hazard ended.
    HazardCleared {
        /// Vehicle id.
        id: String,
        /// Why: heard again and following, seen on the ground, unseen too long, or
        /// cleared by an operator.
        reason: String,
    },
    /// A formation change whose pacing held members too long was planned again from
    /// where the members are.
    FormationReplanned {
        /// The members that were held.
        stuck: Vec<String>,
        /// Who was held how far, for how long.
        reason: String,
    },
    /// The formation cannot be flown clear of the hazards and holds (`reason`), or can
    /// again (`reason` null).
    FormationBlocked {
        /// Why, or `None` when it is no longer blocked.
        reason: Option<String>,
    },
}

impl SwarmEvent {
    /// The vehicle of an event that a vehicle's own actors emit (its FSM, link, commands,
    /// payloads): the events an agent forwards to the coordinators
    /// (`/skein/swarm/events`); `None` for the swarm's and the coordinator's own.
    pub fn vehicle_id(&self) -> Option<&str> {
        match self {
            SwarmEvent::StateChanged { id, .. }
            | SwarmEvent::CommandResult { id, .. }
            | SwarmEvent::StatusText { id, .. }
            | SwarmEvent::LinkLost { id }
            | SwarmEvent::LinkRestored { id }
            | SwarmEvent::Rebooted { id }
            | SwarmEvent::GeofenceClamp { id, .. }
            | SwarmEvent::GeofenceBreach { id, .. }
            | SwarmEvent::FenceSync { id, .. }
            | SwarmEvent::PayloadEvent { id, .. } => Some(id),
            _ => None,
        }
    }
}
