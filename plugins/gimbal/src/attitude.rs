//! Gimbal attitude: the rate-limited slew of the simulated gimbal and the Euler ↔
//! quaternion conversions of `GIMBAL_DEVICE_ATTITUDE_STATUS`.

use skein_plugin_sdk::geometry::wrap_deg_180;

/// A gimbal attitude, degrees, yaw relative to the vehicle (the frame of
/// `GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME`), plus angular rates in deg/s.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Attitude {
    /// Roll, degrees (a two-axis gimbal keeps it 0).
    pub roll_deg: f64,
    /// Pitch, degrees, positive up.
    pub pitch_deg: f64,
    /// Yaw relative to the vehicle's heading, degrees, positive clockwise seen from above,
    /// in `(-180, 180]`.
    pub yaw_deg: f64,
    /// Pitch rate, deg/s.
    pub pitch_rate_deg_s: f64,
    /// Yaw rate, deg/s.
    pub yaw_rate_deg_s: f64,
}

/// Moves an axis from `current` toward `target` by at most `max_rate_deg_s * dt_s`; on a
/// `continuous` axis (yaw all the way round) the short way, wrapped to `(-180, 180]`.
/// Returns the new angle and the rate actually used (deg/s).
pub fn slew(
    current: f64,
    target: f64,
    max_rate_deg_s: f64,
    dt_s: f64,
    continuous: bool,
) -> (f64, f64) {
    if dt_s <= 0.0 {
        return (current, 0.0);
    }
    let error = if continuous {
        wrap_deg_180(target - current)
    } else {
        target - current
    };
    let max_step = max_rate_deg_s * dt_s;
    let step = error.clamp(-max_step, max_step);
    let next = current + step;
    (
        if continuous { wrap_deg_180(next) } else { next },
        step / dt_s,
    )
}

/// The quaternion `[w, x, y, z]` of a Tait-Bryan (Z-Y-X: yaw, then pitch, then roll)
/// attitude given in degrees, as MAVLink carries attitudes.
pub fn quaternion_from_euler(roll_deg: f64, pitch_deg: f64, yaw_deg: f64) -> [f32; 4] {
    let (sr, cr) = (roll_deg.to_radians() / 2.0).sin_cos();
    let (sp, cp) = (pitch_deg.to_radians() / 2.0).sin_cos();
    let (sy, cy) = (yaw_deg.to_radians() / 2.0).sin_cos();
    [
        (cr * cp * cy + sr * sp * sy) as f32,
        (sr * cp * cy - cr * sp * sy) as f32,
        (cr * sp * cy + sr * cp * sy) as f32,
        (cr * cp * sy - sr * sp * cy) as f32,
    ]
}

/// `(roll, pitch, yaw)` in degrees of a quaternion `[w, x, y, z]` (normalised first; the
/// identity when it is all zeros or not finite).
pub fn euler_from_quaternion(q: [f32; 4]) -> (f64, f64, f64) {
    let [w, x, y, z] = q.map(f64::from);
    let n = (w * w + x * x + y * y + z * z).sqrt();
    if !(n.is_finite() && n > 1e-9) {
        return (0.0, 0.0, 0.0);
    }
    let (w, x, y, z) = (w / n, x / n, y / n, z / n);
    let roll = (2.0 * (w * x + y * z)).atan2(1.0 - 2.0 * (x * x + y * y));
    let pitch = (2.0 * (w * y - z * x)).clamp(-1.0, 1.0).asin();
    let yaw = (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z));
    (roll.to_degrees(), pitch.to_degrees(), yaw.to_degrees())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slew_is_rate_limited_and_lands_exactly() {
        let (mut a, mut t) = (0.0, 0.0);
        while a > -45.0 {
            let (next, rate) = slew(a, -45.0, 30.0, 0.1, false);
            assert!((-30.0 - 1e-9..=0.0).contains(&rate));
            a = next;
            t += 0.1;
        }
        assert_eq!(a, -45.0);
        assert!((t - 1.5_f64).abs() < 1e-6, "took {t} s");
    }

    #[test]
    fn continuous_yaw_takes_the_short_way() {
        let (y, rate) = slew(170.0, -170.0, 100.0, 0.05, true);
        assert!((y - 175.0).abs() < 1e-9);
        assert!(rate > 0.0);
        let (y, _) = slew(178.0, -178.0, 100.0, 0.05, true);
        assert!((y + 178.0).abs() < 1e-9, "{y}");
    }

    #[test]
    fn quaternion_round_trip() {
        for (r, p, y) in [(0.0, -45.0, 0.0), (0.0, 10.0, 120.0), (5.0, -80.0, -170.0)] {
            let q = quaternion_from_euler(r, p, y);
            let (r2, p2, y2) = euler_from_quaternion(q);
            assert!((r - r2).abs() < 1e-3 && (p - p2).abs() < 1e-3, "{r2} {p2}");
            assert!(wrap_deg_180(y - y2).abs() < 1e-3, "{y} vs {y2}");
        }
        assert_eq!(quaternion_from_euler(0.0, 0.0, 0.0), [1.0, 0.0, 0.0, 0.0]);
        assert_eq!(euler_from_quaternion([0.0; 4]), (0.0, 0.0, 0.0));
    }
}
