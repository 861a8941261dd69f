//! What the engine shows of itself: the formation's status as `GET /api/v1/formation`
//! serves it, its absent members and figures included.

use super::FormationEngine;
use crate::{FormationStatus, Whereabouts};
use skein_model::geo::Ned;
use std::collections::BTreeMap;

impl FormationEngine {
    /// The status of the last tick, without absent members (see
    /// [`FormationEngine::status_with`]).
    pub fn status(&self, airborne: &[Ned]) -> FormationStatus {
        self.status_with(airborne, &BTreeMap::new())
    }

    /// The status of the last tick. `airborne` are the positions of all airborne vehicles
    /// (swarm-frame NED, for the separation metric); `whereabouts` says where each absent
    /// member ([`FormationEngine::absent_ids`]) is and why it is out (one the map does not
    /// name is not listed). An absent member's error is measured to where its slot is now:
    /// its offset from the reference point when it dropped out, moved and turned with the
    /// formation since.
    pub fn status_with(
        &self,
        airborne: &[Ned],
        whereabouts: &BTreeMap<String, Whereabouts>,
    ) -> FormationStatus {
        let place = |offset: Ned| {
            let r = self.reference.as_ref().filter(|_| self.is_active())?;
            Some(r.position + offset.rotated_yaw(self.pattern_heading.unwrap_or(r.heading_rad)))
        };
        let absent = self.absences.list(place, whereabouts);
        let rms = |errors: &[f64]| {
            (!errors.is_empty())
                .then(|| (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt())
        };
        let flying: Vec<f64> = self.last.iter().map(|m| m.error_m).collect();
        let mut all = flying.clone();
        all.extend(absent.iter().filter_map(|a| a.error_m));
        let min_sep = closest_pair_m(airborne);
        FormationStatus {
            spec: self.spec.clone(),
            active: self.is_active(),
            leader_id: self.leader.clone(),
            reference: self.reference.clone().filter(|_| self.is_active()),
            members: self.last.clone(),
            absent,
            rms_error_m: rms(&all),
            members_rms_error_m: rms(&flying),
            min_separation_m: min_sep,
            transition_progress: self.transition.as_ref().map(|t| t.progress().0),
            pending: self.pending.clone(),
            hazards: self.hazards.clone(),
            blocked: self.blocked.clone(),
        }
    }
}

/// The smallest distance between two of `points` (metres; `None` for fewer than two), by
/// a sweep along north: sorted by north, each point is compared only with the next ones
/// less than the best distance so far to its north. Exact, as the pairwise scan it
/// replaces, and O(n log n) for a swarm spread over an area instead of O(n²) (a thousand
/// vehicles were half a million distances per formation tick).
fn closest_pair_m(points: &[Ned]) -> Option<f64> {
    let mut sorted = points.to_vec();
    sorted.sort_unstable_by(|a, b| a.north_m.total_cmp(&b.north_m));
    let mut best = f64::INFINITY;
    for (i, a) in sorted.iter().enumerate() {
        for b in &sorted[i + 1..] {
            // Not `>=`: with `best` infinite every pair must still be measured.
            if b.north_m - a.north_m > best {
                break;
            }
            best = best.min((*a - *b).norm());
        }
    }
    (sorted.len() >= 2).then_some(best)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    /// The sweep finds what comparing every pair finds, on scattered swarms and on
    /// degenerate ones (a line along east, where every point shares its north).
    #[test]
    fn the_sweep_finds_the_pairwise_minimum() {
        let mut rng = SmallRng::seed_from_u64(7);
        let mut next = || rng.random::<f64>();
        for n in [0usize, 1, 2, 3, 10, 200] {
            let points: Vec<Ned> = (0..n)
                .map(|_| Ned::new(next() * 300.0, next() * 300.0, -10.0 - next() * 5.0))
                .collect();
            let mut pairwise: Option<f64> = None;
            for (i, a) in points.iter().enumerate() {
                for b in &points[i + 1..] {
                    let d = (*a - *b).norm();
                    pairwise = Some(pairwise.map_or(d, |m: f64| m.min(d)));
                }
            }
            assert_eq!(closest_pair_m(&points), pairwise, "{n} points");
        }
        let line: Vec<Ned> = (0..5)
            .map(|i| Ned::new(0.0, 4.0 * f64::from(i), 0.0))
            .collect();
        assert_eq!(closest_pair_m(&line), Some(4.0));
    }
}
