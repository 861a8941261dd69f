//! Small geometry for payloads: NED vectors, look angles (azimuth/elevation) from one point
//! to another, angle wrapping, and a local geodetic ↔ NED conversion.
//!
//! Conventions: NED = north, east, down, metres; azimuth = degrees clockwise from north;
//! elevation = degrees above the horizontal (negative looks down), which is also the
//! gimbal pitch convention of MAVLink's Gimbal Protocol v2 (pitch positive up).

use serde::{Deserialize, Serialize};
use std::ops::{Add, Mul, Sub};

/// A vector in a north-east-down frame, metres.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Ned {
    /// North component, metres.
    pub north_m: f64,
    /// East component, metres.
    pub east_m: f64,
    /// Down component, metres (negative is up).
    pub down_m: f64,
}

impl Ned {
    /// Builds a vector from north, east, down.
    pub const fn new(north_m: f64, east_m: f64, down_m: f64) -> Ned {
        Ned {
            north_m,
            east_m,
            down_m,
        }
    }

    /// Euclidean length, metres.
    pub fn norm(&self) -> f64 {
        self.dot(self).sqrt()
    }

    /// Length of the horizontal (north, east) part, metres.
    pub fn horizontal_norm(&self) -> f64 {
        self.north_m.hypot(self.east_m)
    }

    /// Dot product.
    pub fn dot(&self, o: &Ned) -> f64 {
        self.north_m * o.north_m + self.east_m * o.east_m + self.down_m * o.down_m
    }

    /// Cross product (right-handed NED: north × east = down).
    pub fn cross(&self, o: &Ned) -> Ned {
        Ned::new(
            self.east_m * o.down_m - self.down_m * o.east_m,
            self.down_m * o.north_m - self.north_m * o.down_m,
            self.north_m * o.east_m - self.east_m * o.north_m,
        )
    }
}

impl Add for Ned {
    type Output = Ned;
    fn add(self, o: Ned) -> Ned {
        Ned::new(
            self.north_m + o.north_m,
            self.east_m + o.east_m,
            self.down_m + o.down_m,
        )
    }
}

impl Sub for Ned {
    type Output = Ned;
    fn sub(self, o: Ned) -> Ned {
        Ned::new(
            self.north_m - o.north_m,
            self.east_m - o.east_m,
            self.down_m - o.down_m,
        )
    }
}

impl Mul<f64> for Ned {
    type Output = Ned;
    fn mul(self, k: f64) -> Ned {
        Ned::new(self.north_m * k, self.east_m * k, self.down_m * k)
    }
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

/// A geodetic position (WGS84).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GeoPoint {
    /// Latitude, degrees.
    pub lat_deg: f64,
    /// Longitude, degrees.
    pub lon_deg: f64,
    /// Altitude above mean sea level, metres.
    pub alt_amsl_m: f64,
}

const WGS84_A_M: f64 = 6_378_137.0;
const WGS84_E2: f64 = 6.694_379_990_14e-3;

/// Radii of curvature (meridian, prime vertical) at latitude `lat_deg`, metres.
fn radii(lat_deg: f64) -> (f64, f64) {
    let s = lat_deg.to_radians().sin();
    let w = 1.0 - WGS84_E2 * s * s;
    (
        WGS84_A_M * (1.0 - WGS84_E2) / (w * w.sqrt()),
        WGS84_A_M / w.sqrt(),
    )
}

/// `p` in the local NED tangent plane at `origin` (WGS84 radii of curvature at the origin;
/// error under 0.1 m within 1 km, ignoring the Earth's curvature in `down`).
pub fn geodetic_to_local(origin: GeoPoint, p: GeoPoint) -> Ned {
    let (m, n) = radii(origin.lat_deg);
    Ned::new(
        (p.lat_deg - origin.lat_deg).to_radians() * m,
        (p.lon_deg - origin.lon_deg).to_radians() * n * origin.lat_deg.to_radians().cos(),
        origin.alt_amsl_m - p.alt_amsl_m,
    )
}

/// The inverse of [`geodetic_to_local`].
pub fn local_to_geodetic(origin: GeoPoint, ned: Ned) -> GeoPoint {
    let (m, n) = radii(origin.lat_deg);
    GeoPoint {
        lat_deg: origin.lat_deg + (ned.north_m / m).to_degrees(),
        lon_deg: origin.lon_deg
            + (ned.east_m / (n * origin.lat_deg.to_radians().cos())).to_degrees(),
        alt_amsl_m: origin.alt_amsl_m - ned.down_m,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn look_angles_of_the_cardinal_directions() {
        let o = Ned::new(0.0, 0.0, 0.0);
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
            let back = look_angles(Ned::default(), d * 7.0).unwrap();
            assert!((back.azimuth_deg - az).abs() < 1e-9);
            assert!((back.elevation_deg - el).abs() < 1e-9);
            assert!((back.range_m - 7.0).abs() < 1e-9);
        }
    }

    #[test]
    fn cross_product_is_right_handed() {
        let c = Ned::new(1.0, 0.0, 0.0).cross(&Ned::new(0.0, 1.0, 0.0));
        assert_eq!(c, Ned::new(0.0, 0.0, 1.0));
    }

    #[test]
    fn wrapping() {
        assert_eq!(wrap_deg_180(190.0), -170.0);
        assert_eq!(wrap_deg_180(-180.0), 180.0);
        assert_eq!(wrap_deg_180(540.0), 180.0);
        assert_eq!(wrap_deg_360(-10.0), 350.0);
    }

    #[test]
    fn local_geodetic_round_trip_and_scale() {
        let origin = GeoPoint {
            lat_deg: 47.3977,
            lon_deg: 8.5456,
            alt_amsl_m: 488.0,
        };
        let ned = Ned::new(120.0, -340.0, -25.0);
        let back = geodetic_to_local(origin, local_to_geodetic(origin, ned));
        assert!((back - ned).norm() < 1e-6);
        // 0.001° of latitude is about 111 m.
        let p = GeoPoint {
            lat_deg: origin.lat_deg + 0.001,
            ..origin
        };
        assert!((geodetic_to_local(origin, p).north_m - 111.2).abs() < 0.3);
    }
}
