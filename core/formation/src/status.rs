//! What goes into and comes out of a formation tick: the members' state the engine
//! reads ([`Member`]), the slot command each member is sent ([`SlotCommand`]), and the
//! formation's status as the API shows it ([`FormationStatus`], [`MemberStatus`],
//! [`AbsentMember`]).

use super::hazard::Hazard;
use super::reference::Reference;
use super::spec::FormationSpec;
use serde::Serialize;
use skein_model::geo::Ned;
use std::time::Duration;

/// What the engine needs to know of a member each tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Member {
    /// Position, swarm-frame NED, metres.
    pub position: Ned,
    /// Velocity, swarm-frame NED, m/s.
    pub velocity: Ned,
    /// Heading, radians clockwise from north.
    pub heading_rad: f64,
    /// Time since its last message. A member silent for longer than
    /// [`PACE_SILENCE`](super::PACE_SILENCE) neither slows the formation nor anchors
    /// it (its position is stale); one silent for `ride_through` loses its slot (and the
    /// lead).
    pub silence: Duration,
    /// Where skein currently holds it (for anchoring a new leader), swarm-frame NED,
    /// metres, if anywhere.
    pub target: Option<Ned>,
    /// How long it flies its slot on its own while silent: its agent's ride-through (the
    /// agent flies the formation on from its mirror, `skein_dds::agent`), or
    /// [`LEADER_SILENCE`](super::LEADER_SILENCE) for a vehicle of this process.
    pub ride_through: Duration,
}

/// Slot target for one member.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlotCommand {
    /// Slot index.
    pub slot: usize,
    /// True for the leader's slot.
    pub leader: bool,
    /// Where the member is sent now, swarm frame: on the transition plan while a change
    /// is flown, its slot otherwise (NED, metres).
    pub position: Ned,
    /// The slot itself, swarm-frame NED, metres.
    pub goal: Ned,
    /// Slot velocity (feed-forward), swarm-frame NED, m/s.
    pub velocity: Ned,
    /// Heading to hold, radians clockwise from north.
    pub yaw_rad: f64,
}

/// One member's place.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct MemberStatus {
    /// Vehicle id.
    pub id: String,
    /// Slot index (0 = leader's slot).
    pub slot: usize,
    /// Slot position, swarm-frame NED.
    pub target: Ned,
    /// Distance from the vehicle to its slot, metres. For a member silent for more than
    /// [`PACE_SILENCE`](super::PACE_SILENCE), its error when last heard: its last
    /// position moved on with its slot since.
    pub error_m: f64,
    /// Seconds since it was last heard, when more than
    /// [`PACE_SILENCE`](super::PACE_SILENCE) (it rides through on its slot: see
    /// [`Member::ride_through`]); `null` otherwise.
    pub silent_s: Option<f64>,
}

/// Why a member that flew the formation is out of it, as the coordinator sees it
/// ([`FormationEngine::status_with`](super::FormationEngine::status_with)).
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum Absence {
    /// Nothing heard from it for [`LEADER_SILENCE`](super::LEADER_SILENCE), its link not
    /// yet declared lost (a fade).
    Silent,
    /// Hovering without having been asked to leave (its agent held it when it lost its
    /// coordinator).
    Held,
    /// Its link is lost (a cut-off agent, a radio out of range): also a hazard the
    /// formation flies around.
    Lost,
    /// PX4 failsafe: also a hazard the formation flies around.
    Failsafe,
    /// Any other state PX4 or the vehicle put it in (landing on a low battery, say).
    Other,
}

/// Where an absent member is and why it is absent (the coordinator's view).
#[derive(Debug, Clone, PartialEq)]
pub struct Whereabouts {
    /// Its last known position, swarm-frame NED, metres (`None`: not known).
    pub position: Option<Ned>,
    /// Why it is out of the formation.
    pub absence: Absence,
    /// Its state as the FSM names it (`Hovering`, `Lost`, …).
    pub state: String,
}

/// A member that flew the formation and dropped out of it without the operator asking
/// (`absent` in `GET /api/v1/formation`).
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct AbsentMember {
    /// Vehicle id.
    pub id: String,
    /// The slot index it had.
    pub slot: usize,
    /// Where that slot is now (its offset from the reference point as it was, moved and
    /// turned with the formation), swarm-frame NED.
    pub target: Ned,
    /// Distance from its last known position to that place, metres (`null`: position not
    /// known).
    pub error_m: Option<f64>,
    /// Why it is out.
    pub absence: Absence,
    /// Its state (`Hovering`, `Lost`, …).
    pub state: String,
}

/// The formation as `GET /api/v1/formation` shows it.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct FormationStatus {
    /// The spec in force, if any.
    #[serde(flatten)]
    pub spec: Option<FormationSpec>,
    /// True while vehicles are flying it.
    pub active: bool,
    /// The leader in force: a vehicle id or `"virtual"`.
    pub leader_id: Option<String>,
    /// The reference point.
    pub reference: Option<Reference>,
    /// Members, by slot.
    pub members: Vec<MemberStatus>,
    /// Members that dropped out without the operator asking (see [`AbsentMember`]), by id.
    /// They stay listed until they fly their slot again, the operator commands them, or
    /// the formation stops.
    pub absent: Vec<AbsentMember>,
    /// Root mean square of the slot errors of every member that should fly the formation:
    /// the members and the absent ones (whose position is known), each to where its slot
    /// is now, metres. A member that is out never makes the figure look better.
    pub rms_error_m: Option<f64>,
    /// Root mean square of the slot errors of the members flying a slot only, metres:
    /// how well those fly, whoever is out.
    pub members_rms_error_m: Option<f64>,
    /// Smallest distance between any two airborne vehicles right now, metres, of those
    /// heard within [`PACE_SILENCE`](super::PACE_SILENCE) (a silent one's last position
    /// is not where it is now).
    pub min_separation_m: Option<f64>,
    /// Progress of the formation change in flight (0 to 1), if one is.
    pub transition_progress: Option<f64>,
    /// The formation requested during the change in flight, applied when it ends.
    pub pending: Option<FormationSpec>,
    /// Vehicles planned around as hazards (last known position, radius).
    pub hazards: Vec<Hazard>,
    /// Why the formation cannot be flown clear of the hazards (it holds), if so.
    pub blocked: Option<String>,
}

/// A formation change planned again because pacing held members too long.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Replan {
    /// The members that were held.
    pub stuck: Vec<String>,
    /// Who was held how far, for how long.
    pub reason: String,
}
