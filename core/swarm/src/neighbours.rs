//! Where every vehicle is, for the separation check: each vehicle publishes the places it
//! takes up (measured position and velocity, and its setpoint when skein steers it) on a
//! channel of its own, and reads the others' through the list the coordinator keeps.
//!
//! The coordinator owns the [`NeighbourBoard`]: it gives each vehicle of its process its
//! [`NeighbourSlot`] (the writer, kept across actor restarts) and a [`Neighbours`] reader,
//! and writes the slots of vehicles it hears of from other processes (an agent's
//! neighbours, from their reports). No lock is shared by every vehicle: each slot is its
//! own `watch` channel, and the list of slots changes only when a vehicle joins.

use skein_model::geo::Ned;
use skein_model::safety::Obstacle;
use std::collections::BTreeMap;
use std::sync::Arc;
use tokio::sync::watch;

/// The places one vehicle takes up, swarm frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Occupancy {
    /// Measured position (NED, metres) and velocity (NED, m/s).
    pub measured: Option<(Ned, Ned)>,
    /// Setpoint position and velocity, when skein steers the vehicle.
    pub setpoint: Option<(Ned, Ned)>,
    /// Flies a slot of the formation (on its transition plan).
    pub planned: bool,
}

/// A vehicle's id and the reader of its slot.
type Entry = (String, watch::Receiver<Option<Occupancy>>);

/// One vehicle's writer on the board (cheap to clone; every clone writes the same slot).
#[derive(Clone, Debug)]
pub struct NeighbourSlot(Arc<watch::Sender<Option<Occupancy>>>);

impl NeighbourSlot {
    /// Publishes where the vehicle is and where it is being sent (swarm frame); with
    /// neither it takes up no place (it leaves the others' separation checks).
    pub fn set(&self, measured: Option<(Ned, Ned)>, setpoint: Option<(Ned, Ned)>, planned: bool) {
        let occupancy = (measured.is_some() || setpoint.is_some()).then_some(Occupancy {
            measured,
            setpoint,
            planned,
        });
        self.0.send_replace(occupancy);
    }

    /// What the slot holds now.
    pub fn get(&self) -> Option<Occupancy> {
        *self.0.borrow()
    }
}

/// The coordinator's list of every vehicle's slot (see the module docs).
#[derive(Debug)]
pub struct NeighbourBoard {
    slots: BTreeMap<String, NeighbourSlot>,
    list: watch::Sender<Arc<[Entry]>>,
}

impl Default for NeighbourBoard {
    fn default() -> Self {
        NeighbourBoard {
            slots: BTreeMap::new(),
            list: watch::channel(Arc::from(Vec::new())).0,
        }
    }
}

impl NeighbourBoard {
    /// An empty board.
    pub fn new() -> Self {
        Self::default()
    }

    /// The slot of vehicle `id`, made on first use (every reader sees it from then on).
    pub fn slot(&mut self, id: &str) -> NeighbourSlot {
        if let Some(s) = self.slots.get(id) {
            return s.clone();
        }
        let slot = NeighbourSlot(Arc::new(watch::channel(None).0));
        self.slots.insert(id.to_string(), slot.clone());
        let list: Arc<[Entry]> = self
            .slots
            .iter()
            .map(|(id, s)| (id.clone(), s.0.subscribe()))
            .collect();
        self.list.send_replace(list);
        slot
    }

    /// A reader of every slot, present and future.
    pub fn reader(&self) -> Neighbours {
        Neighbours {
            list: self.list.subscribe(),
        }
    }
}

/// A vehicle's reader of the others' places.
#[derive(Clone, Debug)]
pub struct Neighbours {
    list: watch::Receiver<Arc<[Entry]>>,
}

impl Neighbours {
    /// The points every vehicle except `id` occupies: its measured position and its
    /// setpoint. Separation is kept from both: setpoints against setpoints is what skein
    /// controls, positions cover vehicles it does not steer and controllers that lag.
    /// With `planned` (vehicle `id` flies a slot), the other members are marked
    /// [`Obstacle::planned`]: the formation's transition plan keeps them apart. `out` is
    /// cleared first (the caller keeps it between ticks: no allocation per tick).
    pub fn others(&self, id: &str, planned: bool, out: &mut Vec<Obstacle>) {
        out.clear();
        let list = self.list.borrow().clone();
        for (_, slot) in list.iter().filter(|(other, _)| other != id) {
            let Some(o) = *slot.borrow() else {
                continue;
            };
            // A vehicle skein steers avoids too: each side takes half.
            let reciprocal = o.setpoint.is_some();
            for (position, velocity) in o.measured.into_iter().chain(o.setpoint) {
                out.push(Obstacle {
                    position,
                    velocity,
                    reciprocal,
                    planned: planned && o.planned,
                });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(n: f64) -> Option<(Ned, Ned)> {
        Some((Ned::new(n, 0.0, -10.0), Ned::ZERO))
    }

    #[test]
    fn a_vehicle_sees_every_other_place_but_its_own() {
        let mut board = NeighbourBoard::new();
        let (a, b) = (board.slot("uav-1"), board.slot("uav-2"));
        let reader = board.reader();
        a.set(at(0.0), at(1.0), true);
        b.set(at(5.0), None, false);
        let mut out = Vec::new();
        reader.others("uav-1", true, &mut out);
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].position.north_m, 5.0);
        // Not steered: it does not avoid, so it is not reciprocal; not a member.
        assert!(!out[0].reciprocal && !out[0].planned);
        reader.others("uav-2", true, &mut out);
        assert_eq!(out.len(), 2, "measured position and setpoint");
        assert!(out.iter().all(|o| o.reciprocal));
        // Planned only when both fly the formation's plan.
        reader.others("uav-2", false, &mut out);
        assert!(out.iter().all(|o| !o.planned));
    }

    #[test]
    fn a_vehicle_with_no_place_leaves_the_others_checks() {
        let mut board = NeighbourBoard::new();
        let a = board.slot("uav-1");
        let reader = board.reader();
        a.set(at(0.0), None, false);
        let mut out = Vec::new();
        reader.others("uav-2", false, &mut out);
        assert_eq!(out.len(), 1);
        a.set(None, None, false);
        reader.others("uav-2", false, &mut out);
        assert!(out.is_empty());
        assert_eq!(a.get(), None);
    }

    #[test]
    fn a_vehicle_that_joins_later_is_seen_by_earlier_readers_and_keeps_its_slot() {
        let mut board = NeighbourBoard::new();
        let reader = board.reader();
        let late = board.slot("uav-9");
        late.set(at(3.0), None, false);
        let mut out = Vec::new();
        reader.others("uav-1", false, &mut out);
        assert_eq!(out.len(), 1);
        // A restarted vehicle gets the same slot back, with what it published.
        assert_eq!(board.slot("uav-9").get(), late.get());
    }
}
