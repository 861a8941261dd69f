//! Where every vehicle is, for the separation check: each vehicle publishes the places it
//! takes up (measured position and velocity, and its setpoint when skein steers it) on a
//! channel of its own, and reads the others' through the list the coordinator keeps.
//!
//! The coordinator owns the [`NeighbourBoard`]: it gives each vehicle of its process its
//! [`NeighbourSlot`] (the writer, kept across actor restarts) and a [`Neighbours`] reader,
//! and writes the slots of vehicles it hears of from other processes (an agent's
//! neighbours, from their reports). No lock is shared by every vehicle: each slot has its
//! own, and the list of slots changes only when a vehicle joins.
//!
//! Readers ask for the others near a point ([`Neighbourhood`], an
//! [`ObstacleSource`]): every place is put in a spatial index (a uniform grid of
//! horizontal cells, `grid.rs`) once per refresh period (the control period) by whichever
//! vehicle first needs it, and shared by all, so that a control step costs O(log n) in the
//! size of the swarm instead of O(n). The index is at most one period old, as the slots themselves are (every
//! vehicle writes its own once per control tick).

use grid::Grid;
use skein_model::geo::Ned;
use skein_model::safety::{Obstacle, ObstacleSource};
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::watch;

mod grid;

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

/// One vehicle's place on the board: written by its vehicle, read by everyone (a plain
/// lock, held for a copy: nobody waits for a change).
type Cell = Arc<Mutex<Option<Occupancy>>>;

/// A vehicle's id and its slot.
type Entry = (String, Cell);

/// One vehicle's writer on the board (cheap to clone; every clone writes the same slot).
#[derive(Clone, Debug)]
pub struct NeighbourSlot(Cell);

fn read(cell: &Cell) -> Option<Occupancy> {
    *cell.lock().unwrap_or_else(|p| p.into_inner())
}

impl NeighbourSlot {
    /// Publishes where the vehicle is and where it is being sent (swarm frame); with
    /// neither it takes up no place (it leaves the others' separation checks).
    pub fn set(&self, measured: Option<(Ned, Ned)>, setpoint: Option<(Ned, Ned)>, planned: bool) {
        let occupancy = (measured.is_some() || setpoint.is_some()).then_some(Occupancy {
            measured,
            setpoint,
            planned,
        });
        *self.0.lock().unwrap_or_else(|p| p.into_inner()) = occupancy;
    }

    /// What the slot holds now.
    pub fn get(&self) -> Option<Occupancy> {
        read(&self.0)
    }
}

/// How often the shared index of [`NeighbourBoard::default`] is rebuilt (a 50 Hz control
/// period).
pub const DEFAULT_REFRESH: Duration = Duration::from_millis(20);

/// The coordinator's list of every vehicle's slot (see the module docs).
#[derive(Debug)]
pub struct NeighbourBoard {
    slots: BTreeMap<String, NeighbourSlot>,
    list: watch::Sender<Arc<[Entry]>>,
    index: Arc<SharedIndex>,
}

impl Default for NeighbourBoard {
    fn default() -> Self {
        Self::new(DEFAULT_REFRESH)
    }
}

impl NeighbourBoard {
    /// An empty board whose readers share an index rebuilt at most every `refresh` (the
    /// control period).
    pub fn new(refresh: Duration) -> Self {
        NeighbourBoard {
            slots: BTreeMap::new(),
            list: watch::channel(Arc::from(Vec::new())).0,
            index: Arc::new(SharedIndex {
                refresh,
                current: Mutex::new(None),
                building: Mutex::new(()),
            }),
        }
    }

    /// The slot of vehicle `id`, made on first use (every reader sees it from then on).
    pub fn slot(&mut self, id: &str) -> NeighbourSlot {
        if let Some(s) = self.slots.get(id) {
            return s.clone();
        }
        let slot = NeighbourSlot(Arc::default());
        self.slots.insert(id.to_string(), slot.clone());
        let list: Arc<[Entry]> = self
            .slots
            .iter()
            .map(|(id, s)| (id.clone(), s.0.clone()))
            .collect();
        self.list.send_replace(list);
        slot
    }

