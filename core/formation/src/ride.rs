//! Flying a formation on from its mirror, where its coordinator is not heard: the agents'
//! ride-through and a standby's resumption compute the same formation from the same
//! [`FormationMirror`].
//!
//! Every member of a formation flies the same plan: the reference point `P(t)` moves by
//! its motion (go-to, waypoints, orbit, hold) under the same limits and fence, and each
//! slot is a fixed offset from it in the pattern's frame, turned with the pattern's
//! heading. A [`RideThrough`] advances the mirrored reference exactly as the coordinator's
//! engine does when no member lags (pace 1, no hazard shift), so an agent that stops
//! hearing its coordinator can keep its vehicles on their slots, and predict where its
//! silent neighbours are, for as long as it is configured to ride through; and a standby
//! that takes the role resumes the formation where the riding members are.
//!
//! Offsets are taken from what the members were last sent: a slot target (or a
//! neighbour's last report) is placed relative to the reference *at its stamp*, which is
//! the reference stepped forward from the mirror's stamp (or, for a place older than the
//! mirror, moved back along its velocity). A member in the middle of a formation change
//! rides its place on the change's plan frozen where it was: every member's plan was
//! separated at each instant, and all freeze within a target period of each other.
//!
//! What a ride-through does not know: members lagging (the coordinator slows the
//! reference for them), hazards (it shifts the slots around them), and commands sent
//! meanwhile. That is why it lasts seconds, not minutes, and why the vehicles' own
//! separation and geofence checks stay on.

use super::FormationMirror;
use super::pattern::spin;
use super::reference::{Reference, inner_fence};
use super::spec::FormationFrame;
use skein_model::geo::{Ned, wrap_pi};
use skein_model::safety::Geofence;

/// Longest step of the reference point's integration, s (the coordinator's formation
/// tick is 0.1 s; its reference moves at up to 1.5 m/s² within a step).
pub const RIDE_STEP_S: f64 = 0.05;

/// A formation flown on from its mirror (see the module docs). Times are wall-clock µs of
/// this process ([`skein_protocol::wall_us`]), positions swarm-frame NED of this process.
#[derive(Debug, Clone)]
pub struct RideThrough {
    mirror: FormationMirror,
    /// The reference point at `at_us`.
    reference: Reference,
    /// The pattern's heading at `at_us`, radians clockwise from north.
    heading_rad: f64,
    at_us: u64,
    /// The fence the reference point stays in (the geofence shrunk by the pattern's
    /// reach, as the engine does).
    fence: Geofence,
}

impl RideThrough {
    /// Starts from `mirror` (already in this process's frame and clock), inside
    /// `geofence`.
    pub fn new(mirror: FormationMirror, geofence: &Geofence) -> Self {
        let capacity = mirror.spec.capacity(mirror.assignment.len().max(1));
        let fence = inner_fence(geofence, &mirror.spec.offsets(capacity));
        let heading_rad = mirror
            .pattern_heading_rad
            .unwrap_or(match mirror.spec.frame {
                FormationFrame::World => mirror.spec.heading_deg.to_radians(),
                FormationFrame::Leader => mirror.reference.heading_rad,
            });
        RideThrough {
            reference: mirror.reference.clone(),
            heading_rad,
            at_us: mirror.stamp_us,
            mirror,
            fence,
        }
    }

    /// The mirror it flies.
    pub fn mirror(&self) -> &FormationMirror {
        &self.mirror
    }

    /// The time it has been advanced to, wall-clock µs.
    pub fn at_us(&self) -> u64 {
        self.at_us
    }

    /// The reference point as of [`RideThrough::at_us`].
    pub fn reference(&self) -> &Reference {
        &self.reference
    }

    /// The pattern's heading as of [`RideThrough::at_us`], radians clockwise from north.
    pub fn heading_rad(&self) -> f64 {
        self.heading_rad
    }

    /// Advances the reference to `now_us` as the coordinator would (never backwards), in
    /// steps of at most [`RIDE_STEP_S`]. A `leader`-frame pattern turns with the
    /// reference point's heading.
    pub fn advance_to(&mut self, now_us: u64) {
        if now_us <= self.at_us {
            return;
        }
        let mut left = (now_us - self.at_us) as f64 / 1e6;
        let before = self.reference.heading_rad;
        while left > 1e-9 {
            let dt = left.min(RIDE_STEP_S);
            self.reference.step(dt, &self.fence);
            left -= dt;
        }
        if self.mirror.spec.frame == FormationFrame::Leader {
            self.heading_rad += wrap_pi(self.reference.heading_rad - before);
        }
        self.at_us = now_us;
    }

    /// This ride advanced to `t_us`: forward by [`RideThrough::advance_to`], or, for a
    /// time before it, moved back along its velocity and turn rate (a place stamped a
    /// little before the mirror was taken).
    pub fn at(&self, t_us: u64) -> RideThrough {
        let mut r = self.clone();
        if t_us >= self.at_us {
            r.advance_to(t_us);
        } else {
            let back = (self.at_us - t_us) as f64 / 1e6;
            r.reference.position = r.reference.position - r.reference.velocity * back;
            let turned = r.reference.heading_rate_rad_s * back;
            r.reference.heading_rad -= turned;
            if self.mirror.spec.frame == FormationFrame::Leader {
                r.heading_rad -= turned;
            }
            r.at_us = t_us;
        }
        r
    }

