//! Members that drop out of the formation without being asked ([`Absences`]): a fade of
//! their link, an agent that held them when it lost its coordinator, a lost link, a PX4
//! failsafe. The engine re-forms without them, but the status keeps listing them, each
//! with its error to where its slot is now, so that the formation's figures never look
//! better because a member is out ([`super::AbsentMember`]).
//!
//! A member leaves the list when it flies a slot again, when it is released (the
//! operator commanded it, or an observation took it to a station), or when the formation
//! stops.

use super::status::{AbsentMember, Whereabouts};
use skein_model::geo::Ned;
use std::collections::{BTreeMap, BTreeSet};

/// A slot index and the slot's offset from the reference point, pattern frame (metres).
pub(super) type SlotOffset = (usize, Ned);

/// The absent members and what the engine needs to find them (see the module docs).
#[derive(Debug, Default)]
pub(super) struct Absences {
    /// Each member's slot at the last tick.
    members: BTreeMap<String, SlotOffset>,
    /// Members that dropped out without being released, with their last slot.
    absent: BTreeMap<String, SlotOffset>,
    /// Members released while they still had a slot: not absent when they drop out.
    released: BTreeSet<String>,
}

impl Absences {
    /// Forgets everything (the formation stopped).
    pub(super) fn clear(&mut self) {
        *self = Absences::default();
    }

    /// `id` leaves because it was asked to: it is not absent when it drops out, and no
    /// longer is if it was.
    pub(super) fn release(&mut self, id: &str) {
        self.absent.remove(id);
        if self.members.contains_key(id) {
            self.released.insert(id.to_string());
        }
    }

    /// The absent members' ids.
    pub(super) fn ids(&self) -> impl Iterator<Item = &str> {
        self.absent.keys().map(String::as_str)
    }

    /// This tick's members and their slots: those of the last tick that are not among
    /// them become absent (unless released); those among them are no longer absent.
    pub(super) fn update(&mut self, members: BTreeMap<String, SlotOffset>) {
        let before = std::mem::replace(&mut self.members, members);
        for (id, slot) in before {
            if self.members.contains_key(&id) {
                continue;
            }
            if !self.released.remove(&id) {
                self.absent.entry(id).or_insert(slot);
            }
        }
        for id in self.members.keys() {
            self.absent.remove(id);
        }
    }

    /// The absent members that `whereabouts` names, with their slots placed by `place`
    /// (offset from the reference point, pattern frame → swarm-frame NED; `None` while
    /// no formation is flown).
    pub(super) fn list(
        &self,
        place: impl Fn(Ned) -> Option<Ned>,
        whereabouts: &BTreeMap<String, Whereabouts>,
    ) -> Vec<AbsentMember> {
        self.absent
            .iter()
            .filter_map(|(id, (slot, offset))| {
                let w = whereabouts.get(id)?;
                let target = place(*offset)?;
                Some(AbsentMember {
                    id: id.clone(),
                    slot: *slot,
                    target,
                    error_m: w.position.map(|p| (p - target).norm()),
                    absence: w.absence.clone(),
                    state: w.state.clone(),
                })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Absence;

    fn at(slot: usize, north_m: f64) -> SlotOffset {
        (slot, Ned::new(north_m, 0.0, 0.0))
    }

    fn held(position: Ned) -> Whereabouts {
        Whereabouts {
            position: Some(position),
            absence: Absence::Held,
            state: "Hovering".into(),
        }
    }

    #[test]
    fn a_member_that_drops_out_is_absent_until_it_flies_a_slot_again() {
        let mut a = Absences::default();
        a.update(BTreeMap::from([
            ("a".into(), at(0, 0.0)),
            ("b".into(), at(1, -5.0)),
        ]));
        assert_eq!(a.ids().count(), 0);
        a.update(BTreeMap::from([("a".into(), at(0, 0.0))]));
        assert_eq!(a.ids().collect::<Vec<_>>(), ["b"]);
        // Its slot moves with the reference: 10 m north now.
        let place = |o: Ned| Some(Ned::new(10.0, 0.0, 0.0) + o);
        let w = BTreeMap::from([("b".to_string(), held(Ned::new(0.0, 0.0, 0.0)))]);
        let list = a.list(place, &w);
        assert_eq!(list.len(), 1);
        assert_eq!(list[0].slot, 1);
        assert!((list[0].error_m.unwrap() - 5.0).abs() < 1e-9, "{list:?}");
        assert_eq!(list[0].absence, Absence::Held);
        // Not named by the coordinator: not listed.
        assert!(a.list(place, &BTreeMap::new()).is_empty());
        // Back on a slot (another one): no longer absent.
        a.update(BTreeMap::from([
            ("a".into(), at(0, 0.0)),
            ("b".into(), at(2, -8.0)),
        ]));
        assert_eq!(a.ids().count(), 0);
    }

    #[test]
    fn a_released_member_is_not_absent_when_it_leaves() {
        let mut a = Absences::default();
        a.update(BTreeMap::from([
            ("a".into(), at(0, 0.0)),
            ("b".into(), at(1, -5.0)),
        ]));
        // Released while it still flies its slot (the command is on its way)...
        a.release("b");
        a.update(BTreeMap::from([
            ("a".into(), at(0, 0.0)),
            ("b".into(), at(1, -5.0)),
        ]));
        // ...then gone.
        a.update(BTreeMap::from([("a".into(), at(0, 0.0))]));
        assert_eq!(a.ids().count(), 0);
        // Absent, then released: no longer listed.
        a.update(BTreeMap::new());
        assert_eq!(a.ids().collect::<Vec<_>>(), ["a"]);
        a.release("a");
        assert_eq!(a.ids().count(), 0);
    }
}