    /// Vehicle `id`'s reader of every other slot, present and future.
    pub fn reader(&self, id: &str) -> Neighbours {
        Neighbours {
            list: self.list.subscribe(),
            index: self.index.clone(),
            id: id.to_string(),
            own: Mutex::default(),
        }
    }
}

/// One place in the index.
#[derive(Debug, Clone, Copy)]
struct Place {
    /// Index of its vehicle in the list (which is sorted by id).
    vehicle: u32,
    position: Ned,
    velocity: Ned,
    /// The vehicle is steered by skein (it avoids too).
    reciprocal: bool,
    /// The vehicle flies a formation slot.
    planned: bool,
}

/// Every place at one moment, indexed.
#[derive(Debug)]
struct Snapshot {
    built: Instant,
    /// The list it was built from (a vehicle joining makes a new one).
    list: Arc<[Entry]>,
    /// In list order: by vehicle id, measured position before setpoint.
    places: Vec<Place>,
    /// Places of vehicles not flying a slot, and of those that do.
    free: Grid,
    planned: Grid,
    /// Fastest place of `free`, and of all, m/s.
    free_speed_m_s: f64,
    all_speed_m_s: f64,
}

impl Snapshot {
    fn build(list: Arc<[Entry]>) -> Snapshot {
        let mut places = Vec::with_capacity(2 * list.len());
        for (i, (_, slot)) in list.iter().enumerate() {
            let Some(o) = read(slot) else {
                continue;
            };
            // A vehicle skein steers avoids too: each side takes half.
            let reciprocal = o.setpoint.is_some();
            for (position, velocity) in o.measured.into_iter().chain(o.setpoint) {
                places.push(Place {
                    vehicle: i as u32,
                    position,
                    velocity,
                    reciprocal,
                    planned: o.planned,
                });
            }
        }
        let (mut free_speed_m_s, mut all_speed_m_s) = (0.0f64, 0.0f64);
        for p in &places {
            let speed = p.velocity.norm();
            all_speed_m_s = all_speed_m_s.max(speed);
            if !p.planned {
                free_speed_m_s = free_speed_m_s.max(speed);
            }
        }
        let indexed = |planned: bool| {
            let places = &places;
            Grid::build(
                (0..places.len() as u32)
                    .filter(move |&k| places[k as usize].planned == planned)
                    .map(move |k| (places[k as usize].position, k)),
            )
        };
        let (free, planned) = (indexed(false), indexed(true));
        Snapshot {
            built: Instant::now(),
            list,
            places,
            free,
            planned,
            free_speed_m_s,
            all_speed_m_s,
        }
    }
}

/// The index the readers of one board share.
#[derive(Debug)]
struct SharedIndex {
    refresh: Duration,
    current: Mutex<Option<Arc<Snapshot>>>,
    /// Held while one reader rebuilds; the others use the previous snapshot meanwhile.
    building: Mutex<()>,
}

impl SharedIndex {
    /// The snapshot to read: the current one, rebuilt first when it is older than the
    /// refresh period or the list changed (by this caller, unless another one already
    /// rebuilds).
    fn snapshot(&self, list: &Arc<[Entry]>, now: Instant) -> Arc<Snapshot> {
        let current = self
            .current
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clone();
        let fresh = |s: &Snapshot| {
            Arc::ptr_eq(&s.list, list) && now.saturating_duration_since(s.built) < self.refresh
        };
        match current {
            Some(s) if fresh(&s) => s,
            stale => {
                let building = match self.building.try_lock() {
                    Ok(guard) => guard,
                    // Another reader rebuilds: use what there is, unless the list it was
                    // built from is gone (then wait for the new one).
                    Err(_) => match stale {
                        Some(s) if Arc::ptr_eq(&s.list, list) => return s,
                        _ => self.building.lock().unwrap_or_else(|p| p.into_inner()),
                    },
                };
                // It may have been rebuilt while we waited for the lock.
                if let Some(s) = self
                    .current
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .clone()
                    && fresh(&s)
                {
                    return s;
                }
                let s = Arc::new(Snapshot::build(list.clone()));
                *self.current.lock().unwrap_or_else(|p| p.into_inner()) = Some(s.clone());
                drop(building);
                s
            }
        }
    }
}

