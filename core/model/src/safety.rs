//! The checks every setpoint passes before it leaves skein: geofence, speed and
//! acceleration limits, and separation from the other vehicles.
//!
//! The [`SetpointShaper`] is the single gate: the vehicle asks for a *target* (a hold
//! point, a slot, a go-to point) and the shaper produces the setpoint actually streamed,
//! a "carrot" that moves toward the target no faster than the vehicle model allows, is
//! clamped into the [`Geofence`], steers around the other vehicles (see
//! [`SetpointShaper::step`]) and never advances toward one already closer than the minimum
//! separation. The streamed setpoint carries the carrot's velocity as
//! feed-forward, so PX4 tracks a moving target without lag.

use crate::geo::Ned;
pub use crate::geofence::{FenceViolation, Geofence};
pub use crate::obstacles::{Obstacle, ObstacleSource};
use serde::{Deserialize, Serialize};

/// Motion limits of a vehicle model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MotionLimits {
    /// Horizontal speed limit, m/s.
    pub max_speed_m_s: f64,
    /// Climb rate limit, m/s.
    pub max_climb_m_s: f64,
    /// Descent rate limit, m/s.
    pub max_descent_m_s: f64,
    /// Acceleration limit (any direction), m/s².
    pub max_accel_m_s2: f64,
}

impl Default for MotionLimits {
    /// Under PX4's multicopter defaults (`MPC_XY_VEL_MAX` 12 m/s, `MPC_Z_VEL_MAX_UP`
    /// 3 m/s, `MPC_Z_VEL_MAX_DN` 1.5 m/s, `MPC_ACC_HOR` 3 m/s²): a setpoint that
    /// accelerates slower than the vehicle can is followed closely, which keeps the
    /// separation kept between setpoints true between vehicles.
    fn default() -> Self {
        MotionLimits {
            max_speed_m_s: 8.0,
            max_climb_m_s: 3.0,
            max_descent_m_s: 1.5,
            max_accel_m_s2: 2.5,
        }
    }
}

/// A setpoint as it leaves skein: position and velocity feed-forward in the swarm frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ShapedSetpoint {
    /// Position, swarm-frame NED metres.
    pub position: Ned,
    /// Velocity feed-forward, NED m/s.
    pub velocity: Ned,
    /// Yaw, radians clockwise from north.
    pub yaw_rad: f64,
    /// Set when the geofence moved the setpoint.
    pub fence: Option<FenceViolation>,
    /// Set when the separation check held the setpoint back.
    pub separation_hold: bool,
}

/// The gate between a vehicle's target and the setpoint it streams (see module docs).
#[derive(Debug, Clone)]
pub struct SetpointShaper {
    limits: MotionLimits,
    /// The geofence moved [`FENCE_TRACKING_BUFFER_M`] inwards: what setpoints are
    /// clamped into.
    fence: Geofence,
    enforce_floor: bool,
    min_separation_m: f64,
    planned_separation_m: f64,
    carrot: Ned,
    velocity: Ned,
    /// Scratch list of the obstacles near the carrot (kept: no allocation per step).
    near: Vec<Obstacle>,
}

/// Gain from carrot-to-target distance to the carrot's desired speed (1/s): the carrot
/// slows down over the last metres instead of overshooting.
const APPROACH_GAIN_PER_S: f64 = 1.0;
/// Distance setpoints keep inside the geofence for the vehicle's tracking error, metres.
/// The autopilot holds the same fence and takes `GF_ACTION` on the slightest breach: a
/// vehicle sent at 8 m/s straight at the fence overshoots the shaper's stop by about
/// 1.4 m (PX4's position loop, as the simulator replays it), so 2 m keep it inside.
pub const FENCE_TRACKING_BUFFER_M: f64 = 2.0;
/// Fraction of the acceleration limit avoidance counts on for braking (the rest is left
/// for steering around).
pub const BRAKE_FRACTION: f64 = 0.6;
/// Below this speed, m/s, a vehicle counts as standing still (hovering, on station).
pub const STILL_M_S: f64 = 0.3;
/// How much farther than the separation, metres, the straight way from the carrot to a
/// fixed target must pass a vehicle standing still for avoidance to leave it out: the
/// tracking error of the vehicle following the carrot.
pub const CLEAR_PATH_MARGIN_M: f64 = 1.0;
/// The shortest time to a closest approach the sideways slide is sized over, seconds (a
/// control step of 20 Hz and some: a conflict closer than that slides at full speed).
const STEP_FLOOR_S: f64 = 0.1;

