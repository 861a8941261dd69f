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
//! Geometry and assignment come from [`skein_model::formation`].

use serde::{Deserialize, Serialize};
use skein_model::formation::{Shape, assign_slots, custom_offsets, slot_offsets, slot_positions};
use skein_model::geo::{Ned, wrap_pi};
use skein_model::safety::Geofence;
use std::collections::BTreeMap;
use std::time::Duration;

/// A leader vehicle silent this long loses the lead (PX4's own heartbeat timeout is 1.5 s).
pub const LEADER_SILENCE: Duration = Duration::from_millis(1500);

/// The name of the virtual leader in specs and status (`"leader": "virtual"`).
pub const VIRTUAL: &str = "virtual";

/// How slot offsets are oriented.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FormationFrame {
    /// Fixed in the swarm frame at `heading_deg`.
    #[default]
    World,
    /// Turning with the leader's heading.
    Leader,
}

/// A formation as the operator asks for it (`PUT /api/v1/formation`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FormationSpec {
    /// The shape.
    pub shape: Shape,
    /// Distance between neighbouring slots, metres.
    pub spacing_m: f64,
    /// Leader: a vehicle id, [`VIRTUAL`], or `None` for the first member by id.
    pub leader: Option<String>,
    /// Formation heading, degrees clockwise from north (`world` frame).
    pub heading_deg: f64,
    /// Formation altitude above the swarm origin, metres; `None` = the leader's altitude.
    pub altitude_m: Option<f64>,
    /// How offsets are oriented.
    pub frame: FormationFrame,
    /// Follower offsets of a [`Shape::Custom`] formation (forward, right, down), metres.
    pub offsets: Vec<Ned>,
}

impl FormationSpec {
    /// Slots the formation has for `n` members (custom: its offsets + the leader).
    pub fn capacity(&self, n: usize) -> usize {
        match self.shape {
            Shape::Custom => n.min(self.offsets.len() + 1),
            _ => n,
        }
    }

    fn offsets(&self, n: usize) -> Vec<Ned> {
        match self.shape {
            Shape::Custom => custom_offsets(&self.offsets).into_iter().take(n).collect(),
            shape => slot_offsets(shape, n, self.spacing_m),
        }
    }

    fn wants_virtual(&self) -> bool {
        self.leader.as_deref() == Some(VIRTUAL)
    }
}

/// How the reference point moves.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "motion", rename_all = "snake_case")]
pub enum LeaderMotion {
    /// Stay where it is.
    Hold,
    /// Fly to a point.
    GoTo {
        /// Target, swarm-frame NED.
        target: Ned,
        /// Cruise speed, m/s.
        speed_m_s: f64,
    },
    /// Fly a list of points in order.
    Waypoints {
        /// The points, swarm-frame NED.
        points: Vec<Ned>,
        /// Cruise speed, m/s.
        speed_m_s: f64,
        /// Index of the point being flown to.
        next: usize,
        /// Start over after the last point.
        repeat: bool,
    },
    /// Circle a point.
    Orbit {
        /// Centre, swarm-frame NED (its `down_m` is the orbit altitude).
        centre: Ned,
        /// Radius, metres.
        radius_m: f64,
        /// Speed along the circle, m/s.
        speed_m_s: f64,
        /// Clockwise seen from above.
        clockwise: bool,
    },
}

/// Acceleration limit of the reference point, m/s² (under the vehicles' own, so they keep up).
const REFERENCE_ACCEL_M_S2: f64 = 1.5;
/// Speed of the longest path of a transition relative to the pattern, m/s (a formation
/// moving at 5 m/s stays within the 8 m/s default vehicle limit).
pub const TRANSIT_SPEED_M_S: f64 = 2.5;
/// Separation of [`FormationEngine::default`] (3 m plus the default 0.5 m margin), metres.
pub const DEFAULT_SEPARATION_M: f64 = 3.5;
/// Speed of the outermost slot of a `leader`-frame pattern while it turns, m/s.
pub const TURN_SPEED_M_S: f64 = 2.0;
/// Vertical speed of a transition relative to the pattern, m/s (under PX4's descent limit).
pub const TRANSIT_CLIMB_M_S: f64 = 1.0;
/// Acceleration of a transition's time scale along the longest path, m/s².
pub const TRANSIT_ACCEL_M_S2: f64 = 0.5;
/// Angular acceleration of a turning pattern at its outermost slot, m/s².
pub const TURN_ACCEL_M_S2: f64 = 0.5;
/// A member this far behind its planned place slows the transition's time scale down…
pub const LAG_SLOW_M: f64 = 0.75;
/// … and this far stops it: the plan separates members *at one time scale*, so the
/// time scale waits for the slowest instead of leaving it behind.
pub const LAG_STOP_M: f64 = 1.5;
/// A member this far from where it was sent slows the formation's motion (the
/// reference point's speed and a `leader`-frame pattern's turn rate) down…
pub const PACE_SLOW_M: f64 = 1.0;
/// … and this far stops it, so that no member is left behind by a moving or turning
/// pattern (a far-behind member cuts across the others to catch up).
pub const PACE_STOP_M: f64 = 2.5;

/// A formation change in progress: every member on a straight line in the pattern frame,
/// all on one time scale (see the module docs).
///
/// When followers must pass a leader vehicle, the change has three phases on that time
/// scale: those followers climb (or descend) to their layer while everyone else holds
/// (`hold_s`), then every member flies its straight line with the layered followers
/// staying at their layer, then they return to the formation's altitude at their slots
/// (`hold_s` again). Horizontal motion happens only in the middle phase, all members on
/// one `β`, so the assignment's separation argument holds throughout.
#[derive(Debug, Clone)]
struct Transition {
    /// Where each member starts, pattern frame (unrotated offsets from the anchor).
    starts: BTreeMap<String, Ned>,
    /// Where each member ends, pattern frame.
    goals: BTreeMap<String, Ned>,
    /// Length of the longest path (vertical legs scaled to their slower speed), metres.
    length_m: f64,
    /// Time along the profile, seconds (advances slower than real time while a member
    /// lags its plan).
    elapsed_s: f64,
    /// Rate of the time scale against real time at the last tick, 0 to 1.
    scale: f64,
    /// Layer of the followers that pass a leader vehicle, by member.
    climbs: BTreeMap<String, Climb>,
    /// Length of the layering phases before and after the straight lines, seconds.
    hold_s: f64,
}