    /// The offset from the reference point, pattern frame (forward, right, down; metres),
    /// of a place `p` (swarm-frame NED) at this ride's time.
    pub fn offset_of(&self, p: Ned) -> Ned {
        (p - self.reference.position).rotated_yaw(-self.heading_rad)
    }

    /// Where the place of `offset` (pattern frame) is at this ride's time, and its
    /// velocity: the reference's plus the pattern's turn (`ω × arm`). Swarm-frame NED,
    /// metres and m/s.
    pub fn place(&self, offset: Ned) -> (Ned, Ned) {
        let arm = offset.rotated_yaw(self.heading_rad);
        let rate = match self.mirror.spec.frame {
            FormationFrame::Leader => self.reference.heading_rate_rad_s,
            FormationFrame::World => 0.0,
        };
        (
            self.reference.position + arm,
            self.reference.velocity + spin(rate, arm),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{FormationEngine, LeaderMotion, Member};
    use std::collections::BTreeMap;

    fn fence() -> Geofence {
        Geofence::default()
    }

    fn wedge() -> crate::FormationSpec {
        serde_json::from_value(serde_json::json!({
            "shape": "wedge", "spacing_m": 6.0, "leader": "virtual", "altitude_m": 12.0,
            "heading_deg": 0.0, "frame": "leader", "offsets": []
        }))
        .unwrap()
    }

    /// Members that are exactly where the engine sent them (no lag).
    fn flown(e: &mut FormationEngine, members: &mut BTreeMap<String, Member>, dt: f64) {
        let slots = e.tick(members, dt, &fence());
        for (id, s) in slots {
            let m = members.get_mut(&id).unwrap();
            m.position = s.position;
            m.velocity = s.velocity;
        }
    }

    #[test]
    fn a_ride_from_the_mirror_flies_the_slots_the_engine_flies() {
        for motion in [
            LeaderMotion::GoTo {
                target: Ned::new(400.0, 150.0, -12.0),
                speed_m_s: 5.0,
            },
            LeaderMotion::Orbit {
                centre: Ned::new(0.0, 30.0, -12.0),
                radius_m: 30.0,
                speed_m_s: 5.0,
                clockwise: true,
            },
        ] {
            let mut e = FormationEngine::default();
            e.set(wedge());
            let mut members: BTreeMap<String, Member> = (0..3)
                .map(|i| {
                    (
                        format!("uav-{}", i + 1),
                        Member {
                            position: Ned::new(-6.0 * i as f64, 3.0 * i as f64, -12.0),
                            velocity: Ned::ZERO,
                            heading_rad: 0.0,
                            silence: std::time::Duration::ZERO,
                            target: None,
                            ride_through: std::time::Duration::from_secs(4),
                        },
                    )
                })
                .collect();
            for _ in 0..300 {
                flown(&mut e, &mut members, 0.1);
            }
            e.set_motion(motion.clone()).unwrap();
            for _ in 0..300 {
                flown(&mut e, &mut members, 0.1);
            }
            // At speed: mirror it, and note where each member was sent.
            let mirror = e.mirror().unwrap();
            let mut ride = RideThrough::new(mirror.clone(), &fence());
            let offsets: BTreeMap<String, Ned> = members
                .iter()
                .map(|(id, m)| (id.clone(), ride.offset_of(m.position)))
                .collect();
            // 3 s on: the engine's slots and the ride's places agree.
            for _ in 0..30 {
                flown(&mut e, &mut members, 0.1);
            }
            ride.advance_to(mirror.stamp_us + 3_000_000);
            for (id, m) in &members {
                let (p, v) = ride.place(offsets[id]);
                assert!(
                    (p - m.position).norm() < 0.3,
                    "{motion:?}: {id} ride {p:?} engine {:?}",
                    m.position
                );
                assert!((v - m.velocity).norm() < 0.3, "{motion:?}: {id} {v:?}");
            }
        }
    }

    #[test]
    fn a_place_older_than_the_mirror_is_moved_back_along_the_velocity() {
        let mut e = FormationEngine::default();
        e.set(wedge());
        let mut mirror_reference = Reference::at(Ned::new(10.0, 0.0, -12.0), 0.0);
        mirror_reference.velocity = Ned::new(5.0, 0.0, 0.0);
        mirror_reference.motion = LeaderMotion::GoTo {
            target: Ned::new(500.0, 0.0, -12.0),
            speed_m_s: 5.0,
        };
        let mirror = FormationMirror {
            spec: wedge(),
            reference: mirror_reference,
            leader: None,
            pattern_heading_rad: Some(0.0),
            assignment: BTreeMap::from([("uav-1".to_string(), 0)]),
            stamp_us: 10_000_000,
        };
        let ride = RideThrough::new(mirror, &fence());
        let before = ride.at(9_800_000);
        assert!((before.reference().position.north_m - 9.0).abs() < 1e-9);
        // A member 6 m behind the reference 0.2 s before the mirror: 6 m behind at any
        // time, 2 s later 16 m further north.
        let offset = before.offset_of(Ned::new(3.0, 0.0, -12.0));
        assert!(
            (offset - Ned::new(-6.0, 0.0, 0.0)).norm() < 1e-9,
            "{offset:?}"
        );
        let later = ride.at(12_000_000);
        let (p, v) = later.place(offset);
        assert!((p.north_m - 14.0).abs() < 1e-6, "{p:?}");
        assert!((v.north_m - 5.0).abs() < 1e-9);
    }
}
