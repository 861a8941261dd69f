//! The formation mirror: what a standby coordinator (and every agent) needs to fly on the
//! active one's formation where it was, should it fall silent (`/skein/formation` on DDS,
//! see `skein_dds::mirror` and `skein_dds::agent`).
//!
//! The mirror is the spec, the reference point with its motion, the leader vehicle, the
//! pattern's heading and the slot assignment, stamped. While no coordinator is heard, the
//! agents fly their vehicles' slots on from it ([`super::super::RideThrough`]); a standby
//! that takes the role resumes the formation where they are: its reference is the
//! mirror's, moved on by the mirror's age exactly as the agents move it, at speed. So
//! the new coordinator's first targets are where the members are already flying, without
//! a jump and without the formation stopping.

use super::FormationEngine;
use crate::{FormationSpec, Reference, RideThrough};
use serde::{Deserialize, Serialize};
use skein_model::safety::Geofence;
use skein_protocol::wall_us;
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
    /// When it was taken, wall-clock µs ([`skein_protocol::wall_us`]).
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
            stamp_us: skein_protocol::wall_us(),
        })
    }

    /// Flies `m` on: the formation, its reference moved on by the mirror's age as the
    /// riding agents move it (inside `geofence`), its leader, pattern heading and slot
    /// assignment (see the module docs); for [`super::RESUME_PACE_GRACE`] at the mirror's
    /// speed, however far the members are from where this coordinator sends them.
    pub fn resume(&mut self, m: FormationMirror, geofence: &Geofence) {
        self.deactivate();
        let mut ride = RideThrough::new(m, geofence);
        ride.advance_to(wall_us());
        let heading = ride.heading_rad();
        let reference = ride.reference().clone();
        let m = ride.mirror().clone();
        self.spec = Some(m.spec);
        self.active = true;
        self.leader = m.leader;
        // The previous coordinator's choice of leader stands.
        self.requested_led = self.leader.is_some();
        self.reference = Some(reference);
        self.pattern_heading = m.pattern_heading_rad.map(|_| heading);
        self.assignment = m.assignment;
        self.pace_grace_s = super::RESUME_PACE_GRACE.as_secs_f64();
    }
}

#[cfg(test)]
mod tests {
    use super::super::RESUME_PACE_GRACE;
    use super::*;
    use crate::LeaderMotion;
    use skein_model::geo::Ned;
    use std::time::Duration;

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
        b.resume(back, &Geofence::default());
        assert!(b.is_active());
        assert_eq!(b.spec(), Some(&spec));
        let r = b.reference.as_ref().unwrap();
        // A second old: the riding members flew on for that second, at speed (its motion
        // holds, so it brakes at the reference's 1.5 m/s² meanwhile: 5 m less 0.75 m).
        assert!((r.position.north_m - 44.25).abs() < 0.1, "{r:?}");
        assert!((r.velocity.north_m - 3.5).abs() < 0.05, "{r:?}");
        assert_eq!(b.assignment.get("uav-1"), Some(&0));
        b.deactivate();
        assert!(b.mirror().is_none());
    }

    #[test]
    fn a_resumed_formation_keeps_its_speed_while_the_members_still_ride_on_their_own() {
        let spec: FormationSpec = serde_json::from_value(serde_json::json!({
            "shape": "line", "spacing_m": 6.0, "leader": "virtual", "altitude_m": 12.0,
            "heading_deg": 0.0, "frame": "world", "offsets": []
        }))
        .unwrap();
        let mirror = FormationMirror {
            spec,
            reference: Reference {
                position: Ned::new(0.0, 0.0, -12.0),
                velocity: Ned::new(5.0, 0.0, 0.0),
                heading_rad: 0.0,
                heading_rate_rad_s: 0.0,
                motion: LeaderMotion::GoTo {
                    target: Ned::new(400.0, 0.0, -12.0),
                    speed_m_s: 5.0,
                },
            },
            leader: None,
            pattern_heading_rad: None,
            assignment: [("uav-1".to_string(), 0), ("uav-2".to_string(), 1)].into(),
            stamp_us: wall_us(),
        };
        let mut e = FormationEngine::new(3.0);
        e.resume(mirror, &Geofence::default());
        // The members are nowhere near where this coordinator sends them: their agents
        // still fly the old coordinator's formation (here: they stay 20 m behind).
        let members: BTreeMap<String, crate::Member> = ["uav-1", "uav-2"]
            .iter()
            .map(|id| {
                (
                    id.to_string(),
                    super::super::tests::member(-20.0, 0.0, -12.0),
                )
            })
            .collect();
        let speed = |e: &FormationEngine| e.reference.as_ref().unwrap().velocity.norm();
        // 2.5 s: longer than the pace takes to stop a formation from 5 m/s (it brakes
        // at 1.5 m/s²), shorter than the grace.
        assert!(RESUME_PACE_GRACE > Duration::from_millis(2500));
        for _ in 0..25 {
            e.tick(&members, 0.1, &Geofence::default());
        }
        assert!(
            speed(&e) > 4.9,
            "slowed within the grace: {} m/s",
            speed(&e)
        );
        // After it, a member that far from its slot stops the formation (the pace).
        for _ in 0..30 {
            e.tick(&members, 0.1, &Geofence::default());
        }
        assert!(
            speed(&e) < 2.5,
            "not paced after the grace: {} m/s",
            speed(&e)
        );
    }
}