impl Transition {
    /// Duration of the straight-line phase, seconds: a trapezoidal speed profile over
    /// `length_m` (peak speed, its acceleration time, and the cruise time).
    fn profile(&self) -> (f64, f64, f64) {
        let (l, v, a) = (self.length_m, TRANSIT_SPEED_M_S, TRANSIT_ACCEL_M_S2);
        let vp = v.min((a * l).sqrt());
        let ta = vp / a;
        let tc = ((l - vp * ta) / vp).max(0.0);
        (vp, ta, tc)
    }

    /// Total duration on the time scale, seconds.
    fn duration_s(&self) -> f64 {
        if self.length_m < 1e-6 {
            return 2.0 * self.hold_s;
        }
        let (_, ta, tc) = self.profile();
        2.0 * self.hold_s + 2.0 * ta + tc
    }

    /// Progress `β` in [0, 1] of the straight lines and its rate (1/s) at `elapsed_s`.
    fn progress(&self) -> (f64, f64) {
        let l = self.length_m;
        if l < 1e-6 {
            return (
                if self.elapsed_s >= self.hold_s {
                    1.0
                } else {
                    0.0
                },
                0.0,
            );
        }
        let (vp, ta, tc) = self.profile();
        let a = TRANSIT_ACCEL_M_S2;
        let da = 0.5 * a * ta * ta;
        let t = self.elapsed_s - self.hold_s;
        let (s, ds) = if t <= 0.0 {
            (0.0, 0.0)
        } else if t < ta {
            (0.5 * a * t * t, a * t)
        } else if t < ta + tc {
            (da + vp * (t - ta), vp)
        } else if t < 2.0 * ta + tc {
            let u = 2.0 * ta + tc - t;
            (l - 0.5 * a * u * u, a * u)
        } else {
            (l, 0.0)
        };
        ((s / l).clamp(0.0, 1.0), ds / l)
    }

    fn done(&self) -> bool {
        self.elapsed_s >= self.duration_s()
    }

    /// How far the layered followers are on their way to their layer (0 to 1) at
    /// `elapsed_s`, smoothstep, and its rate (1/s).
    fn layering(&self) -> (f64, f64) {
        if self.hold_s <= 0.0 {
            return (0.0, 0.0);
        }
        let e = self.elapsed_s;
        let end = self.duration_s();
        let (x, dx) = if e < self.hold_s {
            (e / self.hold_s, 1.0 / self.hold_s)
        } else if e > end - self.hold_s {
            ((end - e) / self.hold_s, -1.0 / self.hold_s)
        } else {
            (1.0, 0.0)
        };
        let x = x.clamp(0.0, 1.0);
        (x * x * (3.0 - 2.0 * x), 6.0 * x * (1.0 - x) * dx)
    }

    /// Planned offset of `id` now, pattern frame, and its rate of change.
    fn planned(&self, id: &str) -> Option<(Ned, Ned)> {
        let (beta, rate) = self.progress();
        let a = *self.starts.get(id)?;
        let b = *self.goals.get(id)?;
        let rate = rate * self.scale;
        let h = self.climbs.get(id).map_or(0.0, |c| c.height_m);
        let (f, df) = self.layering();
        let climb = Ned::new(0.0, 0.0, -h * f);
        let climb_rate = Ned::new(0.0, 0.0, -h * df * self.scale);
        Some((a + (b - a) * beta + climb, (b - a) * rate + climb_rate))
    }
}

/// The layer of a follower that passes a leader vehicle during a transition.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Climb {
    /// Height above the straight path, metres (negative: below it).
    height_m: f64,
}

impl Climb {
    /// The smallest layer (over the leader rather than under it on a tie) that keeps a
    /// follower going `a → b` at least `separation_m` from the origin (the leader
    /// vehicle, in its own pattern frame) through all three phases, or the highest one
    /// when none does (the shapers protect the rest). A layer below lowers the reference's
    /// ceiling (every planned place stays inside the fence).
    fn over_origin(a: Ned, b: Ned, separation_m: f64) -> Climb {
        [1.0, -1.0, 1.5, -1.5, 2.0, -2.0, 3.0, -3.0]
            .into_iter()
            .map(|k| Climb {
                height_m: k * separation_m,
            })
            .find(|c| clearance_from_origin(a, b, Some(c)) >= separation_m)
            .unwrap_or(Climb {
                height_m: 3.0 * separation_m,
            })
    }

    /// Length of the layering phases for this climb, seconds (peak vertical speed
    /// [`TRANSIT_CLIMB_M_S`]).
    fn hold_s(&self) -> f64 {
        1.5 * self.height_m.abs() / TRANSIT_CLIMB_M_S
    }
}

/// Smallest distance from the origin (the leader vehicle, in its own pattern frame) of a
/// follower going `a → b` on `climb`'s layer: up from `a`, along the lifted straight line,
/// down onto `b`, sampled.
fn clearance_from_origin(a: Ned, b: Ned, climb: Option<&Climb>) -> f64 {
    let up = Ned::new(0.0, 0.0, -climb.map_or(0.0, |c| c.height_m));
    let at = |k: u32| f64::from(k) / 100.0;
    let rise = (0..=100).map(|k| a + up * at(k));
    let line = (0..=100).map(|k| a + (b - a) * at(k) + up);
    let fall = (0..=100).map(|k| b + up * at(k));
    rise.chain(line)
        .chain(fall)
        .map(|p| p.norm())
        .fold(f64::INFINITY, f64::min)
}

/// Path length of a transition leg for the time scale: horizontal metres, or vertical
/// metres scaled to the slower vertical speed.
fn leg_length(d: Ned) -> f64 {
    d.horizontal_norm()
        .max(d.down_m.abs() * TRANSIT_SPEED_M_S / TRANSIT_CLIMB_M_S)
}
/// Distance slots keep inside the geofence, for the vehicles' tracking error, metres.
pub const FENCE_BUFFER_M: f64 = 2.0;
/// Speed at which a reference outside the (shrunk) fence flies back in, m/s.
pub const RETURN_SPEED_M_S: f64 = 2.0;
/// Distance to a go-to point or waypoint that counts as reached, metres.
const REACHED_M: f64 = 0.5;

