//! Tracks in a rehearsal: the intruders of the scenario (the simulator's own paths,
//! [`skein_sim::intruders`]) as the swarm's tracker would hold them, from their truth.
//! No camera is rendered: an intruder is seen while an airborne vehicle that carries a
//! gimbal is within [`DETECTION_RANGE_M`] of it, confirmed once seen for
//! [`CONFIRM_S`], lost after [`LOST_AFTER_S`] unseen and forgotten [`DELETE_AFTER_S`]
//! later. The numbers follow the live chain's (the simulated camera finds a small
//! multicopter up to about 120 m; the tracker confirms a passing intruder within 5 s and
//! loses it after 2 s unseen).

use skein_mission::TrackSeen;
use skein_model::geo::Ned;
use std::collections::BTreeMap;

/// An observation UAV sees an intruder this close, metres.
pub const DETECTION_RANGE_M: f64 = 120.0;
/// Seen this long, seconds: confirmed.
pub const CONFIRM_S: f64 = 2.0;
/// Unseen this long, seconds: lost.
pub const LOST_AFTER_S: f64 = 2.0;
/// Lost this long, seconds: deleted.
pub const DELETE_AFTER_S: f64 = 10.0;

#[derive(Debug, Clone)]
struct Held {
    id: String,
    first_seen_s: f64,
    last_seen_s: f64,
    position: Ned,
}

/// The tracks held so far, by intruder id.
#[derive(Debug, Default)]
pub(crate) struct Tracks {
    held: BTreeMap<String, Held>,
    next: u32,
}

impl Tracks {
    /// Updates from the intruders' truth `intruders` (id, position) at `now_s` and the
    /// airborne observers' positions `eyes`.
    pub fn update(&mut self, now_s: f64, intruders: &[(String, Ned)], eyes: &[Ned]) {
        for (id, p) in intruders {
            let seen = eyes.iter().any(|e| (*e - *p).norm() <= DETECTION_RANGE_M);
            if let Some(h) = self.held.get_mut(id) {
                h.position = *p;
                if seen {
                    // Lost and seen again: a new track, as the tracker starts one.
                    if now_s - h.last_seen_s > LOST_AFTER_S {
                        h.first_seen_s = now_s;
                        self.next += 1;
                        h.id = format!("track-{}", self.next);
                    }
                    h.last_seen_s = now_s;
                }
            } else if seen {
                self.next += 1;
                self.held.insert(
                    id.clone(),
                    Held {
                        id: format!("track-{}", self.next),
                        first_seen_s: now_s,
                        last_seen_s: now_s,
                        position: *p,
                    },
                );
            }
        }
        let gone: Vec<String> = self
            .held
            .iter()
            .filter(|(id, h)| {
                now_s - h.last_seen_s > LOST_AFTER_S + DELETE_AFTER_S
                    || !intruders.iter().any(|(i, _)| i == *id)
            })
            .map(|(id, _)| id.clone())
            .collect();
        for id in gone {
            self.held.remove(&id);
        }
    }

    /// The tracks at `now_s`, as a mission tick sees them.
    pub fn seen(&self, now_s: f64) -> Vec<TrackSeen> {
        self.held
            .values()
            .map(|h| TrackSeen {
                id: h.id.clone(),
                position: h.position,
                confirmed: now_s - h.last_seen_s <= LOST_AFTER_S
                    && h.last_seen_s - h.first_seen_s >= CONFIRM_S,
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_intruder_in_range_is_confirmed_then_lost_then_forgotten() {
        let mut t = Tracks::default();
        let eye = [Ned::new(0.0, 0.0, -10.0)];
        let at = |east: f64| vec![("intruder-1".to_string(), Ned::new(0.0, east, -14.0))];
        // Every half second, as the mission tick updates it.
        let fly = |t: &mut Tracks, from_s: f64, to_s: f64, east: f64| {
            let mut s = from_s;
            while s <= to_s + 1e-9 {
                t.update(s, &at(east), &eye);
                s += 0.5;
            }
        };
        fly(&mut t, 0.0, 0.5, 200.0);
        assert!(t.seen(0.5).is_empty(), "out of range");
        fly(&mut t, 1.0, 2.5, 100.0);
        assert!(!t.seen(2.5)[0].confirmed, "tentative");
        fly(&mut t, 3.0, 3.5, 90.0);
        assert!(t.seen(3.5)[0].confirmed);
        assert_eq!(t.seen(3.5)[0].id, "track-1");
        fly(&mut t, 4.0, 6.0, 300.0);
        assert!(!t.seen(6.0)[0].confirmed, "lost");
        fly(&mut t, 6.5, 20.0, 300.0);
        assert!(t.seen(20.0).is_empty(), "forgotten");
    }
}
