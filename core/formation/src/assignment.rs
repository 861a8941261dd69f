//! Which slot each member flies: minimum total squared distance (Kuhn–Munkres, see
//! [`skein_model::formation::assign_slots_by`]) from where the members start to the free
//! slots, a leader vehicle keeping slot 0, the members farthest from every slot waiting
//! when a custom shape has too few; and the [`Transition`] that takes them there. The
//! assignment stays purely the minimum total squared distance even with hazards (its
//! separation argument depends on it): a path that would pass a hazard, or a leader
//! vehicle, is flown on a layer above (or below) it instead (see `climb`).

use super::climb::Keepout;
use super::hazard::Hazard;
use super::transition::Transition;
use skein_model::formation::assign_slots;
use skein_model::geo::Ned;
use std::collections::BTreeMap;

/// Assigns members to slots and plans the transition to them. `starts` are where the
/// members start, pattern frame (metres from the anchor, unturned); `offsets` are the
/// slots, pattern frame, slot 0 the leader's; `leader` is the leader vehicle (slot 0,
/// not on the plan; followers pass it at least `separation_m` metres away), `None` for
/// the virtual leader (every slot free). Members beyond the free slots get none.
/// `hazards` are in the pattern frame too.
pub(super) fn assign(
    starts: &BTreeMap<String, Ned>,
    offsets: &[Ned],
    leader: Option<&str>,
    separation_m: f64,
    hazards: &[Hazard],
) -> (BTreeMap<String, usize>, Transition) {
    let mut assignment = BTreeMap::new();
    let first_follower_slot = match leader {
        Some(l) => {
            assignment.insert(l.to_string(), 0);
            1
        }
        None => 0,
    };
    // Beyond capacity (custom shapes): the members farthest from every slot wait.
    let free = &offsets[first_follower_slot..];
    let mut candidates: Vec<(&String, Ned)> = starts
        .iter()
        .filter(|(id, _)| Some(id.as_str()) != leader)
        .map(|(id, p)| (id, *p))
        .collect();
    if candidates.len() > free.len() {
        let nearest_slot = |p: Ned| {
            free.iter()
                .map(|s| (p - *s).norm_squared())
                .fold(f64::MAX, f64::min)
        };
        candidates.sort_by(|a, b| nearest_slot(a.1).total_cmp(&nearest_slot(b.1)));
        candidates.truncate(free.len());
    }
    let positions: Vec<Ned> = candidates.iter().map(|(_, p)| *p).collect();
    let slots = assign_slots(&positions, free);
    let mut transition = Transition::new();
    // Paths keep clear of the leader vehicle and of every hazard, on a layer if need be.
    let keepouts: Vec<Keepout> = leader
        .map(|_| Keepout::leader(separation_m))
        .into_iter()
        .chain(hazards.iter().map(|h| Keepout {
            centre: h.position,
            radius_m: h.clearance_m(separation_m),
            may_leave: true,
        }))
        .collect();
    for ((id, start), slot) in candidates.into_iter().zip(slots) {
        let slot = slot + first_follower_slot;
        assignment.insert(id.clone(), slot);
        transition.add(id, start, offsets[slot], &keepouts);
    }
    (assignment, transition)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn starts(list: &[(&str, Ned)]) -> BTreeMap<String, Ned> {
        list.iter().map(|(id, p)| (id.to_string(), *p)).collect()
    }

    /// A line of three: leader, right, left at 5 m.
    fn line() -> Vec<Ned> {
        vec![Ned::ZERO, Ned::new(0.0, 5.0, 0.0), Ned::new(0.0, -5.0, 0.0)]
    }

    #[test]
    fn followers_take_their_nearest_slots_around_the_leader() {
        let s = starts(&[
            ("a", Ned::new(1.0, -4.0, 0.0)),
            ("b", Ned::new(0.0, 0.0, 0.0)),
            ("c", Ned::new(-1.0, 3.0, 0.0)),
        ]);
        let (assignment, t) = assign(&s, &line(), Some("b"), 3.5, &[]);
        assert_eq!(assignment, starts_to_slots(&[("a", 2), ("b", 0), ("c", 1)]));
        // The leader vehicle is not on the plan; the others start where they are.
        assert!(t.planned("b").is_none());
        assert_eq!(t.planned("a").unwrap().0, Ned::new(1.0, -4.0, 0.0));
        assert_eq!(t.starts.len(), 2);
        assert_eq!(t.goals["c"], Ned::new(0.0, 5.0, 0.0));
    }

    #[test]
    fn a_virtual_leader_leaves_every_slot_free() {
        let s = starts(&[
            ("a", Ned::new(0.0, 6.0, 0.0)),
            ("b", Ned::new(0.0, -6.0, 0.0)),
            ("c", Ned::new(0.5, 0.5, 0.0)),
        ]);
        let (assignment, t) = assign(&s, &line(), None, 3.5, &[]);
        assert_eq!(assignment, starts_to_slots(&[("a", 1), ("b", 2), ("c", 0)]));
        // Nobody passes a leader vehicle: no layers, so the extents are the ends only.
        let up = t.extents().iter().filter(|p| p.down_m != 0.0).count();
        assert_eq!(up, 0);
    }

    #[test]
    fn beyond_capacity_the_farthest_members_wait() {
        let offsets = vec![Ned::ZERO, Ned::new(-5.0, 0.0, 0.0)];
        let s = starts(&[
            ("a", Ned::ZERO),
            ("b", Ned::new(-4.0, 0.0, 0.0)),
            ("c", Ned::new(30.0, 30.0, 0.0)),
        ]);
        let (assignment, t) = assign(&s, &offsets, Some("a"), 3.5, &[]);
        assert_eq!(assignment, starts_to_slots(&[("a", 0), ("b", 1)]));
        assert!(t.planned("c").is_none());
    }

    #[test]
    fn a_follower_crossing_the_leader_vehicle_flies_a_layer() {
        // b must go from the left of the leader to its right, c the other way.
        let s = starts(&[
            ("a", Ned::ZERO),
            ("b", Ned::new(0.0, -5.0, 0.0)),
            ("c", Ned::new(0.0, 5.0, 0.0)),
        ]);
        let offsets = vec![Ned::ZERO, Ned::new(0.0, 5.0, 0.0), Ned::new(-5.0, 0.0, 0.0)];
        let (assignment, t) = assign(&s, &offsets, Some("a"), 3.5, &[]);
        // c keeps its slot; b goes behind the leader, its straight path clear of it.
        assert_eq!(assignment, starts_to_slots(&[("a", 0), ("b", 2), ("c", 1)]));
        assert!(t.extents().iter().all(|p| p.down_m == 0.0));
        // With c forced out of the way, b must pass the leader: a layer 3.5 m up.
        let s = starts(&[("a", Ned::ZERO), ("b", Ned::new(0.0, -5.0, 0.0))]);
        let (_, t) = assign(&s, &offsets[..2], Some("a"), 3.5, &[]);
        let extents = t.extents();
        assert!(extents.contains(&Ned::new(0.0, -5.0, -3.5)), "{extents:?}");
        assert!(extents.contains(&Ned::new(0.0, 5.0, -3.5)), "{extents:?}");
    }

    #[test]
    fn a_path_through_a_hazard_is_flown_on_a_layer_over_it() {
        // Slots 6 m west and east; each member starts 12 m north of its nearest one, and
        // a hazard sits on the western member's straight path.
        let offsets = vec![Ned::new(0.0, -6.0, 0.0), Ned::new(0.0, 6.0, 0.0)];
        let s = starts(&[
            ("e", Ned::new(12.0, 8.0, 0.0)),
            ("w", Ned::new(12.0, -8.0, 0.0)),
        ]);
        let hazard = Hazard {
            id: "x".into(),
            position: Ned::new(6.0, -7.0, 0.0),
            radius_m: 1.0,
            unseen_s: 1.0,
            reason: "Lost".into(),
        };
        let (plain, t) = assign(&s, &offsets, None, 3.5, &[]);
        let (avoiding, layered) = assign(&s, &offsets, None, 3.5, std::slice::from_ref(&hazard));
        // The same assignment (minimum squared distance keeps the separation argument)…
        assert_eq!(plain, starts_to_slots(&[("e", 1), ("w", 0)]));
        assert_eq!(avoiding, plain);
        assert!(t.extents().iter().all(|p| p.down_m == 0.0));
        // … but "w" flies over the hazard, 4.5 m (its clearance) above its straight path.
        let up: Vec<Ned> = layered
            .extents()
            .into_iter()
            .filter(|p| p.down_m != 0.0)
            .collect();
        assert!(up.contains(&Ned::new(12.0, -8.0, -4.5)), "{up:?}");
        assert!(up.contains(&Ned::new(0.0, -6.0, -4.5)), "{up:?}");
        assert_eq!(up.len(), 2, "only w climbs: {up:?}");
    }

    fn starts_to_slots(list: &[(&str, usize)]) -> BTreeMap<String, usize> {
        list.iter().map(|(id, s)| (id.to_string(), *s)).collect()
    }
}