/// A vehicle's reader of the others' places.
#[derive(Debug)]
pub struct Neighbours {
    list: watch::Receiver<Arc<[Entry]>>,
    index: Arc<SharedIndex>,
    /// The vehicle that reads.
    id: String,
    /// What the reader keeps between control steps: its own place in the list it last
    /// read, and the scratch list of places found (held inline, next to the rest of the
    /// vehicle's state, not in an allocation of its own that each step would miss).
    own: Mutex<ReaderCache>,
}

/// See [`Neighbours::own`].
#[derive(Debug, Default)]
struct ReaderCache {
    /// The list and where the reader's vehicle is in it.
    position: Option<(Arc<[Entry]>, Option<u32>)>,
    found: Vec<u32>,
}

impl Neighbours {
    /// The others as the reader's vehicle sees them, for one control step at `now`: an
    /// [`ObstacleSource`] over every vehicle but itself. Separation is kept from both
    /// places of each: setpoints against setpoints is what skein controls, positions cover
    /// vehicles it does not steer and controllers that lag. With `planned` (the vehicle
    /// flies a slot), the other members are [`Obstacle::planned`]: the formation's
    /// transition plan keeps them apart.
    pub fn around(&self, planned: bool, now: Instant) -> Neighbourhood<'_> {
        let list = self.list.borrow().clone();
        let snapshot = self.index.snapshot(&list, now);
        let mut cache = self.own.lock().unwrap_or_else(|p| p.into_inner());
        // Looked up again only when the list changed (a vehicle joined): the ids are
        // strings apart in memory, a search per step would cost a cache miss per probe.
        let own = match &cache.position {
            Some((l, own)) if Arc::ptr_eq(l, &snapshot.list) => *own,
            _ => {
                let own = snapshot
                    .list
                    .binary_search_by(|(other, _)| other.as_str().cmp(&self.id))
                    .ok()
                    .map(|i| i as u32);
                cache.position = Some((snapshot.list.clone(), own));
                own
            }
        };
        Neighbourhood {
            snapshot,
            own,
            planned,
            reader: &self.own,
        }
    }

    /// Every point the others occupy, as [`Neighbours::around`] gives them now, whatever
    /// the distance; `out` is cleared first.
    pub fn others(&self, planned: bool, out: &mut Vec<Obstacle>) {
        self.around(planned, Instant::now())
            .near(Ned::ZERO, f64::INFINITY, f64::INFINITY, out);
    }
}

/// The others around one vehicle at one control step (see [`Neighbours::around`]).
#[derive(Debug)]
pub struct Neighbourhood<'a> {
    snapshot: Arc<Snapshot>,
    own: Option<u32>,
    planned: bool,
    /// The reader's cache, whose scratch list of the places found serves every query.
    reader: &'a Mutex<ReaderCache>,
}

impl Neighbourhood<'_> {
    fn obstacle(&self, p: &Place) -> Obstacle {
        Obstacle {
            position: p.position,
            velocity: p.velocity,
            reciprocal: p.reciprocal,
            planned: self.planned && p.planned,
        }
    }
}

