//! Land detector (PX4 `land_detector`): take-off and landing detection.

#![allow(deprecated)]

use super::*;

impl Vehicle {
    pub(super) fn land_detector(&mut self, now: Instant, dt: f64, out: &mut Outbox) {
        if self.landed {
            if self.armed && self.pos.down_m < -TAKEOFF_DETECT_M {
                self.landed = false;
                self.took_off = true;
                self.landed_at = None;
                self.ground_contact_s = 0.0;
                self.say(
                    now,
                    MavSeverity::MAV_SEVERITY_INFO,
                    &crate::px4_events::TAKEOFF_DETECTED,
                    "Takeoff detected",
                    [0; 40],
                    out,
                );
            }
            return;
        }
        let contact = self.pos.down_m >= -0.05 && self.vel.down_m.abs() < 0.3;
        if !self.armed {
            if self.pos.down_m >= 0.0 {
                // Motors off: it fell; it lies on the ground now.
                self.landed = true;
                self.landed_at = Some(now);
                self.vel = Ned::ZERO;
            }
            return;
        }
        let not_climbing = self.vel_sp_smooth.down_m >= -0.05;
        if contact && not_climbing {
            self.ground_contact_s += dt;
            if self.ground_contact_s >= LAND_DETECT_S {
                self.landed = true;
                self.landed_at = Some(now);
                self.ground_contact_s = 0.0;
                self.vel = Ned::ZERO;
                self.say(
                    now,
                    MavSeverity::MAV_SEVERITY_INFO,
                    &crate::px4_events::LANDING_DETECTED,
                    "Landing detected",
                    [0; 40],
                    out,
                );
            }
        } else {
            self.ground_contact_s = 0.0;
        }
    }
}
