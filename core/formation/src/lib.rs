//! The formation engine at run time (the paper's CoordinatorUAVModel): who leads, where
//! the formation's reference point is and how it moves, which slot each member flies, and
//! how well they fly it.
//!
//! - **Reference point** `P(t)`: where slot 0 is. It holds, goes to a point at a speed,
//!   follows waypoints or orbits a point ([`LeaderMotion`]), with speed and acceleration
//!   limits, clamped into the geofence.
//! - **Leader**: a vehicle (it flies `P`; the followers fly their offsets from the
//!   leader's *measured* position and velocity, true leader-follower) or the virtual
//!   leader (everyone flies their offsets from `P`).
//! - **Failover**: a leader vehicle that leaves the formation or falls silent for
//!   [`LEADER_SILENCE`] is replaced by the member nearest to it; the others are re-slotted
//!   around it; the event says who and why.
//! - **Frame**: offsets turn with the formation heading — `world`: the spec's
//!   `heading_deg`; `leader`: the leader's heading (the virtual leader's direction of
//!   travel).
//! - **Assignment**: minimum total squared distance (Kuhn–Munkres) whenever the shape,
//!   the leader or the membership changes; a vehicle leader keeps slot 0.
//! - **Transitions** (separation by construction, CAPT: Turpin, Michael & Kumar,
//!   "Concurrent assignment and planning of trajectories for multiple robots", IJRR 2014):
//!   after every assignment each member flies the straight line from where it starts to
//!   its new slot, *all members on one shared time scale* `β(t)` (a trapezoidal profile
//!   of the longest path, [`TRANSIT_SPEED_M_S`], [`TRANSIT_ACCEL_M_S2`]), in the pattern
//!   frame that moves and turns with the reference. Because the assignment minimises the
//!   total squared distance, swapping any two members' goals cannot lower it, so
//!   `(a_i − a_j)·(b_i − b_j) ≥ 0` for starts `a` and goals `b`; the squared distance
//!   of two members at `β` is then at least `(1−β)²|a_i−a_j|² + β²|b_i−b_j|² ≥ δ²/2`,
//!   where `δ` is the smallest distance among the starts and among the goals. Every pair
//!   therefore stays at least `δ/√2` apart throughout; the API refuses a formation whose
//!   slots are closer than `√2 ×` the setpoint separation. A change requested during a
//!   transition waits for it to end (latest request wins); a member joining or leaving
//!   during one re-plans from the planned positions. The members' shapers
//!   protect what the plan does not cover (a vehicle leader, vehicles outside the
//!   formation, a member far off its plan, see [`skein_model::safety::SetpointShaper`]).
//!
//! - **Hazards**: a member lost (or in PX4's failsafe) is an obstacle at its last known
//!   position, its radius growing with the time unseen. The reference moves by the
//!   smallest horizontal shift that puts every slot the separation plus that radius away
//!   ([`clearing_shift`]); a member whose straight path would pass a hazard flies it on a
//!   layer above (or below) it, as followers pass a leader vehicle (the assignment stays
//!   minimum squared distance, so its separation argument holds); a formation that cannot
//!   be cleared within [`MAX_HAZARD_SHIFT_M`] inside the fence holds and says so
//!   (`blocked`).
//! - **No deadlock**: a change whose pacing has held a member for the replan time
//!   (default 10 s) is planned again from where the members are ([`Replan`]).
//!
//! Geometry and assignment come from [`skein_model::formation`].
//!
//! One concept per file:
//! - `spec`: the formation as asked for and how its reference point moves.
//! - `reference`: the moving reference point, its limits, fence and pace.
//! - `pattern`: the slot pattern's heading and turn.
//! - `leader`: leader resolution and failover.
//! - `assignment`: which slot each member flies.
//! - `transition`: a formation change in flight on one time scale.
//! - `climb`: the layers of followers whose path would pass a leader vehicle.
//! - `hazard`: vehicles that may still fly where the formation is not steering them, and
//!   how slots and paths keep clear of them.
//! - `status`: what goes into and comes out of a tick.
//! - `ride`: the formation flown on from its mirror where its coordinator is not heard
//!   (an agent's ride-through, a standby's resumption).
//! - `absence`: members that dropped out without being asked, still listed with their
//!   error, so that `rms_error_m` never improves because a member is out.
//! - `engine`: the engine's state, its tick (`engine::tick`, one function per step) and
//!   its status.
//!
//! A crate below the runtime, as `skein-model` is: no actor, no task, no I/O. The
//! coordinator's formation loop (`skein_swarm`) feeds it the members' reports and sends
//! the slot commands it returns; the benchmarks' virtual-time rehearsal ticks it
//! directly. It reads the swarm protocol's time stamps and track ids (`skein-protocol`).
#![warn(missing_docs)]

mod absence;
mod assignment;
mod climb;
mod engine;
mod hazard;
mod leader;
mod pattern;
mod reference;
mod ride;
mod spec;
mod status;
mod transition;

pub use engine::PACE_SILENCE;
pub use engine::mirror::FormationMirror;
pub use engine::{DEFAULT_SEPARATION_M, FormationEngine, MAX_HAZARD_SHIFT_M};
pub use hazard::{Hazard, HazardConfig, clearing_shift};
pub use leader::{LEADER_SILENCE, LeaderChange};
pub use pattern::{TURN_ACCEL_M_S2, TURN_SPEED_M_S};
pub use reference::{FENCE_BUFFER_M, PACE_SLOW_M, PACE_STOP_M, RETURN_SPEED_M_S, Reference};
pub use ride::{RIDE_STEP_S, RideThrough};
pub use spec::{FormationFrame, FormationSpec, LeaderMotion, VIRTUAL};
pub use status::{
    Absence, AbsentMember, FormationStatus, Member, MemberStatus, Replan, SlotCommand, Whereabouts,
};
pub use transition::{
    LAG_SLOW_M, LAG_STOP_M, TRANSIT_ACCEL_M_S2, TRANSIT_CLIMB_M_S, TRANSIT_SPEED_M_S,
};