/// The formation's reference point and its motion.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Reference {
    /// Position, swarm-frame NED.
    pub position: Ned,
    /// Velocity, m/s.
    pub velocity: Ned,
    /// Direction of travel (or the last one), radians clockwise from north.
    pub heading_rad: f64,
    /// Rate of change of the heading, rad/s (turning formations add `ω × offset` to the
    /// slots' velocity feed-forward).
    pub heading_rate_rad_s: f64,
    /// What it is doing.
    pub motion: LeaderMotion,
}

impl Reference {
    fn at(position: Ned, heading_rad: f64) -> Self {
        Reference {
            position,
            velocity: Ned::ZERO,
            heading_rad,
            heading_rate_rad_s: 0.0,
            motion: LeaderMotion::Hold,
        }
    }

    /// Advances the reference by `dt_s`, inside `fence` (the geofence shrunk by the
    /// pattern's reach, so that every slot is inside the geofence): go-to and waypoint
    /// targets are clamped into it so the reference brakes before its edge, and a
    /// reference outside it (the pattern grew) flies back in at [`RETURN_SPEED_M_S`]
    /// rather than jumping.
    pub fn step(&mut self, dt_s: f64, fence: &Geofence) {
        self.step_paced(dt_s, fence, 1.0);
    }

    /// [`Reference::step`] at `pace` (0 to 1) of the motion's speed; the return into
    /// the fence is not slowed.
    pub fn step_paced(&mut self, dt_s: f64, fence: &Geofence, pace: f64) {
        let (inside, outside) = fence.clamp(self.position, true);
        let pace = pace.clamp(0.0, 1.0);
        let desired = match &mut self.motion {
            _ if outside.is_some() => approach(self.position, inside, RETURN_SPEED_M_S),
            LeaderMotion::Hold => Ned::ZERO,
            LeaderMotion::GoTo { target, speed_m_s } => {
                approach(self.position, fence.clamp(*target, true).0, *speed_m_s)
            }
            LeaderMotion::Waypoints {
                points,
                speed_m_s,
                next,
                repeat,
            } => {
                // Intermediate points are passed at speed: switch to the next one as soon
                // as it is within the distance needed to turn onto it.
                let last = *next + 1 >= points.len() && !*repeat;
                let turn_m =
                    (*speed_m_s * *speed_m_s / (2.0 * REFERENCE_ACCEL_M_S2)).max(REACHED_M);
                if let Some(p) = points.get(*next).copied() {
                    let reach = if last { REACHED_M } else { turn_m };
                    if (p - self.position).norm() < reach && !last {
                        *next += 1;
                        if *next >= points.len() {
                            *next = 0;
                        }
                    }
                }
                let target = points
                    .get(*next)
                    .copied()
                    .unwrap_or(*points.last().expect("validated non-empty"));
                let target = fence.clamp(target, true).0;
                let intermediate = *next + 1 < points.len() || *repeat;
                if intermediate {
                    let d = target - self.position;
                    if d.norm() < 1e-6 {
                        Ned::ZERO
                    } else {
                        d * (*speed_m_s / d.norm())
                    }
                } else {
                    approach(self.position, target, *speed_m_s)
                }
            }
            LeaderMotion::Orbit {
                centre,
                radius_m,
                speed_m_s,
                clockwise,
            } => {
                // Tangential speed plus a radial correction onto the circle.
                let rel = Ned::new(
                    self.position.north_m - centre.north_m,
                    self.position.east_m - centre.east_m,
                    0.0,
                );
                let r = rel.horizontal_norm().max(1e-6);
                let radial = rel * (1.0 / r);
                let sign = if *clockwise { 1.0 } else { -1.0 };
                let tangent = Ned::new(-radial.east_m, radial.north_m, 0.0) * sign;
                let mut v = tangent * *speed_m_s + radial * ((*radius_m - r).clamp(-3.0, 3.0));
                v.down_m = (centre.down_m - self.position.down_m).clamp(-2.0, 2.0);
                v
            }
        };
        let desired = if outside.is_some() {
            desired
        } else {
            desired * pace
        };
        let dv = desired - self.velocity;
        let dv = dv.clamped_norm(REFERENCE_ACCEL_M_S2 * dt_s);
        self.velocity = self.velocity + dv;
        self.position = self.position + self.velocity * dt_s;
        let before = self.heading_rad;
        if self.velocity.horizontal_norm() > 0.5 {
            self.heading_rad = self.velocity.east_m.atan2(self.velocity.north_m);
        }
        self.heading_rate_rad_s = if dt_s > 0.0 {
            wrap_pi(self.heading_rad - before) / dt_s
        } else {
            0.0
        };
    }
}

/// Velocity toward `target` at up to `speed`, slowing over the last metres.
fn approach(from: Ned, target: Ned, speed_m_s: f64) -> Ned {
    let d = target - from;
    let dist = d.norm();
    if dist < 1e-6 {
        return Ned::ZERO;
    }
    // v = sqrt(2·a·d) stops in time with the reference's acceleration limit.
    let v = speed_m_s.min((2.0 * REFERENCE_ACCEL_M_S2 * dist).sqrt());
    d * (v / dist)
}

/// What the engine needs to know of a member each tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Member {
    /// Position, swarm frame.
    pub position: Ned,
    /// Velocity, m/s.
    pub velocity: Ned,
    /// Heading, radians clockwise from north.
    pub heading_rad: f64,
    /// Time since its last message.
    pub silence: Duration,
    /// Where skein currently holds it (for anchoring a new leader), if anywhere.
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
    /// is flown, its slot otherwise.
    pub position: Ned,
    /// The slot itself, swarm frame.
    pub goal: Ned,
    /// Slot velocity (feed-forward), m/s.
    pub velocity: Ned,
    /// Heading to hold, radians clockwise from north.
    pub yaw_rad: f64,
}

/// One member's place.
#[derive(Debug, Clone, PartialEq, Serialize)]
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