impl ObstacleSource for Neighbourhood<'_> {
    fn near(&self, center: Ned, radius_m: f64, planned_radius_m: f64, out: &mut Vec<Obstacle>) {
        out.clear();
        let mut cache = self.reader.lock().unwrap_or_else(|p| p.into_inner());
        let found = &mut cache.found;
        found.clear();
        let s = &self.snapshot;
        s.free.within(center, radius_m, found);
        let planned_r = if self.planned {
            planned_radius_m
        } else {
            radius_m
        };
        s.planned.within(center, planned_r, found);
        // The list's order, as the whole list would give them.
        found.sort_unstable();
        out.extend(
            found
                .iter()
                .map(|&k| &s.places[k as usize])
                .filter(|p| Some(p.vehicle) != self.own)
                .map(|p| self.obstacle(p)),
        );
    }

    fn max_speed_m_s(&self) -> f64 {
        if self.planned {
            self.snapshot.free_speed_m_s
        } else {
            self.snapshot.all_speed_m_s
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(n: f64) -> Option<(Ned, Ned)> {
        Some((Ned::new(n, 0.0, -10.0), Ned::ZERO))
    }

    /// A board whose index is rebuilt at every read (what each test looks at is what the
    /// slots hold at that moment).
    fn live_board() -> NeighbourBoard {
        NeighbourBoard::new(Duration::ZERO)
    }

    #[test]
    fn a_vehicle_sees_every_other_place_but_its_own() {
        let mut board = live_board();
        let (a, b) = (board.slot("uav-1"), board.slot("uav-2"));
        let (reader_1, reader_2) = (board.reader("uav-1"), board.reader("uav-2"));
        a.set(at(0.0), at(1.0), true);
        b.set(at(5.0), None, false);
        let mut out = Vec::new();
        reader_1.others(true, &mut out);
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].position.north_m, 5.0);
        // Not steered: it does not avoid, so it is not reciprocal; not a member.
        assert!(!out[0].reciprocal && !out[0].planned);
        reader_2.others(true, &mut out);
        assert_eq!(out.len(), 2, "measured position and setpoint");
        assert!(out.iter().all(|o| o.reciprocal));
        // Planned only when both fly the formation's plan.
        reader_2.others(false, &mut out);
        assert!(out.iter().all(|o| !o.planned));
    }

    #[test]
    fn a_vehicle_with_no_place_leaves_the_others_checks() {
        let mut board = live_board();
        let a = board.slot("uav-1");
        let reader = board.reader("uav-2");
        a.set(at(0.0), None, false);
        let mut out = Vec::new();
        reader.others(false, &mut out);
        assert_eq!(out.len(), 1);
        a.set(None, None, false);
        reader.others(false, &mut out);
        assert!(out.is_empty());
        assert_eq!(a.get(), None);
    }

    #[test]
    fn a_vehicle_that_joins_later_is_seen_by_earlier_readers_and_keeps_its_slot() {
        let mut board = live_board();
        let reader = board.reader("uav-1");
        let late = board.slot("uav-9");
        late.set(at(3.0), None, false);
        let mut out = Vec::new();
        reader.others(false, &mut out);
        assert_eq!(out.len(), 1);
        // A restarted vehicle gets the same slot back, with what it published.
        assert_eq!(board.slot("uav-9").get(), late.get());
    }

    #[test]
    fn the_index_is_built_once_a_period_and_again_when_a_vehicle_joins() {
        let mut board = NeighbourBoard::new(Duration::from_secs(3600));
        let a = board.slot("uav-1");
        let reader = board.reader("uav-2");
        a.set(at(0.0), None, false);
        let mut out = Vec::new();
        reader.others(false, &mut out);
        assert_eq!(out[0].position.north_m, 0.0);
        // Within the period every reader shares the snapshot: a move shows next period.
        a.set(at(7.0), None, false);
        board.reader("uav-2").others(false, &mut out);
        assert_eq!(out[0].position.north_m, 0.0);
        // A vehicle joining makes a new list: the index is built again at once.
        let b = board.slot("uav-3");
        b.set(at(20.0), None, false);
        reader.others(false, &mut out);
        let norths: Vec<f64> = out.iter().map(|o| o.position.north_m).collect();
        assert_eq!(norths, vec![7.0, 20.0]);
    }

    #[test]
    fn asked_by_distance_the_index_gives_the_near_places_in_list_order() {
        let mut board = live_board();
        let slots: Vec<_> = (0..50)
            .map(|i| board.slot(&format!("uav-{i:02}")))
            .collect();
        for (i, s) in slots.iter().enumerate() {
            // A line along north, 4 m apart; every third one steered (two places each).
            let p = at(4.0 * i as f64);
            let sp = (i % 3 == 0).then(|| (Ned::new(4.0 * i as f64, 1.0, -10.0), Ned::ZERO));
            s.set(p, sp, i % 2 == 0);
        }
        let reader = board.reader("uav-10");
        let mut all = Vec::new();
        reader.others(true, &mut all);
        let around = reader.around(true, Instant::now());
        let center = Ned::new(40.0, 0.0, -10.0);
        let mut near = Vec::new();
        around.near(center, 9.0, 2.0, &mut near);
        let expected: Vec<Obstacle> = all
            .iter()
            .copied()
            .filter(|o| {
                let r = if o.planned { 2.0 } else { 9.0 };
                (o.position - center).norm() <= r
            })
            .collect();
        assert!(!expected.is_empty());
        assert_eq!(near, expected);
        assert!(around.max_speed_m_s() == 0.0);
    }
}