impl SetpointShaper {
    /// A shaper whose carrot starts at `start` (the vehicle's current position) at rest.
    pub fn new(start: Ned, limits: MotionLimits, fence: Geofence, min_separation_m: f64) -> Self {
        SetpointShaper {
            limits,
            fence: fence.shrunk(FENCE_TRACKING_BUFFER_M),
            enforce_floor: false,
            min_separation_m,
            planned_separation_m: min_separation_m,
            carrot: start,
            velocity: Ned::ZERO,
            near: Vec::new(),
        }
    }

    /// Sets the inner limit kept from [`Obstacle::planned`] vehicles (metres; at most the
    /// minimum separation): a transition plan keeps members apart by construction, so the
    /// shaper only stops the carrot from closing in below this distance.
    pub fn with_planned_separation(mut self, planned_separation_m: f64) -> Self {
        self.planned_separation_m = planned_separation_m.min(self.min_separation_m);
        self
    }

    /// The current carrot (last position setpoint).
    pub fn carrot(&self) -> Ned {
        self.carrot
    }

    /// Moves the carrot to `p` and stops it (used when a hold point is re-anchored).
    pub fn reset(&mut self, p: Ned) {
        self.carrot = p;
        self.velocity = Ned::ZERO;
    }

    /// Whether the fence's floor applies (airborne phases; not takeoff or landing).
    pub fn enforce_floor(&mut self, on: bool) {
        self.enforce_floor = on;
    }

    /// Clamps into `fence` from now on (moved [`FENCE_TRACKING_BUFFER_M`] inwards, like
    /// the fence given at construction): an operator's new geofence.
    pub fn set_fence(&mut self, fence: &Geofence) {
        self.fence = fence.shrunk(FENCE_TRACKING_BUFFER_M);
    }

    /// Changes the limits (vehicle model change).
    pub fn set_limits(&mut self, limits: MotionLimits, fence: Geofence, min_separation_m: f64) {
        self.limits = limits;
        self.fence = fence.shrunk(FENCE_TRACKING_BUFFER_M);
        self.min_separation_m = min_separation_m;
        self.planned_separation_m = self.planned_separation_m.min(min_separation_m);
    }