/// A change of leader.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LeaderChange {
    /// The previous leader (`"virtual"` or a vehicle id), if any.
    pub from: Option<String>,
    /// The new one.
    pub to: String,
    /// Why.
    pub reason: String,
}

/// The formation as `GET /api/v1/formation` shows it.
#[derive(Debug, Clone, PartialEq, Serialize)]
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
}

/// Formation state between ticks.
#[derive(Debug)]
pub struct FormationEngine {
    spec: Option<FormationSpec>,
    active: bool,
    leader: Option<String>,
    reference: Option<Reference>,
    assignment: BTreeMap<String, usize>,
    last: Vec<MemberStatus>,
    changes: Vec<LeaderChange>,
    transition: Option<Transition>,
    /// Where each member was sent at the last tick: its offset from the anchor (swarm
    /// frame axes, i.e. already turned by the heading of that tick).
    commanded: BTreeMap<String, Ned>,
    /// Where each member was sent at the last tick and how fast that place moved, swarm
    /// frame (metres, m/s), for the pace of the formation.
    sent: BTreeMap<String, (Ned, Ned)>,
    /// Heading of the slot pattern at the last tick, radians.
    pattern_heading: Option<f64>,
    /// Its rate of turn, rad/s.
    pattern_rate: f64,
    /// A formation requested during a transition, applied when it ends.
    pending: Option<FormationSpec>,
    /// The last tick put `pending` in force.
    pending_applied: bool,
    /// Distance followers keep from a leader vehicle on their transition paths, metres.
    separation_m: f64,
}

impl Default for FormationEngine {
    fn default() -> Self {
        FormationEngine {
            spec: None,
            active: false,
            leader: None,
            reference: None,
            assignment: BTreeMap::new(),
            last: Vec::new(),
            changes: Vec::new(),
            transition: None,
            commanded: BTreeMap::new(),
            sent: BTreeMap::new(),
            pattern_heading: None,
            pattern_rate: 0.0,
            pending: None,
            pending_applied: false,
            separation_m: DEFAULT_SEPARATION_M,
        }
    }
}

impl FormationEngine {
    /// An engine whose transitions keep followers `separation_m` from a leader vehicle
    /// (the swarm's setpoint separation).
    pub fn new(separation_m: f64) -> Self {
        FormationEngine {
            separation_m,
            ..FormationEngine::default()
        }
    }

    /// The spec in force.
    pub fn spec(&self) -> Option<&FormationSpec> {
        self.spec.as_ref()
    }

    /// True while the formation is flown.
    pub fn is_active(&self) -> bool {
        self.active && self.spec.is_some()
    }

    /// The leader in force (vehicle id or `"virtual"`).
    pub fn leader(&self) -> Option<&str> {
        self.leader.as_deref()
    }

    /// Sets a new formation. The reference point stays where it is (a shape change in
    /// flight reshapes around the same point) unless there is none yet. While a change is
    /// being flown, the new one waits for it to end (the latest request wins): the
    /// separation the transition keeps holds between settled formations.
    pub fn set(&mut self, spec: FormationSpec) {
        if self.active && self.transition.is_some() {
            self.pending = Some(spec);
            return;
        }
        self.apply(spec);
    }

    fn apply(&mut self, spec: FormationSpec) {
        let leader_changes = self
            .spec
            .as_ref()
            .is_none_or(|old| old.leader != spec.leader);
        if leader_changes {
            self.leader = None;
            self.reference = None;
        }
        self.spec = Some(spec);
        self.active = true;
        self.pending = None;
        self.assignment.clear();
    }

    /// The formation waiting for the change in flight to end, if any.
    pub fn pending(&self) -> Option<&FormationSpec> {
        self.pending.as_ref()
    }

    /// Stops flying the formation (the spec is kept for the next `set`).
    pub fn deactivate(&mut self) {
        self.active = false;
        self.leader = None;
        self.reference = None;
        self.assignment.clear();
        self.last.clear();
        self.transition = None;
        self.commanded.clear();
        self.sent.clear();
        self.pattern_heading = None;
        self.pattern_rate = 0.0;
        self.pending = None;
    }

    /// Gives the reference point a new motion (leader go-to, waypoints, orbit).
    ///
    /// # Errors
    /// When no formation is flown yet.
    pub fn set_motion(&mut self, motion: LeaderMotion) -> Result<(), String> {
        match self.reference.as_mut().filter(|_| self.active) {
            Some(r) => {
                r.motion = motion;
                Ok(())
            }
            None => Err("no formation is being flown: PUT /api/v1/formation first".into()),
        }
    }

    /// Leader changes since the last call (for the event stream).
    pub fn take_leader_changes(&mut self) -> Vec<LeaderChange> {
        std::mem::take(&mut self.changes)
    }

    /// True once after a tick that put a pending formation (requested during a
    /// transition) in force (for the event stream).
    pub fn take_pending_applied(&mut self) -> bool {
        std::mem::take(&mut self.pending_applied)
    }

    /// The member nearest to `to`, by id.
    fn nearest(members: &BTreeMap<String, Member>, to: Ned) -> Option<String> {
        members
            .iter()
            .min_by(|a, b| {
                (a.1.position - to)
                    .norm_squared()
                    .total_cmp(&(b.1.position - to).norm_squared())
            })
            .map(|(id, _)| id.clone())
    }

