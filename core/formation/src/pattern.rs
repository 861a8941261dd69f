//! The slot pattern's orientation: a `leader`-frame pattern turns as a rigid body
//! toward the leader's heading, its outermost slot at no more than [`TURN_SPEED_M_S`]
//! and [`TURN_ACCEL_M_S2`]; a turning pattern adds `ω × r` to each slot's velocity.

use skein_model::geo::{Ned, wrap_pi};

/// Speed of the outermost slot of a `leader`-frame pattern while it turns, m/s.
pub const TURN_SPEED_M_S: f64 = 2.0;
/// Angular acceleration of a turning pattern at its outermost slot, m/s².
pub const TURN_ACCEL_M_S2: f64 = 0.5;

/// The pattern's heading and turn rate after `dt_s` (> 0) seconds, turning from
/// `heading_rad` at `rate_rad_s` toward `wanted_rad` (radians clockwise from north,
/// rad/s): the outermost of `offsets` (pattern frame, metres; at least 1 m counted)
/// moves at most `pace ×` [`TURN_SPEED_M_S`] and accelerates at most
/// [`TURN_ACCEL_M_S2`], and the turn stops on the wanted heading.
pub(super) fn turn(
    heading_rad: f64,
    rate_rad_s: f64,
    wanted_rad: f64,
    offsets: &[Ned],
    pace: f64,
    dt_s: f64,
) -> (f64, f64) {
    let reach = offsets
        .iter()
        .map(|o| o.horizontal_norm())
        .fold(1.0, f64::max);
    let (max_rate, max_accel) = (pace * TURN_SPEED_M_S / reach, TURN_ACCEL_M_S2 / reach);
    let error = wrap_pi(wanted_rad - heading_rad);
    // Turn rate that still stops on the wanted heading, then the change of rate the
    // angular acceleration allows.
    let wanted_rate = error.signum() * max_rate.min((2.0 * max_accel * error.abs()).sqrt());
    let rate = rate_rad_s + (wanted_rate - rate_rad_s).clamp(-max_accel * dt_s, max_accel * dt_s);
    let step = rate * dt_s;
    if step.abs() >= error.abs() && wanted_rate.abs() < max_accel * dt_s {
        (wanted_rad, 0.0)
    } else {
        (wrap_pi(heading_rad + step), rate)
    }
}

/// Velocity (m/s, swarm frame) of the point at `arm` (metres from the pattern's anchor)
/// of a pattern turning at `rate_rad_s` about the down axis: `ω × r`.
pub(super) fn spin(rate_rad_s: f64, arm: Ned) -> Ned {
    Ned::new(-rate_rad_s * arm.east_m, rate_rad_s * arm.north_m, 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{FRAC_PI_2, PI};

    /// A pattern reaching 10 m: at most 0.2 rad/s, 0.05 rad/s².
    fn wide() -> Vec<Ned> {
        vec![
            Ned::ZERO,
            Ned::new(0.0, 10.0, 0.0),
            Ned::new(-6.0, -8.0, 0.0),
        ]
    }

    #[test]
    fn a_turn_starts_at_the_acceleration_limit() {
        let (h, r) = turn(0.0, 0.0, FRAC_PI_2, &wide(), 1.0, 0.1);
        assert!((r - 0.005).abs() < 1e-12, "{r}");
        assert!((h - 0.0005).abs() < 1e-12, "{h}");
        // Toward the shorter side: from 10° to 350° turns left.
        let (_, r) = turn(
            10f64.to_radians(),
            0.0,
            350f64.to_radians(),
            &wide(),
            1.0,
            0.1,
        );
        assert!(r < 0.0, "{r}");
    }

    #[test]
    fn a_turn_cruises_at_the_outer_slot_speed_and_stops_on_the_heading() {
        let (mut h, mut r) = (0.0, 0.0);
        let mut top = 0.0f64;
        for _ in 0..400 {
            (h, r) = turn(h, r, PI * 0.9, &wide(), 1.0, 0.1);
            top = top.max(r.abs());
        }
        // Outermost slot at 10 m, TURN_SPEED_M_S 2 m/s: 0.2 rad/s.
        assert!((top - 0.2).abs() < 1e-9, "{top}");
        assert_eq!((h, r), (PI * 0.9, 0.0));
    }

    #[test]
    fn pace_slows_the_turn_and_zero_stops_it() {
        let (mut h, mut r) = (0.0, 0.0);
        for _ in 0..100 {
            (h, r) = turn(h, r, PI * 0.9, &wide(), 0.5, 0.1);
        }
        assert!((r - 0.1).abs() < 1e-9, "{r}");
        for _ in 0..100 {
            (h, r) = turn(h, r, PI * 0.9, &wide(), 0.0, 0.1);
        }
        assert_eq!(r, 0.0);
        let still = h;
        assert_eq!(turn(h, r, PI * 0.9, &wide(), 0.0, 0.1), (still, 0.0));
    }

    #[test]
    fn a_small_pattern_turns_as_if_one_metre_wide() {
        let (_, r) = turn(0.0, 0.0, 1.0, &[Ned::ZERO], 1.0, 0.1);
        assert!((r - TURN_ACCEL_M_S2 * 0.1).abs() < 1e-12, "{r}");
    }

    #[test]
    fn spin_is_omega_cross_r() {
        assert_eq!(
            spin(0.5, Ned::new(10.0, 0.0, -3.0)),
            Ned::new(0.0, 5.0, 0.0)
        );
        assert_eq!(spin(0.5, Ned::new(0.0, 4.0, 0.0)), Ned::new(-2.0, 0.0, 0.0));
        assert_eq!(spin(0.0, Ned::new(7.0, 4.0, 0.0)), Ned::new(-0.0, 0.0, 0.0));
    }
}
