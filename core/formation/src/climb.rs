//! The layers of a transition: a follower whose straight path would pass a leader
//! vehicle (which keeps slot 0, outside the assignment's separation argument) or a hazard
//! (a lost vehicle) flies it on a layer above or below it ([`Climb`]), chosen by its
//! clearance from every such [`Keepout`] along the whole three-phase path.

use skein_model::geo::Ned;

/// Vertical speed of a transition relative to the pattern, m/s (under PX4's descent limit).
pub const TRANSIT_CLIMB_M_S: f64 = 1.0;

/// The layer of a follower that passes a leader vehicle during a transition.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Climb {
    /// Height above the straight path, metres (negative: below it).
    pub(super) height_m: f64,
}

/// A place a transition path keeps away from, pattern frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Keepout {
    /// Its centre, metres.
    pub(super) centre: Ned,
    /// The distance to keep, metres.
    pub(super) radius_m: f64,
    /// A path that starts closer may leave it (a member caught inside a growing hazard);
    /// otherwise the path must keep the full radius from its first metre.
    pub(super) may_leave: bool,
}

impl Keepout {
    /// The leader vehicle at the pattern's origin.
    pub(super) fn leader(separation_m: f64) -> Self {
        Keepout {
            centre: Ned::ZERO,
            radius_m: separation_m,
            may_leave: false,
        }
    }

    /// The distance a path `a → b` on `climb` must keep from it.
    fn needed_m(&self, a: Ned) -> f64 {
        if self.may_leave {
            self.radius_m.min((a - self.centre).norm())
        } else {
            self.radius_m
        }
    }

    /// True when the path `a → b` on `climb` keeps what it must.
    pub(super) fn clear(&self, a: Ned, b: Ned, climb: Option<&Climb>) -> bool {
        clearance_from_origin(a - self.centre, b - self.centre, climb) >= self.needed_m(a) - 1e-9
    }
}

impl Climb {
    /// The smallest layer (above rather than below on a tie) that keeps a member going
    /// `a → b` clear of every keep-out through all three phases, trying multiples of the
    /// largest keep-out radius; the highest tried when none does (the shapers protect the
    /// rest).
    pub(super) fn over(a: Ned, b: Ned, keepouts: &[Keepout]) -> Climb {
        let base = keepouts.iter().map(|k| k.radius_m).fold(0.0, f64::max);
        [1.0, -1.0, 1.5, -1.5, 2.0, -2.0, 3.0, -3.0]
            .into_iter()
            .map(|k| Climb { height_m: k * base })
            .find(|c| keepouts.iter().all(|k| k.clear(a, b, Some(c))))
            .unwrap_or(Climb {
                height_m: 3.0 * base,
            })
    }

    /// [`Climb::over`] the leader vehicle alone (at the origin, `separation_m`).
    #[cfg(test)]
    pub(super) fn over_origin(a: Ned, b: Ned, separation_m: f64) -> Climb {
        Climb::over(a, b, &[Keepout::leader(separation_m)])
    }

    /// Length of the layering phases for this climb, seconds (peak vertical speed
    /// [`TRANSIT_CLIMB_M_S`]).
    pub(super) fn hold_s(&self) -> f64 {
        1.5 * self.height_m.abs() / TRANSIT_CLIMB_M_S
    }
}

/// Smallest distance (metres) from the origin (the leader vehicle, in its own pattern
/// frame) of a follower going `a → b` on `climb`'s layer: up from `a`, along the lifted
/// straight line, down onto `b`, sampled.
pub(super) fn clearance_from_origin(a: Ned, b: Ned, climb: Option<&Climb>) -> f64 {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-9
    }

    #[test]
    fn climbs_pick_the_smallest_clear_layer() {
        let sep = 3.5;
        // Across the leader: the first layer above clears it exactly.
        let c = Climb::over_origin(Ned::new(0.0, -5.0, 0.0), Ned::new(0.0, 5.0, 0.0), sep);
        assert_eq!(c.height_m, 3.5);
        assert!(close(c.hold_s(), 5.25));
        // Passing 2 m below the leader: going up would meet it, going down clears it.
        let c = Climb::over_origin(Ned::new(0.0, -5.0, 2.0), Ned::new(0.0, 5.0, 2.0), sep);
        assert_eq!(c.height_m, -3.5);
        // Starting too close for any layer: the highest one.
        let c = Climb::over_origin(Ned::new(0.0, -2.0, 0.0), Ned::new(0.0, 5.0, 0.0), sep);
        assert_eq!(c.height_m, 10.5);
        assert!(close(c.hold_s(), 15.75));
    }

    #[test]
    fn clearance_is_the_closest_approach_to_the_origin() {
        let (a, b) = (Ned::new(0.0, -5.0, 0.0), Ned::new(0.0, 5.0, 0.0));
        assert!(close(clearance_from_origin(a, b, None), 0.0));
        let off = Ned::new(3.0, 0.0, 0.0);
        assert!(close(clearance_from_origin(a + off, b + off, None), 3.0));
        let climb = Climb { height_m: 4.0 };
        assert!(close(
            clearance_from_origin(a + off, b + off, Some(&climb)),
            5.0
        ));
        // The rise and the fall count too: an end near the origin bounds it.
        let c = clearance_from_origin(Ned::new(0.0, 1.0, 0.0), b, Some(&climb));
        assert!(close(c, 1.0));
    }
}