    fn resolve_leader(
        &mut self,
        spec: &FormationSpec,
        members: &BTreeMap<String, Member>,
    ) -> Option<String> {
        if spec.wants_virtual() {
            return Some(VIRTUAL.to_string());
        }
        let healthy = |id: &str| members.get(id).is_some_and(|m| m.silence < LEADER_SILENCE);
        let current = self.leader.clone().filter(|l| l != VIRTUAL);
        if let Some(l) = &current
            && healthy(l)
        {
            return current;
        }
        let wanted = spec.leader.clone().filter(|l| healthy(l));
        let healthy_members: BTreeMap<String, Member> = members
            .iter()
            .filter(|(_, m)| m.silence < LEADER_SILENCE)
            .map(|(k, v)| (k.clone(), *v))
            .collect();
        let (new, reason) = match (&current, wanted) {
            (None, Some(w)) => (Some(w), "requested leader".to_string()),
            (None, None) if spec.leader.is_none() => (
                healthy_members.keys().next().cloned(),
                "first member".to_string(),
            ),
            (previous, _) => {
                // Failover: the member nearest to where the leader was.
                let near = self.reference.as_ref().map(|r| r.position).or_else(|| {
                    spec.leader
                        .as_ref()
                        .and_then(|l| members.get(l))
                        .map(|m| m.position)
                });
                let pick = match near {
                    Some(p) => Self::nearest(&healthy_members, p),
                    None => healthy_members.keys().next().cloned(),
                };
                let why = match previous {
                    Some(p) if members.contains_key(p) => {
                        format!("leader {p} silent for {} ms", LEADER_SILENCE.as_millis())
                    }
                    Some(p) => format!("leader {p} left the formation"),
                    None => format!(
                        "requested leader {} is not in the formation",
                        spec.leader.as_deref().unwrap_or("?")
                    ),
                };
                (pick, why)
            }
        };
        if let Some(n) = &new
            && self.leader.as_ref() != Some(n)
        {
            self.changes.push(LeaderChange {
                from: self.leader.clone(),
                to: n.clone(),
                reason,
            });
        }
        new
    }