    /// Advances the carrot by `dt_s` toward `target` (with the target's own velocity
    /// `target_velocity` as feed-forward), keeping to the speed and acceleration limits, the
    /// geofence, and the minimum separation from `others` (swarm-frame positions of the
    /// other vehicles). Returns the setpoint to stream.
    pub fn step(
        &mut self,
        target: Ned,
        target_velocity: Ned,
        yaw_rad: f64,
        dt_s: f64,
        others: &(impl ObstacleSource + ?Sized),
    ) -> ShapedSetpoint {
        // Setpoints stay a tracking buffer inside the fence (see `fence`), so that the
        // vehicle's own overshoot does not take it out.
        let (target, fence) = self.fence.clamp(target, self.enforce_floor);
        let to_target = target - self.carrot;
        // Approach speed: proportional near the target, and never more than can be braked
        // to zero within the acceleration limit (a linear profile from cruise speed would
        // ask for more deceleration than the vehicle has and arrive fast).
        let dist = to_target.norm();
        let brake = BRAKE_FRACTION * self.limits.max_accel_m_s2;
        let approach = (dist * APPROACH_GAIN_PER_S).min((2.0 * brake * dist).sqrt());
        let mut desired = if dist > 1e-9 {
            target_velocity + to_target * (approach / dist)
        } else {
            target_velocity
        };
        desired = self.limit_speed(desired);
        // The carrot moves at most this far in this step, unless the fence moves it (the
        // margin by which the obstacles found for avoidance also cover the separation
        // check at the next point).
        let step_bound_m = dt_s.max(0.0)
            * self
                .limits
                .max_speed_m_s
                .hypot(self.limits.max_climb_m_s.max(self.limits.max_descent_m_s));
        // A fixed target: the carrot stops there, so a vehicle standing still clear of
        // the way there is no obstacle (braking for it would be braking for a point the
        // carrot never reaches).
        let path_end = (target_velocity.norm() < 1e-9).then_some(target);
        let avoided = self.avoid_near(desired, others, step_bound_m, path_end);
        desired = self.limit_speed(avoided);
        // Never toward a boundary of the fence faster than can be braked on it: a carrot
        // the clamp stops at speed leaves the vehicle's momentum to carry it out.
        desired =
            self.fence
                .braked_toward_boundaries(self.carrot, desired, brake, self.enforce_floor);
        // Acceleration limit on the change of the carrot's velocity.
        let dv = desired - self.velocity;
        let dv = dv.clamped_norm(self.limits.max_accel_m_s2 * dt_s);
        let mut velocity = self.limit_speed(self.velocity + dv);
        let mut next = self.carrot + velocity * dt_s;
        // Never step past the target.
        if to_target.norm() <= (velocity * dt_s).norm() && target_velocity.norm() < 1e-9 {
            next = target;
            velocity = Ned::ZERO;
        }
        let (next, fence_step) = self.fence.clamp(next, self.enforce_floor);
        if fence_step.is_some() && dt_s > 0.0 {
            // Against the fence the feed-forward is what the carrot really does, never a
            // push through it.
            velocity = (next - self.carrot) * (1.0 / dt_s);
        }
        let min = self.min_separation_m.max(self.planned_separation_m);
        let mut near = std::mem::take(&mut self.near);
        // What `avoid_near` found around the carrot holds every obstacle within the
        // separations of any point up to `step_bound_m` away: asked again only when the
        // step went further (the fence moved it).
        let covered = (next - self.carrot).norm() <= step_bound_m;
        if !covered {
            others.near(next, min, self.planned_separation_m, &mut near);
        }
        let separation_hold = self.violates_separation(next, &near);
        self.near = near;
        if separation_hold {
            self.velocity = Ned::ZERO;
        } else {
            self.carrot = next;
            self.velocity = velocity;
        }
        ShapedSetpoint {
            position: self.carrot,
            velocity: self.velocity,
            yaw_rad,
            fence: fence.or(fence_step),
            separation_hold,
        }
    }

    fn limit_speed(&self, v: Ned) -> Ned {
        let mut v = v;
        let h = v.horizontal_norm();
        if h > self.limits.max_speed_m_s {
            let k = self.limits.max_speed_m_s / h;
            v.north_m *= k;
            v.east_m *= k;
        }
        v.down_m = v
            .down_m
            .clamp(-self.limits.max_climb_m_s, self.limits.max_descent_m_s);
        v
    }

