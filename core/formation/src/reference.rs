//! The formation's moving reference point `P(t)` (where slot 0 is): how it holds, goes
//! to a point, follows waypoints or orbits under speed and acceleration limits, stays
//! inside the geofence shrunk by the pattern's reach, and slows down (its *pace*) while
//! members fall behind.

use super::spec::LeaderMotion;
use serde::{Deserialize, Serialize};
use skein_model::geo::{Ned, wrap_pi};
use skein_model::safety::Geofence;

/// Acceleration limit of the reference point, m/s² (under the vehicles' own, so they keep up).
pub(super) const REFERENCE_ACCEL_M_S2: f64 = 1.5;
/// Distance slots keep inside the geofence, for the vehicles' tracking error, metres.
pub const FENCE_BUFFER_M: f64 = 2.0;
/// Speed at which a reference outside the (shrunk) fence flies back in, m/s.
pub const RETURN_SPEED_M_S: f64 = 2.0;
/// Distance to a go-to point or waypoint that counts as reached, metres.
const REACHED_M: f64 = 0.5;
/// A member this far from where it was sent slows the formation's motion (the
/// reference point's speed and a `leader`-frame pattern's turn rate) down…
pub const PACE_SLOW_M: f64 = 1.0;
/// … and this far stops it, so that no member is left behind by a moving or turning
/// pattern (a far-behind member cuts across the others to catch up).
pub const PACE_STOP_M: f64 = 2.5;