    /// Computes this tick's slot for every member. `members` are the vehicles flying the
    /// formation (healthy or not); `dt_s` is the time since the last tick; `fence` bounds
    /// the reference point.
    pub fn tick(
        &mut self,
        members: &BTreeMap<String, Member>,
        dt_s: f64,
        fence: &Geofence,
    ) -> BTreeMap<String, SlotCommand> {
        let mut out = BTreeMap::new();
        if self.transition.is_none()
            && let Some(next) = self.pending.take()
        {
            self.apply(next);
            self.pending_applied = true;
        }
        let Some(spec) = self.spec.clone().filter(|_| self.active) else {
            return out;
        };
        // Silent members keep no slot (they would hold the others' assignment hostage).
        let live: BTreeMap<String, Member> = members
            .iter()
            .filter(|(_, m)| m.silence < LEADER_SILENCE)
            .map(|(k, v)| (k.clone(), *v))
            .collect();
        if live.is_empty() {
            self.last.clear();
            return out;
        }
        let leader = self.resolve_leader(&spec, members);
        let Some(leader) = leader else {
            self.last.clear();
            return out;
        };
        if self.leader.as_ref() != Some(&leader) {
            let failover = self.leader.as_ref().is_some_and(|l| l != VIRTUAL);
            self.leader = Some(leader.clone());
            self.assignment.clear();
            // Offsets from the old anchor mean nothing around the new one.
            self.commanded.clear();
            self.sent.clear();
            // A new leader vehicle takes the formation from where it is: the old leader's
            // spot may still be occupied (a silent vehicle may hover on there).
            if failover
                && leader != VIRTUAL
                && let (Some(r), Some(m)) = (self.reference.as_mut(), live.get(&leader))
            {
                let mut p = m.target.unwrap_or(m.position);
                p.down_m = r.position.down_m;
                r.position = p;
            }
        }
        let virtual_leader = leader == VIRTUAL;
        let capacity = spec.capacity(live.len());
        let offsets = spec.offsets(capacity);
        // The reference point: created where the leader is held (or the members' centroid
        // for a virtual leader), at the formation altitude.
        let reference = self.reference.get_or_insert_with(|| {
            let mut p = if virtual_leader {
                let n = live.len() as f64;
                live.values().fold(Ned::ZERO, |a, m| a + m.position) * (1.0 / n)
            } else {
                let m = &live[&leader];
                m.target.unwrap_or(m.position)
            };
            if let Some(alt) = spec.altitude_m {
                p.down_m = -alt;
            }
            Reference::at(p, spec.heading_deg.to_radians())
        });
        // The reference stays far enough inside the fence for every slot to be inside, and
        // every place on a transition in flight or about to start: paths are straight
        // between start and goal (plus a climb), so their ends bound their reach.
        let mut extents: Vec<Ned> = offsets.clone();
        extents.extend(self.commanded.values().copied());
        if let Some(t) = &self.transition {
            for (id, start) in &t.starts {
                let up = Ned::new(0.0, 0.0, -t.climbs.get(id).map_or(0.0, |c| c.height_m));
                extents.push(*start);
                extents.push(*start + up);
                if let Some(goal) = t.goals.get(id) {
                    extents.push(*goal);
                    extents.push(*goal + up);
                }
            }
        }
        let reach_h = extents
            .iter()
            .map(|o| o.horizontal_norm())
            .fold(0.0, f64::max);
        let reach_up = extents.iter().map(|o| -o.down_m).fold(0.0, f64::max);
        let reach_down = extents.iter().map(|o| o.down_m).fold(0.0, f64::max);
        let inner = Geofence {
            radius_m: (fence.radius_m - reach_h - FENCE_BUFFER_M).max(0.0),
            max_altitude_m: (fence.max_altitude_m - reach_up - FENCE_BUFFER_M)
                .max(fence.min_altitude_m),
            min_altitude_m: (fence.min_altitude_m + reach_down + FENCE_BUFFER_M)
                .min(fence.max_altitude_m),
            polygon: fence.polygon.clone(),
        };
        // The pace: how far the farthest member is from where it was sent (extrapolated
        // to now), against PACE_SLOW_M … PACE_STOP_M.
        let behind = self
            .sent
            .iter()
            .filter_map(|(id, (p, v))| Some((live.get(id)?.position - (*p + *v * dt_s)).norm()))
            .fold(0.0, f64::max);
        let pace = ((PACE_STOP_M - behind) / (PACE_STOP_M - PACE_SLOW_M)).clamp(0.0, 1.0);
        reference.step_paced(dt_s, &inner, pace);
        let reference = reference.clone();
        // Anchor and heading of the slot pattern.
        let (anchor, anchor_velocity, wanted_heading) = if virtual_leader {
            let h = match spec.frame {
                FormationFrame::World => spec.heading_deg.to_radians(),
                FormationFrame::Leader => reference.heading_rad,
            };
            (reference.position, reference.velocity, h)
        } else {
            let m = &live[&leader];
            let h = match spec.frame {
                FormationFrame::World => spec.heading_deg.to_radians(),
                FormationFrame::Leader => m.heading_rad,
            };
            let mut a = m.position;
            // Followers keep the formation altitude, not the leader's transient one.
            a.down_m = reference.position.down_m;
            (a, m.velocity, h)
        };
        // A `leader`-frame pattern turns as a rigid body, its outermost slot at no more
        // than TURN_SPEED_M_S (the leader's heading may jump, e.g. when it sets off); a
        // `world` heading changes only with the spec, and the transition covers that.
        let (heading, heading_rate) = match (spec.frame, self.pattern_heading) {
            (FormationFrame::Leader, Some(h)) if dt_s > 0.0 => {
                let reach = offsets
                    .iter()
                    .map(|o| o.horizontal_norm())
                    .fold(1.0, f64::max);
                let (max_rate, max_accel) =
                    (pace * TURN_SPEED_M_S / reach, TURN_ACCEL_M_S2 / reach);
                let error = wrap_pi(wanted_heading - h);
                // Turn rate that still stops on the wanted heading, then the change of
                // rate the angular acceleration allows.
                let wanted_rate =
                    error.signum() * max_rate.min((2.0 * max_accel * error.abs()).sqrt());
                let rate = self.pattern_rate
                    + (wanted_rate - self.pattern_rate).clamp(-max_accel * dt_s, max_accel * dt_s);
                let step = rate * dt_s;
                let (h, rate) = if step.abs() >= error.abs() && wanted_rate.abs() < max_accel * dt_s
                {
                    (wanted_heading, 0.0)
                } else {
                    (wrap_pi(h + step), rate)
                };
                (h, rate)
            }
            _ => (wanted_heading, 0.0),
        };
        self.pattern_rate = heading_rate;
        self.pattern_heading = Some(heading);
        let slots = slot_positions(&offsets, anchor, heading);
        // The pattern frame: offsets from the anchor, before turning by the heading.
        let to_pattern = |p: Ned| (p - anchor).rotated_yaw(-heading);
        if let Some(t) = self.transition.as_mut() {
            // How far the slowest member is behind its place on the plan.
            let lag = t
                .starts
                .keys()
                .filter_map(|id| {
                    let (offset, _) = t.planned(id)?;
                    Some((live.get(id)?.position - (anchor + offset.rotated_yaw(heading))).norm())
                })
                .fold(0.0, f64::max);
            t.scale = ((LAG_STOP_M - lag) / (LAG_STOP_M - LAG_SLOW_M)).clamp(0.0, 1.0);
            t.elapsed_s += dt_s * t.scale;
        }

        // Assignment when the shape, leader or membership changed, then a transition.
        let membership_changed = self.assignment.len() != capacity
            || self.assignment.keys().any(|k| !live.contains_key(k));
        if membership_changed {
            self.assignment.clear();
            // Where each member starts: where it was being sent (its slot, or its place on
            // the plan in flight: the plan is what keeps the separation), relative to the
            // anchor so that a moving formation does not jump; a newcomer from where it is.
            self.transition = None;
            let commanded = &self.commanded;
            let start_of = |id: &str| -> Ned {
                commanded
                    .get(id)
                    .map(|arm| arm.rotated_yaw(-heading))
                    .unwrap_or_else(|| to_pattern(live[id].position))
            };
            let mut ids: Vec<&String> = live.keys().collect();
            let first_follower_slot = if virtual_leader {
                0
            } else {
                self.assignment.insert(leader.clone(), 0);
                ids.retain(|id| **id != leader);
                1
            };
            // Beyond capacity (custom shapes): the members farthest from every slot wait.
            let free = &offsets[first_follower_slot..];
            let mut candidates: Vec<(&String, Ned)> =
                ids.iter().map(|id| (*id, start_of(id))).collect();
            if candidates.len() > free.len() {
                candidates.sort_by(|a, b| {
                    let da = free
                        .iter()
                        .map(|s| (a.1 - *s).norm_squared())
                        .fold(f64::MAX, f64::min);
                    let db = free
                        .iter()
                        .map(|s| (b.1 - *s).norm_squared())
                        .fold(f64::MAX, f64::min);
                    da.total_cmp(&db)
                });
                candidates.truncate(free.len());
            }
            let starts: Vec<Ned> = candidates.iter().map(|(_, p)| *p).collect();
            let assignment = assign_slots(&starts, free);
            let mut transition = Transition {
                starts: BTreeMap::new(),
                goals: BTreeMap::new(),
                length_m: 0.0,
                elapsed_s: 0.0,
                scale: 1.0,
                climbs: BTreeMap::new(),
                hold_s: 0.0,
            };
            for ((id, start), slot) in candidates.iter().zip(assignment) {
                let slot = slot + first_follower_slot;
                self.assignment.insert((*id).clone(), slot);
                let goal = offsets[slot];
                transition.length_m = transition.length_m.max(leg_length(goal - *start));
                // The assignment's ordering argument does not cover the leader vehicle (it
                // keeps slot 0): a follower whose straight path would pass it flies on a
                // layer above (or below) it, reached before anyone moves horizontally and
                // left after everyone arrived (see `Transition`).
                if !virtual_leader && clearance_from_origin(*start, goal, None) < self.separation_m
                {
                    let climb = Climb::over_origin(*start, goal, self.separation_m);
                    transition.hold_s = transition.hold_s.max(climb.hold_s());
                    transition.climbs.insert((*id).clone(), climb);
                }
                transition.starts.insert((*id).clone(), *start);
                transition.goals.insert((*id).clone(), goal);
            }
            self.transition = Some(transition);
        }

        self.last.clear();
        self.commanded.clear();
        self.sent.clear();
        let spin = |arm: Ned| {
            // Rotation of the pattern: ω × r, with ω about the down axis.
            Ned::new(-heading_rate * arm.east_m, heading_rate * arm.north_m, 0.0)
        };
        for (id, &slot) in &self.assignment {
            let is_leader_vehicle = !virtual_leader && *id == leader;
            let planned = self.transition.as_ref().and_then(|t| t.planned(id));
            let (position, velocity) = if is_leader_vehicle {
                // The leader vehicle flies the reference point itself.
                (reference.position, reference.velocity)
            } else if let Some((offset, rate)) = planned {
                let arm = offset.rotated_yaw(heading);
                self.commanded.insert(id.clone(), arm);
                (
                    anchor + arm,
                    anchor_velocity + rate.rotated_yaw(heading) + spin(arm),
                )
            } else {
                let arm = slots[slot] - anchor;
                self.commanded.insert(id.clone(), arm);
                (slots[slot], anchor_velocity + spin(arm))
            };
            // The slot itself: errors are measured to it, not to the transition's plan.
            let goal = if is_leader_vehicle {
                position
            } else {
                slots[slot]
            };
            self.sent.insert(id.clone(), (position, velocity));
            out.insert(
                id.clone(),
                SlotCommand {
                    slot,
                    leader: is_leader_vehicle,
                    position,
                    goal,
                    velocity,
                    yaw_rad: heading,
                },
            );
            if let Some(m) = members.get(id) {
                self.last.push(MemberStatus {
                    id: id.clone(),
                    slot,
                    target: goal,
                    error_m: (m.position - goal).norm(),
                });
            }
        }
        if self.transition.as_ref().is_some_and(Transition::done) {
            self.transition = None;
        }
        self.last.sort_by_key(|m| m.slot);
        out
    }

