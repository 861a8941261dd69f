//! What the engine shows of itself: the formation's status as `GET /api/v1/formation`
//! serves it, its absent members and figures included.

use super::FormationEngine;
use crate::formation::{FormationStatus, Whereabouts};
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
        let mut min_sep: Option<f64> = None;
        for (i, a) in airborne.iter().enumerate() {
            for b in &airborne[i + 1..] {
                let d = (*a - *b).norm();
                min_sep = Some(min_sep.map_or(d, |m| m.min(d)));
            }
        }
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