/// The formation's reference point and its motion.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
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
    /// A reference holding at `position` (swarm-frame NED), heading `heading_rad`
    /// (radians clockwise from north), at rest.
    pub(super) fn at(position: Ned, heading_rad: f64) -> Self {
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

/// Velocity toward `target` at up to `speed_m_s` (swarm-frame NED, m/s), slowing over
/// the last metres so that it stops on `target` with the reference's acceleration limit.
pub(super) fn approach(from: Ned, target: Ned, speed_m_s: f64) -> Ned {
    let d = target - from;
    let dist = d.norm();
    if dist < 1e-6 {
        return Ned::ZERO;
    }
    // v = sqrt(2·a·d) stops in time with the reference's acceleration limit.
    let v = speed_m_s.min((2.0 * REFERENCE_ACCEL_M_S2 * dist).sqrt());
    d * (v / dist)
}

/// The pace of the formation's motion (0 to 1) when the member farthest from where it
/// was sent is `behind_m` metres off: 1 up to [`PACE_SLOW_M`], 0 from [`PACE_STOP_M`].
pub(super) fn pace(behind_m: f64) -> f64 {
    ((PACE_STOP_M - behind_m) / (PACE_STOP_M - PACE_SLOW_M)).clamp(0.0, 1.0)
}

/// The fence the reference point must stay in so that every place in `extents`
/// (offsets from the reference, swarm-frame NED, metres) stays [`FENCE_BUFFER_M`] inside
/// `fence`: radius less the horizontal reach, ceiling lowered by the upward reach, floor
/// raised by the downward reach (never past each other), the polygon's edges and the
/// exclusion areas kept the horizontal reach away.
pub(super) fn inner_fence(fence: &Geofence, extents: &[Ned]) -> Geofence {
    let reach_h = extents
        .iter()
        .map(|o| o.horizontal_norm())
        .fold(0.0, f64::max);
    let reach_up = extents.iter().map(|o| -o.down_m).fold(0.0, f64::max);
    let reach_down = extents.iter().map(|o| o.down_m).fold(0.0, f64::max);
    Geofence {
        radius_m: (fence.radius_m - reach_h - FENCE_BUFFER_M).max(0.0),
        max_altitude_m: (fence.max_altitude_m - reach_up - FENCE_BUFFER_M)
            .max(fence.min_altitude_m),
        min_altitude_m: (fence.min_altitude_m + reach_down + FENCE_BUFFER_M)
            .min(fence.max_altitude_m),
        area_margin_m: fence.area_margin_m + reach_h + FENCE_BUFFER_M,
        ..fence.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f64 = 0.05;

    fn fence() -> Geofence {
        Geofence::default()
    }

    fn going_to(target: Ned, speed_m_s: f64) -> Reference {
        let mut r = Reference::at(Ned::new(0.0, 0.0, -10.0), 0.0);
        r.motion = LeaderMotion::GoTo { target, speed_m_s };
        r
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
            r.step(DT, &fence());
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
            r.step(DT, &fence());
        }
        assert!(
            (r.position - Ned::new(10.0, 10.0, 0.0)).norm() < 0.5,
            "{r:?}"
        );
    }

    #[test]
    fn go_to_accelerates_to_its_speed_and_never_beyond() {
        let mut r = going_to(Ned::new(200.0, 0.0, -10.0), 5.0);
        // One step: the acceleration limit, not the speed, bounds the change.
        r.step(DT, &fence());
        assert!((r.velocity.north_m - REFERENCE_ACCEL_M_S2 * DT).abs() < 1e-12);
        let mut top = 0.0f64;
        for _ in 0..400 {
            r.step(DT, &fence());
            top = top.max(r.velocity.norm());
        }
        assert!((top - 5.0).abs() < 1e-9, "top speed {top}");
        assert!((r.velocity.north_m - 5.0).abs() < 1e-9, "{r:?}");
        assert_eq!(r.heading_rad, 0.0, "heading north");
        assert_eq!(r.heading_rate_rad_s, 0.0);
    }

    #[test]
    fn go_to_stops_on_its_target() {
        let target = Ned::new(0.0, 30.0, -10.0);
        let mut r = going_to(target, 5.0);
        for _ in 0..1200 {
            r.step(DT, &fence());
        }
        assert!((r.position - target).norm() < 0.05, "{r:?}");
        assert!(r.velocity.norm() < 0.05, "{r:?}");
        // Flying east: heading π/2, kept after it stopped.
        assert!((r.heading_rad - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
    }

    #[test]
    fn a_go_to_outside_the_fence_stops_at_its_edge() {
        let fence = Geofence {
            radius_m: 50.0,
            ..Geofence::default()
        };
        let mut r = going_to(Ned::new(100.0, 0.0, -10.0), 5.0);
        for _ in 0..2000 {
            r.step(DT, &fence);
        }
        assert!((r.position.north_m - 50.0).abs() < 0.05, "{r:?}");
        assert!(r.velocity.norm() < 0.05, "{r:?}");
    }

    #[test]
    fn pace_scales_the_speed_and_zero_stops_it() {
        let mut r = going_to(Ned::new(200.0, 0.0, -10.0), 4.0);
        for _ in 0..200 {
            r.step_paced(DT, &fence(), 0.5);
        }
        assert!((r.velocity.north_m - 2.0).abs() < 1e-9, "{r:?}");
        // Out-of-range paces are clamped.
        for _ in 0..200 {
            r.step_paced(DT, &fence(), 3.0);
        }
        assert!((r.velocity.north_m - 4.0).abs() < 1e-9, "{r:?}");
        for _ in 0..200 {
            r.step_paced(DT, &fence(), 0.0);
        }
        assert_eq!(r.velocity, Ned::ZERO);
        let stopped = r.position;
        r.step_paced(DT, &fence(), -1.0);
        assert_eq!(r.position, stopped);
    }

    #[test]
    fn a_reference_outside_the_fence_flies_back_in_unpaced() {
        let fence = Geofence {
            radius_m: 10.0,
            ..Geofence::default()
        };
        let mut r = Reference::at(Ned::new(20.0, 0.0, -10.0), 0.0);
        for _ in 0..40 {
            // Even at pace 0 (members behind) it returns, at RETURN_SPEED_M_S.
            r.step_paced(DT, &fence, 0.0);
        }
        assert!(
            (r.velocity.north_m + RETURN_SPEED_M_S).abs() < 1e-9,
            "{r:?}"
        );
        assert!(r.position.north_m > 10.0, "still outside: {r:?}");
        for _ in 0..400 {
            r.step_paced(DT, &fence, 0.0);
        }
        assert!((r.position.north_m - 10.0).abs() < 0.05, "{r:?}");
        assert!(r.velocity.norm() < 0.01, "{r:?}");
    }

    #[test]
    fn a_zero_time_step_changes_nothing() {
        let mut r = going_to(Ned::new(100.0, 0.0, -10.0), 5.0);
        let before = r.clone();
        r.step(0.0, &fence());
        assert_eq!(r, before);
    }

    #[test]
    fn approach_brakes_over_the_last_metres() {
        let from = Ned::new(0.0, 0.0, -10.0);
        assert_eq!(approach(from, from, 5.0), Ned::ZERO);
        // Far: the cruise speed, toward the target.
        let v = approach(from, Ned::new(0.0, -100.0, -10.0), 5.0);
        assert!((v - Ned::new(0.0, -5.0, 0.0)).norm() < 1e-12, "{v:?}");
        // 3 m away: sqrt(2 · 1.5 · 3) = 3 m/s.
        let v = approach(from, Ned::new(3.0, 0.0, -10.0), 5.0);
        assert!((v - Ned::new(3.0, 0.0, 0.0)).norm() < 1e-12, "{v:?}");
    }

    #[test]
    fn pace_falls_from_one_to_zero_between_its_limits() {
        assert_eq!(pace(0.0), 1.0);
        assert_eq!(pace(PACE_SLOW_M), 1.0);
        assert!((pace(1.75) - 0.5).abs() < 1e-12);
        assert_eq!(pace(PACE_STOP_M), 0.0);
        assert_eq!(pace(10.0), 0.0);
    }

    #[test]
    fn the_inner_fence_leaves_room_for_the_pattern() {
        let fence = Geofence::default();
        let extents = [
            Ned::new(3.0, 4.0, 0.0),
            Ned::new(0.0, -2.0, -6.0),
            Ned::new(0.0, 0.0, 1.0),
        ];
        let inner = inner_fence(&fence, &extents);
        assert!((inner.radius_m - (500.0 - 5.0 - FENCE_BUFFER_M)).abs() < 1e-12);
        assert!((inner.max_altitude_m - (120.0 - 6.0 - FENCE_BUFFER_M)).abs() < 1e-12);
        assert!((inner.min_altitude_m - (0.0 + 1.0 + FENCE_BUFFER_M)).abs() < 1e-12);
        // A pattern larger than the fence: radius 0, ceiling and floor meet.
        let tiny = Geofence {
            radius_m: 5.0,
            max_altitude_m: 4.0,
            min_altitude_m: 2.0,
            ..Geofence::default()
        };
        let inner = inner_fence(&tiny, &extents);
        assert_eq!(inner.radius_m, 0.0);
        assert_eq!(inner.max_altitude_m, 2.0);
        assert_eq!(inner.min_altitude_m, 4.0);
    }
}
