//! What a rehearsal measures as it flies, on where the aircraft really are (the
//! simulator's truth): the smallest distance between two airborne vehicles, the smallest
//! geofence margin of an airborne vehicle, each vehicle's battery when it lands, the
//! survey coverage, and the paths flown (one point a second) for the picture.

use crate::aircraft::Aircraft;
use crate::coverage::Coverage;
use skein_model::geo::Ned;
use skein_model::geofence::Geofence;
use std::collections::BTreeMap;

/// The closest two airborne vehicles came: distance (m), the pair, when (mission s).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Closest {
    pub distance_m: f64,
    pub pair: [String; 2],
    pub at_s: f64,
}

/// The nearest an airborne vehicle came to the fence's boundary: margin (m, negative
/// outside), who, when (mission s).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Nearest {
    pub margin_m: f64,
    pub vehicle: String,
    pub at_s: f64,
}

/// The figures so far.
#[derive(Debug, Default)]
pub(crate) struct Record {
    pub closest: Option<Closest>,
    pub nearest_fence: Option<Nearest>,
    /// Battery when each vehicle last landed, percent.
    pub energy_at_landing: BTreeMap<String, f64>,
    /// Each vehicle's path, one point a second, swarm frame.
    pub trails: BTreeMap<String, Vec<Ned>>,
    /// Each intruder's path, likewise.
    pub intruder_trails: BTreeMap<String, Vec<Ned>>,
    /// Each survey's coverage, by step index.
    pub coverage: BTreeMap<usize, Coverage>,
    airborne: BTreeMap<String, bool>,
}

impl Record {
    /// Separation and fence margin of the airborne aircraft at mission time `at_s`;
    /// notes landings.
    pub fn note(&mut self, aircraft: &[Aircraft], fence: &Geofence, at_s: f64) {
        let flying: Vec<(&str, Ned)> = aircraft
            .iter()
            .filter(|a| a.state.is_airborne())
            .map(|a| (a.id.as_str(), a.truth()))
            .collect();
        for (i, (a, p)) in flying.iter().enumerate() {
            for (b, q) in &flying[i + 1..] {
                let d = (*p - *q).norm();
                if self.closest.as_ref().is_none_or(|c| d < c.distance_m) {
                    self.closest = Some(Closest {
                        distance_m: d,
                        pair: [a.to_string(), b.to_string()],
                        at_s,
                    });
                }
            }
            let margin_m = fence.margin_m(*p);
            if self
                .nearest_fence
                .as_ref()
                .is_none_or(|n| margin_m < n.margin_m)
            {
                self.nearest_fence = Some(Nearest {
                    margin_m,
                    vehicle: a.to_string(),
                    at_s,
                });
            }
        }
        for a in aircraft {
            let now = a.state.is_airborne();
            let was = self.airborne.insert(a.id.clone(), now).unwrap_or(false);
            if was
                && !now
                && let Some(b) = a.battery_percent()
            {
                self.energy_at_landing.insert(a.id.clone(), b);
            }
        }
    }

    /// One point of every path (called once a second).
    pub fn trail(&mut self, aircraft: &[Aircraft], intruders: &[(String, Ned)]) {
        for a in aircraft.iter().filter(|a| a.state.is_airborne()) {
            self.trails.entry(a.id.clone()).or_default().push(a.truth());
        }
        for (id, p) in intruders {
            self.intruder_trails.entry(id.clone()).or_default().push(*p);
        }
    }
}