    /// Velocity-space avoidance. For every other vehicle, the speed at which the carrot
    /// closes on it (relative to its velocity) is limited to what can still be braked away
    /// before the separation: `sqrt(2·a·(d − d_min))` with `a` a fraction
    /// ([`BRAKE_FRACTION`]) of the acceleration limit, halved when the other vehicle is
    /// steered by skein too (each takes half, as in reciprocal velocity obstacles), unless
    /// the two, as they move, pass farther apart than the separation and
    /// [`CLEAR_PATH_MARGIN_M`] (their closest approach). What is removed is turned into a
    /// sideways velocity (from farther than twice that clearance, no more than opens the
    /// closest approach to it in the time left to it), in the direction the vehicle already slides around the other
    /// one, or to the right when it comes straight at it (the right-hand rule: two
    /// vehicles meeting head-on both veer right and pass; a vehicle behind a stationary
    /// one slides around it instead of stopping).
    ///
    /// A [`Obstacle::planned`] vehicle is left to the formation's transition plan (which
    /// keeps the pair apart by construction; shaping the approach would take the vehicles
    /// off the plan's common time scale): only closing in below the planned separation
    /// is removed.
    ///
    /// A vehicle standing still clear of the way to a fixed target (`path_end`) is left
    /// out ([`SetpointShaper::clear_of_path`]).
    ///
    /// Returns the avoiding velocity and the largest speed it had along the way (what
    /// bounds the closing speed of every obstacle, see [`SetpointShaper::avoid_near`]).
    fn avoid(&self, v: Ned, others: &[Obstacle], path_end: Option<Ned>) -> (Ned, f64) {
        let brake = BRAKE_FRACTION * self.limits.max_accel_m_s2;
        let mut out = v;
        let mut peak = v.norm();
        for o in others {
            if self.clear_of_path(o, path_end) {
                continue;
            }
            let away = self.carrot - o.position;
            let dist = away.norm();
            if dist < 1e-6 {
                continue;
            }
            let n = away * (1.0 / dist);
            let closing = -(out - o.velocity).dot(&n);
            if o.planned {
                if dist < self.planned_separation_m && closing > 0.0 {
                    out = out + n * closing;
                    peak = peak.max(out.norm());
                }
                continue;
            }
            let spare = (dist - self.min_separation_m).max(0.0);
            let share = if o.reciprocal { 0.5 } else { 1.0 };
            let allowed = share * (2.0 * brake * spare).sqrt();
            let excess = closing - allowed;
            let Some(slide) = self.slide(away, out - o.velocity, excess) else {
                continue;
            };
            out = out + n * excess;
            // Sideways, horizontally: keep sliding the way the vehicle already slides
            // around the other one; when it comes straight at it, to the right.
            let h = (n.north_m.powi(2) + n.east_m.powi(2)).sqrt();
            if h > 1e-6 {
                let right = Ned::new(n.east_m / h, -n.north_m / h, 0.0);
                let side = if out.dot(&right) >= -1e-9 {
                    right
                } else {
                    right * -1.0
                };
                out = out + side * slide;
            }
            peak = peak.max(out.norm());
        }
        (out, peak)
    }

    /// How fast to slide sideways around another vehicle `away` from the carrot
    /// (metres, from it to the carrot) at `relative` velocity (m/s) when the closing
    /// speed is `excess` m/s over what can be braked; `None` when no avoidance is needed.
    ///
    /// Close by (within twice the separation and [`CLEAR_PATH_MARGIN_M`], the
    /// clearance), all the excess, whenever there is one. Farther, the closest approach
    /// decides: a vehicle whose way passes clear is no reason to turn, and one that does
    /// not is nudged aside no faster than opens the miss distance to the clearance by
    /// then (a conflict seconds ahead needs a nudge, not a swerve: vehicles on survey
    /// lanes 8 m apart at 8 m/s pushed each other off them, closing in on one ahead on
    /// the next lane 40 m away read as flying at it, and a rehearsal saw a lane flown
    /// 10 m off its line and 5 % of the survey unseen). Close by, velocities still change
    /// too much for either: two vehicles crossing after takeoff, nudged, came 3.15 m
    /// apart.
    fn slide(&self, away: Ned, relative: Ned, excess: f64) -> Option<f64> {
        if excess <= 0.0 {
            return None;
        }
        let clearance = self.min_separation_m + CLEAR_PATH_MARGIN_M;
        if away.norm() <= 2.0 * clearance {
            return Some(excess);
        }
        let (t_s, miss_m) = closest_approach(away, relative);
        (miss_m < clearance).then(|| excess.min((clearance - miss_m) / t_s.max(STEP_FLOOR_S)))
    }

