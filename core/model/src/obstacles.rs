//! The other vehicles as the separation check sees them: [`Obstacle`], and where the
//! [`crate::safety::SetpointShaper`] asks for the ones near a point ([`ObstacleSource`]).

use crate::geo::Ned;

/// Another vehicle, as the separation check sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Obstacle {
    /// Where it is, or where it is being sent, swarm frame.
    pub position: Ned,
    /// Its velocity, m/s.
    pub velocity: Ned,
    /// True when skein steers it too: it takes half of the avoidance.
    pub reciprocal: bool,
    /// True when both vehicles fly one formation transition plan, which keeps them apart
    /// by construction: the shaper then only guards the inner limit (see
    /// [`SetpointShaper::step`]) instead of shaping the approach.
    pub planned: bool,
}

impl Obstacle {
    /// A vehicle standing still that does not avoid.
    pub fn fixed(position: Ned) -> Self {
        Obstacle {
            position,
            velocity: Ned::ZERO,
            reciprocal: false,
            planned: false,
        }
    }
}

/// Where the other vehicles are, asked by distance: a plain list, or a spatial index of a
/// large swarm (`skein_swarm::neighbours`).
///
/// The shaper asks only for the obstacles that can matter and gets the same setpoint as
/// from the whole list, as long as `near` keeps the list's order.
pub trait ObstacleSource {
    /// Clears `out` and fills it with at least every obstacle within `radius_m` of
    /// `center` (swarm frame, metres), and every [`Obstacle::planned`] one within
    /// `planned_radius_m`, in one fixed order (the order of the full list). Giving more
    /// is harmless (only slower).
    fn near(&self, center: Ned, radius_m: f64, planned_radius_m: f64, out: &mut Vec<Obstacle>);

    /// An upper bound of the speed of every obstacle `near` can give that is not
    /// planned, m/s.
    fn max_speed_m_s(&self) -> f64;
}

impl ObstacleSource for [Obstacle] {
    fn near(&self, center: Ned, radius_m: f64, planned_radius_m: f64, out: &mut Vec<Obstacle>) {
        out.clear();
        out.extend(self.iter().filter(|o| {
            let r = if o.planned {
                planned_radius_m
            } else {
                radius_m
            };
            (o.position - center).norm_squared() <= r * r
        }));
    }

    fn max_speed_m_s(&self) -> f64 {
        self.iter()
            .filter(|o| !o.planned)
            .map(|o| o.velocity.norm())
            .fold(0.0, f64::max)
    }
}

impl<const N: usize> ObstacleSource for [Obstacle; N] {
    fn near(&self, center: Ned, radius_m: f64, planned_radius_m: f64, out: &mut Vec<Obstacle>) {
        self.as_slice()
            .near(center, radius_m, planned_radius_m, out);
    }

    fn max_speed_m_s(&self) -> f64 {
        self.as_slice().max_speed_m_s()
    }
}

impl ObstacleSource for Vec<Obstacle> {
    fn near(&self, center: Ned, radius_m: f64, planned_radius_m: f64, out: &mut Vec<Obstacle>) {
        self.as_slice()
            .near(center, radius_m, planned_radius_m, out);
    }

    fn max_speed_m_s(&self) -> f64 {
        self.as_slice().max_speed_m_s()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::safety::{Geofence, MotionLimits, SetpointShaper};

    /// Every obstacle, whatever the distance: what the shaper saw before it asked by
    /// distance.
    struct Everything(Vec<Obstacle>);

    impl ObstacleSource for Everything {
        fn near(&self, _: Ned, _: f64, _: f64, out: &mut Vec<Obstacle>) {
            out.clear();
            out.extend_from_slice(&self.0);
        }
        fn max_speed_m_s(&self) -> f64 {
            self.0.max_speed_m_s()
        }
    }

    /// A small deterministic generator (no dependency needed for a test's numbers).
    struct Lcg(u64);
    impl Lcg {
        fn unit(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
        fn range(&mut self, a: f64, b: f64) -> f64 {
            a + (b - a) * self.unit()
        }
    }

    #[test]
    fn asking_by_distance_gives_the_setpoints_of_the_whole_list() {
        let mut rng = Lcg(7);
        let mut acted = 0;
        for case in 0..200 {
            // A crowd around the vehicle, some moving fast, some planned.
            let crowd: Vec<Obstacle> = (0..40)
                .map(|_| Obstacle {
                    position: Ned::new(
                        rng.range(-60.0, 60.0),
                        rng.range(-60.0, 60.0),
                        rng.range(-15.0, -5.0),
                    ),
                    velocity: Ned::new(rng.range(-6.0, 6.0), rng.range(-6.0, 6.0), 0.0),
                    reciprocal: rng.unit() < 0.5,
                    planned: rng.unit() < 0.3,
                })
                .collect();
            let start = Ned::new(0.0, 0.0, -10.0);
            let fence = Geofence::default();
            let limits = MotionLimits::default();
            let mut by_distance =
                SetpointShaper::new(start, limits, fence.clone(), 3.5).with_planned_separation(2.0);
            let mut whole = by_distance.clone();
            let mut alone = by_distance.clone();
            let target = Ned::new(rng.range(-80.0, 80.0), rng.range(-80.0, 80.0), -10.0);
            let everything = Everything(crowd.clone());
            for _ in 0..100 {
                let a = by_distance.step(target, Ned::ZERO, 0.0, 0.02, crowd.as_slice());
                let b = whole.step(target, Ned::ZERO, 0.0, 0.02, &everything);
                assert_eq!(a, b, "case {case}");
                alone.step(target, Ned::ZERO, 0.0, 0.02, &[] as &[Obstacle]);
            }
            if (alone.carrot() - by_distance.carrot()).norm() > 1e-6 {
                acted += 1;
            }
        }
        // The crowds were close enough to matter, or the test shows nothing.
        assert!(acted > 50, "obstacles acted in {acted} of 200 cases");
    }
}
