//! The formation mirror: what a standby coordinator needs to fly on the active one's
//! formation where it was, should it take over (`/skein/formation` on DDS, see
//! `skein_dds::mirror`).
//!
//! The mirror is the spec, the reference point with its motion, the leader vehicle, the
//! pattern's heading and the slot assignment, stamped. Resuming puts the reference where
//! the members' targets are: a vehicle moves its last slot target on by its age for at
//! most [`TARGET_EXTRAPOLATION`] and then holds it, so the reference moves on by the
//! mirror's age up to that much, at its velocity while the members still move, else at
//! rest (its motion then accelerates it again as at the start). So the new coordinator's
//! first targets are where the members are aiming, without a jump.

use super::FormationEngine;
use crate::formation::{FormationSpec, Reference};
use crate::protocol::TARGET_EXTRAPOLATION;
use crate::protocol::age_of;
use serde::{Deserialize, Serialize};
use skein_model::geo::Ned;
use std::collections::BTreeMap;

/// The formation as a standby mirrors it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FormationMirror {
    /// The formation flown.
    pub spec: FormationSpec,
    /// Its reference point and motion (swarm-frame NED of the sender).
    pub reference: Reference,
    /// The leader vehicle, for a vehicle-led formation.
    pub leader: Option<String>,
    /// The pattern's heading, radians clockwise from north (leader-frame patterns).
    pub pattern_heading_rad: Option<f64>,
    /// Vehicle id → slot index.
    pub assignment: BTreeMap<String, usize>,
    /// When it was taken, wall-clock µs ([`crate::protocol::wall_us`]).
    pub stamp_us: u64,
}

impl FormationEngine {
    /// The formation to mirror, `None` when none is flown (or it has no reference yet).
    pub fn mirror(&self) -> Option<FormationMirror> {
        if !self.active {
            return None;
        }
        Some(FormationMirror {
            spec: self.spec.clone()?,
            reference: self.reference.clone()?,
            leader: self.leader.clone(),
            pattern_heading_rad: self.pattern_heading,
            assignment: self.assignment.clone(),
            stamp_us: crate::protocol::wall_us(),
        })
    }

    /// Flies `m` on: the formation, its reference where the members' targets are (see
    /// the module docs), its leader and slot assignment.
    pub fn resume(&mut self, m: FormationMirror) {
        self.deactivate();
        let age = age_of(m.stamp_us);
        let moved = age.min(TARGET_EXTRAPOLATION).as_secs_f64();
        let mut reference = m.reference;
        reference.position = reference.position + reference.velocity * moved;
        reference.heading_rad += reference.heading_rate_rad_s * moved;
        if age > TARGET_EXTRAPOLATION {
            reference.velocity = Ned::ZERO;
            reference.heading_rate_rad_s = 0.0;
        }
        self.spec = Some(m.spec);
        self.active = true;
        self.leader = m.leader;
        self.reference = Some(reference);
        self.pattern_heading = m.pattern_heading_rad;
        self.assignment = m.assignment;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formation::LeaderMotion;

    #[test]
    fn a_resumed_formation_goes_on_from_where_the_mirror_was() {
        let spec: FormationSpec = serde_json::from_value(serde_json::json!({
            "shape": "wedge", "spacing_m": 6.0, "leader": "virtual", "altitude_m": 12.0,
            "heading_deg": 0.0, "frame": "world", "offsets": []
        }))
        .unwrap();
        let mut a = FormationEngine::new(3.0);
        assert!(a.mirror().is_none());
        a.set(spec.clone());
        a.reference = Some(Reference {
            position: Ned::new(40.0, 0.0, -12.0),
            velocity: Ned::new(5.0, 0.0, 0.0),
            heading_rad: 0.0,
            heading_rate_rad_s: 0.0,
            motion: LeaderMotion::Hold,
        });
        a.assignment.insert("uav-1".into(), 0);
        let mut m = a.mirror().unwrap();
        m.stamp_us -= 1_000_000; // taken a second ago
        let text = serde_json::to_string(&m).unwrap();
        let back: FormationMirror = serde_json::from_str(&text).unwrap();
        assert_eq!(back, m);

        let mut b = FormationEngine::new(3.0);
        b.resume(back);
        assert!(b.is_active());
        assert_eq!(b.spec(), Some(&spec));
        let r = b.reference.as_ref().unwrap();
        // A second old: the members' targets stopped 0.5 s on, and so does the reference.
        assert!((r.position.north_m - 42.5).abs() < 0.1, "{r:?}");
        assert_eq!(r.velocity, Ned::ZERO);
        assert_eq!(b.assignment.get("uav-1"), Some(&0));
        b.deactivate();
        assert!(b.mirror().is_none());
    }
}
