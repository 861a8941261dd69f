//! What goes into and comes out of a formation tick: the members' state the engine
//! reads ([`Member`]), the slot command each member is sent ([`SlotCommand`]), and the
//! formation's status as the API shows it ([`FormationStatus`], [`MemberStatus`]).

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
    /// Time since its last message (a leader silent for
    /// [`LEADER_SILENCE`](super::LEADER_SILENCE) loses the lead; any silent member its slot).
    pub silence: Duration,
    /// Where skein currently holds it (for anchoring a new leader), swarm-frame NED,
    /// metres, if anywhere.
    pub target: Option<Ned>,
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
    /// Distance from the vehicle to its slot, metres.
    pub error_m: f64,
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
    /// Root mean square of the members' slot errors, metres.
    pub rms_error_m: Option<f64>,
    /// Smallest distance between any two airborne vehicles right now, metres.
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