    /// [`SetpointShaper::avoid`] over the obstacles that can matter, asked of `others` by
    /// distance, with the same result as over all of them.
    ///
    /// An obstacle that is not [`Obstacle::planned`] changes the velocity only when the
    /// closing speed exceeds `share · sqrt(2·a·(d − d_min))`, and the closing speed is at
    /// most the velocity's speed plus the obstacle's: beyond [`SetpointShaper::reach_m`]
    /// of that bound it cannot act. A planned one acts only within the planned separation.
    /// The velocity grows as obstacles act, so the bound is checked afterwards: when the
    /// velocity grew past it, the pass is made again over the wider reach (rare: it takes
    /// several obstacles acting at once).
    ///
    /// The obstacles are asked for with `margin_m` more than each separation (the radii
    /// only grow: more obstacles than can act change nothing), and are left in
    /// `self.near`: every obstacle within the separations of a point at most `margin_m`
    /// from the carrot, what [`SetpointShaper::violates_separation`] needs after the step.
    fn avoid_near(
        &mut self,
        v: Ned,
        others: &(impl ObstacleSource + ?Sized),
        margin_m: f64,
        path_end: Option<Ned>,
    ) -> Ned {
        let others_speed = others.max_speed_m_s();
        let mut bound = v.norm();
        let mut near = std::mem::take(&mut self.near);
        let min = self.min_separation_m.max(self.planned_separation_m);
        let out = loop {
            let reach = self.reach_m(bound, others_speed).max(min + margin_m);
            others.near(
                self.carrot,
                reach,
                self.planned_separation_m + margin_m,
                &mut near,
            );
            let (out, peak) = self.avoid(v, &near, path_end);
            if peak <= bound || !peak.is_finite() {
                break out;
            }
            bound = peak;
        };
        self.near = near;
        out
    }

    /// Distance beyond which an obstacle that is not planned cannot change a velocity of
    /// at most `speed_m_s` when no obstacle is faster than `others_speed_m_s` (the closing
    /// speed is then below what can still be braked away, whichever side avoids), metres.
    pub fn reach_m(&self, speed_m_s: f64, others_speed_m_s: f64) -> f64 {
        let brake = BRAKE_FRACTION * self.limits.max_accel_m_s2;
        // share ≥ 1/2: closing ≤ sqrt(2·a·spare)/2  ⇔  spare ≥ 2·closing²/a.
        let closing = speed_m_s + others_speed_m_s;
        let spare = 2.0 * closing * closing / brake.max(1e-9);
        // A little more, for rounding.
        (self.min_separation_m + spare) * 1.001 + 0.01
    }

    /// `o` stands still (slower than [`STILL_M_S`]), is not planned, and the straight way
    /// from the carrot to `path_end` (a fixed target) passes it farther than the
    /// separation and [`CLEAR_PATH_MARGIN_M`]: the carrot, which stops at the target,
    /// never comes near it. A vehicle behind the target, say a neighbour on its own
    /// station, then no longer pushes aside a vehicle flying to the station beside it
    /// (two such pushes from both sides held a vehicle swinging between them for 40 s).
    /// Once it moves, it is an obstacle again.
    fn clear_of_path(&self, o: &Obstacle, path_end: Option<Ned>) -> bool {
        let Some(end) = path_end else {
            return false;
        };
        if o.planned || o.velocity.norm() >= STILL_M_S {
            return false;
        }
        let clearance = self.min_separation_m + CLEAR_PATH_MARGIN_M;
        distance_to_segment(o.position, self.carrot, end) >= clearance
    }

    /// True when moving the carrot to `next` brings it closer to a vehicle that is already
    /// within the minimum separation (moving away is always allowed, so two vehicles that
    /// start too close can still separate).
    fn violates_separation(&self, next: Ned, others: &[Obstacle]) -> bool {
        others.iter().any(|o| {
            let min = if o.planned {
                self.planned_separation_m
            } else {
                self.min_separation_m
            };
            let d_next = (next - o.position).norm_squared();
            d_next < min * min && d_next < (self.carrot - o.position).norm_squared()
        })
    }
}

/// The closest approach of two vehicles `away` apart (metres, from the other to this
/// one) moving at `relative` (this one's velocity less the other's, m/s): in how many
/// seconds (0 when they are not closing) and how far apart, metres.
fn closest_approach(away: Ned, relative: Ned) -> (f64, f64) {
    let speed2 = relative.norm_squared();
    if speed2 < 1e-12 {
        return (0.0, away.norm());
    }
    let t_s = (-away.dot(&relative) / speed2).max(0.0);
    (t_s, (away + relative * t_s).norm())
}

/// Distance from `p` to the segment from `a` to `b`, metres.
fn distance_to_segment(p: Ned, a: Ned, b: Ned) -> f64 {
    let ab = b - a;
    let len2 = ab.norm_squared();
    let t = if len2 > 1e-12 {
        ((p - a).dot(&ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (a + ab * t)).norm()
}

#[cfg(test)]
mod tests;
