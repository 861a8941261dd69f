//! Angles: wrapping, and the look angles (azimuth, elevation, range) between two NED
//! points.
//!
//! Conventions: azimuth = degrees clockwise from north; elevation = degrees above the
//! horizontal (negative looks down), which is also the gimbal pitch convention of
//! MAVLink's Gimbal Protocol v2 (pitch positive up).

use crate::Ned;
use serde::{Deserialize, Serialize};

/// Wraps degrees to `(-180, 180]`.
pub fn wrap_deg_180(deg: f64) -> f64 {
    let w = (deg + 180.0).rem_euclid(360.0) - 180.0;
    if w == -180.0 { 180.0 } else { w }
}

/// Wraps degrees to `[0, 360)`.
pub fn wrap_deg_360(deg: f64) -> f64 {
    let w = deg.rem_euclid(360.0);
    if w >= 360.0 { 0.0 } else { w }
}

/// Wraps radians to `(-π, π]`.
pub fn wrap_pi(rad: f64) -> f64 {
    let two_pi = std::f64::consts::TAU;
    let mut w = rad.rem_euclid(two_pi);
    if w > std::f64::consts::PI {
        w -= two_pi;
    }
    w
}

/// Direction and distance from one point to another.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LookAngles {
    /// Degrees clockwise from north, `[0, 360)`.
    pub azimuth_deg: f64,
    /// Degrees above the horizontal, `[-90, 90]` (negative: the target is below).
    pub elevation_deg: f64,
    /// Straight-line distance, metres.
    pub range_m: f64,
}

/// The look angles from `from` to `to` (both NED in the same frame), `None` when they
/// coincide (closer than 1 mm).
pub fn look_angles(from: Ned, to: Ned) -> Option<LookAngles> {
    let d = to - from;
    let range_m = d.norm();
    if range_m < 1e-3 {
        return None;
    }
    Some(LookAngles {
        azimuth_deg: wrap_deg_360(d.east_m.atan2(d.north_m).to_degrees()),
        elevation_deg: (-d.down_m).atan2(d.horizontal_norm()).to_degrees(),
        range_m,
    })
}

/// The unit vector pointing at `azimuth_deg` (clockwise from north) and `elevation_deg`
/// (above the horizontal).
pub fn direction(azimuth_deg: f64, elevation_deg: f64) -> Ned {
    let (sa, ca) = azimuth_deg.to_radians().sin_cos();
    let (se, ce) = elevation_deg.to_radians().sin_cos();
    Ned::new(ce * ca, ce * sa, -se)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn look_angles_of_the_cardinal_directions() {
        let o = Ned::ZERO;
        let east_below = look_angles(o, Ned::new(0.0, 10.0, 10.0)).unwrap();
        assert!((east_below.azimuth_deg - 90.0).abs() < 1e-9);
        assert!((east_below.elevation_deg + 45.0).abs() < 1e-9);
        let west = look_angles(o, Ned::new(0.0, -5.0, 0.0)).unwrap();
        assert!((west.azimuth_deg - 270.0).abs() < 1e-9);
        assert!(look_angles(o, o).is_none());
    }

    #[test]
    fn direction_inverts_look_angles() {
        for (az, el) in [(0.0, 0.0), (135.0, -30.0), (300.0, 60.0)] {
            let d = direction(az, el);
            let back = look_angles(Ned::ZERO, d * 7.0).unwrap();
            assert!((back.azimuth_deg - az).abs() < 1e-9);
            assert!((back.elevation_deg - el).abs() < 1e-9);
            assert!((back.range_m - 7.0).abs() < 1e-9);
        }
    }

    #[test]
    fn wrapping() {
        assert_eq!(wrap_deg_180(190.0), -170.0);
        assert_eq!(wrap_deg_180(-180.0), 180.0);
        assert_eq!(wrap_deg_180(540.0), 180.0);
        assert_eq!(wrap_deg_360(-10.0), 350.0);
        assert_eq!(wrap_deg_360(-90.0), 270.0);
        assert_eq!(wrap_deg_360(720.0), 0.0);
        assert!((wrap_pi(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
        assert!((wrap_pi(-0.5) + 0.5).abs() < 1e-12);
    }
}