    /// The status of the last tick. `airborne` are the positions of all airborne vehicles
    /// (for the separation metric).
    pub fn status(&self, airborne: &[Ned]) -> FormationStatus {
        let rms = (!self.last.is_empty()).then(|| {
            (self.last.iter().map(|m| m.error_m * m.error_m).sum::<f64>() / self.last.len() as f64)
                .sqrt()
        });
        let mut min_sep: Option<f64> = None;
        for (i, a) in airborne.iter().enumerate() {
            for b in &airborne[i + 1..] {
                let d = (*a - *b).norm();
                min_sep = Some(min_sep.map_or(d, |m| m.min(d)));
            }
        }
        FormationStatus {
            spec: self.spec.clone(),
            active: self.is_active(),
            leader_id: self.leader.clone(),
            reference: self.reference.clone().filter(|_| self.is_active()),
            members: self.last.clone(),
            rms_error_m: rms,
            min_separation_m: min_sep,
            transition_progress: self.transition.as_ref().map(|t| t.progress().0),
            pending: self.pending.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> FormationSpec {
        FormationSpec {
            shape: Shape::Line,
            spacing_m: 5.0,
            leader: Some("uav-2".into()),
            heading_deg: 0.0,
            altitude_m: None,
            frame: FormationFrame::World,
            offsets: vec![],
        }
    }

    fn member(n: f64, e: f64, d: f64) -> Member {
        Member {
            position: Ned::new(n, e, d),
            velocity: Ned::ZERO,
            heading_rad: 0.0,
            silence: Duration::ZERO,
            target: None,
        }
    }

    fn fence() -> Geofence {
        Geofence::default()
    }

    #[test]
    fn line_around_the_leader_with_nearest_assignment() {
        let mut e = FormationEngine::default();
        e.set(spec());
        let mut members = BTreeMap::new();
        members.insert("uav-1".to_string(), member(0.0, -3.0, -10.0));
        members.insert("uav-2".to_string(), member(0.0, 0.0, -10.0));
        members.insert("uav-3".to_string(), member(0.0, 3.0, -10.0));
        let slots = e.tick(&members, 0.1, &fence());
        assert_eq!(slots["uav-2"].slot, 0);
        assert!(slots["uav-2"].leader);
        assert!((slots["uav-1"].goal - Ned::new(0.0, -5.0, -10.0)).norm() < 1e-9);
        assert!((slots["uav-3"].goal - Ned::new(0.0, 5.0, -10.0)).norm() < 1e-9);
        // The transition to the slots starts where the members are.
        assert!((slots["uav-1"].position - Ned::new(0.0, -3.0, -10.0)).norm() < 1e-9);
        let positions: Vec<Ned> = members.values().map(|m| m.position).collect();
        let st = e.status(&positions);
        assert_eq!(st.leader_id.as_deref(), Some("uav-2"));
        assert!((st.rms_error_m.unwrap() - (8.0f64 / 3.0).sqrt()).abs() < 1e-9);
        assert!((st.min_separation_m.unwrap() - 3.0).abs() < 1e-9);
    }

    #[test]
    fn the_leaders_hold_target_anchors_the_formation() {
        let mut e = FormationEngine::default();
        e.set(FormationSpec {
            leader: None,
            ..spec()
        });
        let mut members = BTreeMap::new();
        let mut a = member(0.0, 0.0, -9.6);
        a.target = Some(Ned::new(0.0, 0.0, -10.0));
        members.insert("a".to_string(), a);
        members.insert("b".to_string(), member(0.0, 4.0, -9.6));
        let slots = e.tick(&members, 0.1, &fence());
        assert_eq!(slots["a"].position, Ned::new(0.0, 0.0, -10.0));
        // Followers anchor on the leader's measured position, at the formation altitude.
        assert!((slots["b"].goal - Ned::new(0.0, 5.0, -10.0)).norm() < 1e-9);
    }

    #[test]
    fn a_silent_leader_is_replaced_by_the_nearest_member() {
        let mut e = FormationEngine::default();
        e.set(spec());
        let mut members = BTreeMap::new();
        members.insert("uav-1".to_string(), member(0.0, -5.0, -10.0));
        members.insert("uav-2".to_string(), member(0.0, 0.0, -10.0));
        members.insert("uav-3".to_string(), member(0.0, 12.0, -10.0));
        e.tick(&members, 0.1, &fence());
        assert_eq!(e.take_leader_changes()[0].to, "uav-2");
        members.get_mut("uav-2").unwrap().silence = Duration::from_secs(2);
        let slots = e.tick(&members, 0.1, &fence());
        let change = e.take_leader_changes();
        assert_eq!(change.len(), 1);
        assert_eq!(
            (change[0].from.as_deref(), change[0].to.as_str()),
            (Some("uav-2"), "uav-1")
        );
        assert!(change[0].reason.contains("silent"), "{change:?}");
        assert_eq!(slots["uav-1"].slot, 0);
        assert!(
            !slots.contains_key("uav-2"),
            "a silent member keeps no slot"
        );
        assert_eq!(slots.len(), 2);
        // The formation re-anchors on the new leader, not on the silent one's spot.
        assert!((slots["uav-1"].position - Ned::new(0.0, -5.0, -10.0)).norm() < 1e-9);
        assert!((slots["uav-3"].goal - Ned::new(0.0, 0.0, -10.0)).norm() < 1e-9);
    }

    #[test]
    fn a_virtual_leader_moves_the_whole_formation() {
        let mut e = FormationEngine::default();
        e.set(FormationSpec {
            leader: Some(VIRTUAL.into()),
            altitude_m: Some(10.0),
            frame: FormationFrame::Leader,
            ..spec()
        });
        let mut members = BTreeMap::new();
        members.insert("a".to_string(), member(0.0, -5.0, -10.0));
        members.insert("b".to_string(), member(0.0, 5.0, -10.0));
        e.tick(&members, 0.1, &fence());
        e.set_motion(LeaderMotion::GoTo {
            target: Ned::new(100.0, 0.0, -10.0),
            speed_m_s: 5.0,
        })
        .unwrap();
        // The members track what they are sent perfectly (the pace would stop a
        // formation whose members stay behind).
        let mut fly = |e: &mut FormationEngine| {
            let slots = e.tick(&members, 0.1, &fence());
            for (id, s) in &slots {
                let m = members.get_mut(id).unwrap();
                m.position = s.position + s.velocity * 0.1;
                m.velocity = s.velocity;
            }
            slots
        };
        let mut slots = BTreeMap::new();
        for _ in 0..100 {
            slots = fly(&mut e);
        }
        // After 10 s at up to 5 m/s (accelerating at 2 m/s²): moving north at 5 m/s.
        let r = e.status(&[]).reference.unwrap();
        assert!((r.velocity.north_m - 5.0).abs() < 1e-6, "{r:?}");
        assert!(
            r.position.north_m > 40.0 && r.position.north_m < 50.0,
            "{r:?}"
        );
        for s in slots.values() {
            assert!(
                (s.velocity.north_m - 5.0).abs() < 1e-6,
                "feed-forward {s:?}"
            );
            assert!((s.yaw_rad).abs() < 1e-9);
        }
        assert_eq!(e.leader(), Some(VIRTUAL));
        for _ in 0..300 {
            fly(&mut e);
        }
        let r = e.status(&[]).reference.unwrap();
        assert!(
            (r.position - Ned::new(100.0, 0.0, -10.0)).norm() < 0.1,
            "{r:?}"
        );
    }

    #[test]
    fn a_member_left_behind_stops_the_virtual_leader() {
        let mut e = FormationEngine::default();
        e.set(FormationSpec {
            leader: Some(VIRTUAL.into()),
            altitude_m: Some(10.0),
            ..spec()
        });
        let mut members = BTreeMap::new();
        members.insert("a".to_string(), member(0.0, -5.0, -10.0));
        members.insert("b".to_string(), member(0.0, 5.0, -10.0));
        e.tick(&members, 0.1, &fence());
        e.set_motion(LeaderMotion::GoTo {
            target: Ned::new(100.0, 0.0, -10.0),
            speed_m_s: 5.0,
        })
        .unwrap();
        // The members never move: the reference sets off, then waits for them.
        for _ in 0..200 {
            e.tick(&members, 0.1, &fence());
        }
        let r = e.status(&[]).reference.unwrap();
        assert!(r.velocity.norm() < 1e-6, "{r:?}");
        assert!(
            r.position.north_m > 0.5 && r.position.north_m < PACE_STOP_M + 1.0,
            "{r:?}"
        );
    }

    #[test]
    fn orbit_and_waypoints_keep_their_geometry() {
        let mut r = Reference::at(Ned::new(20.0, 0.0, -10.0), 0.0);
        r.motion = LeaderMotion::Orbit {
            centre: Ned::new(0.0, 0.0, -10.0),
            radius_m: 20.0,
            speed_m_s: 4.0,
            clockwise: true,
        };
        for _ in 0..600 {
            r.step(0.05, &fence());
        }
        assert!((r.position.horizontal_norm() - 20.0).abs() < 0.5, "{r:?}");
        assert!((r.velocity.horizontal_norm() - 4.0).abs() < 0.3, "{r:?}");
        let mut r = Reference::at(Ned::ZERO, 0.0);
        r.motion = LeaderMotion::Waypoints {
            points: vec![Ned::new(10.0, 0.0, 0.0), Ned::new(10.0, 10.0, 0.0)],
            speed_m_s: 3.0,
            next: 0,
            repeat: false,
        };
        for _ in 0..2000 {
            r.step(0.05, &fence());
        }
        assert!(
            (r.position - Ned::new(10.0, 10.0, 0.0)).norm() < 0.5,
            "{r:?}"
        );
    }

    #[test]
    fn custom_shapes_have_a_capacity() {
        let mut e = FormationEngine::default();
        e.set(FormationSpec {
            shape: Shape::Custom,
            leader: Some("a".into()),
            offsets: vec![Ned::new(-5.0, 0.0, 0.0)],
            ..spec()
        });
        let mut members = BTreeMap::new();
        members.insert("a".to_string(), member(0.0, 0.0, -10.0));
        members.insert("b".to_string(), member(-4.0, 0.0, -10.0));
        members.insert("c".to_string(), member(30.0, 30.0, -10.0));
        let slots = e.tick(&members, 0.1, &fence());
        assert_eq!(slots.len(), 2);
        assert_eq!(slots["b"].goal, Ned::new(-5.0, 0.0, -10.0));
        assert!(
            !slots.contains_key("c"),
            "beyond capacity: the farthest waits"
        );
    }

    #[test]
    fn inactive_engine_gives_nothing() {
        let mut e = FormationEngine::default();
        let mut members = BTreeMap::new();
        members.insert("a".to_string(), member(0.0, 0.0, 0.0));
        assert!(e.tick(&members, 0.1, &fence()).is_empty());
        e.set(spec());
        e.deactivate();
        assert!(e.tick(&members, 0.1, &fence()).is_empty());
        assert!(!e.status(&[]).active);
        assert!(e.set_motion(LeaderMotion::Hold).is_err());
    }
}
