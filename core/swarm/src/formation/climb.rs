//! The layers of a transition: a follower whose straight path would pass a leader
//! vehicle (which keeps slot 0, outside the assignment's separation argument) flies it on
//! a layer above or below the leader ([`Climb`]), chosen by its clearance from the
//! leader along the whole three-phase path.

use super::transition::TRANSIT_CLIMB_M_S;
use skein_model::geo::Ned;

/// The layer of a follower that passes a leader vehicle during a transition.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Climb {
    /// Height above the straight path, metres (negative: below it).
    pub(super) height_m: f64,
}

impl Climb {
    /// The smallest layer (over the leader rather than under it on a tie) that keeps a
    /// follower going `a → b` at least `separation_m` from the origin (the leader
    /// vehicle, in its own pattern frame) through all three phases, or the highest one
    /// when none does (the shapers protect the rest). A layer below lowers the reference's
    /// ceiling (every planned place stays inside the fence).
    pub(super) fn over_origin(a: Ned, b: Ned, separation_m: f64) -> Climb {
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
