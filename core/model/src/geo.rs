//! Geodetic points, NED vectors and local tangent-plane frames.
//!
//! Every PX4 has its own local NED origin (where its EKF started), so raw
//! `LOCAL_POSITION_NED` values of two vehicles cannot be compared. skein works in one
//! *swarm frame*, a NED tangent plane anchored at a swarm origin, and converts each
//! vehicle's positions and setpoints through geodetic coordinates (WGS84, `map_3d`):
//! swarm NED → geodetic → vehicle local NED. Velocities are carried over unrotated: two
//! tangent planes a few kilometres apart differ by well under a milliradian.

use serde::{Deserialize, Serialize};
use std::ops::{Add, Mul, Sub};

/// A geodetic position on the WGS84 ellipsoid.
///
/// `alt_amsl_m` is the altitude above mean sea level as PX4 reports it in
/// `GLOBAL_POSITION_INT.alt` (treated as ellipsoid height for the tangent-plane maths: the
/// geoid offset is a constant over a swarm's extent and cancels out).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct GeoPoint {
    /// Latitude, degrees, positive north.
    pub lat_deg: f64,
    /// Longitude, degrees, positive east.
    pub lon_deg: f64,
    /// Altitude above mean sea level, metres.
    pub alt_amsl_m: f64,
}

impl GeoPoint {
    /// Builds a point from degrees and metres.
    pub const fn new(lat_deg: f64, lon_deg: f64, alt_amsl_m: f64) -> Self {
        Self {
            lat_deg,
            lon_deg,
            alt_amsl_m,
        }
    }

    /// Builds a point from MAVLink integer encoding: latitude and longitude in degE7,
    /// altitude in millimetres (as in `GLOBAL_POSITION_INT` and `HOME_POSITION`).
    pub fn from_mavlink(lat_e7: i32, lon_e7: i32, alt_mm: i32) -> Self {
        Self::new(
            f64::from(lat_e7) * 1e-7,
            f64::from(lon_e7) * 1e-7,
            f64::from(alt_mm) * 1e-3,
        )
    }

    /// The MAVLink integer encoding `(lat degE7, lon degE7, alt mm)`.
    pub fn to_mavlink(&self) -> (i32, i32, i32) {
        (
            (self.lat_deg * 1e7).round() as i32,
            (self.lon_deg * 1e7).round() as i32,
            (self.alt_amsl_m * 1e3).round() as i32,
        )
    }
}

/// A vector in a north-east-down frame, metres (positions) or metres per second
/// (velocities, where the field names keep `_m` for brevity and the type says which).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, utoipa::ToSchema)]
pub struct Ned {
    /// North component, metres.
    pub north_m: f64,
    /// East component, metres.
    pub east_m: f64,
    /// Down component, metres (negative is up).
    pub down_m: f64,
}

impl Ned {
    /// The zero vector.
    pub const ZERO: Ned = Ned::new(0.0, 0.0, 0.0);

    /// Builds a vector from its north, east and down components.
    pub const fn new(north_m: f64, east_m: f64, down_m: f64) -> Self {
        Self {
            north_m,
            east_m,
            down_m,
        }
    }

    /// Euclidean length.
    pub fn norm(&self) -> f64 {
        (self.north_m * self.north_m + self.east_m * self.east_m + self.down_m * self.down_m).sqrt()
    }

    /// The same vector shortened to at most `max` (metres, or the vector's own unit).
    pub fn clamped_norm(self, max: f64) -> Ned {
        let n = self.norm();
        if n > max { self * (max / n) } else { self }
    }

    /// Length of the horizontal (north, east) part.
    pub fn horizontal_norm(&self) -> f64 {
        self.north_m.hypot(self.east_m)
    }

    /// Squared Euclidean length (cheaper than [`Ned::norm`] for comparisons).
    pub fn norm_squared(&self) -> f64 {
        self.north_m * self.north_m + self.east_m * self.east_m + self.down_m * self.down_m
    }

    /// Dot product.
    pub fn dot(&self, other: &Ned) -> f64 {
        self.north_m * other.north_m + self.east_m * other.east_m + self.down_m * other.down_m
    }

    /// Rotates the horizontal part by `yaw_rad` about the down axis (clockwise seen from
    /// above, as headings turn): a vector `(1, 0, 0)` rotated by π/2 points east.
    pub fn rotated_yaw(&self, yaw_rad: f64) -> Ned {
        let (s, c) = yaw_rad.sin_cos();
        Ned::new(
            c * self.north_m - s * self.east_m,
            s * self.north_m + c * self.east_m,
            self.down_m,
        )
    }

    /// True when every component is finite.
    pub fn is_finite(&self) -> bool {
        self.north_m.is_finite() && self.east_m.is_finite() && self.down_m.is_finite()
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

/// A local tangent-plane NED frame anchored at a geodetic origin.
///
/// The swarm frame is one (anchored at the swarm origin); each vehicle's PX4 local frame is
/// another (anchored at its EKF origin, see [`NedFrame::from_reference`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NedFrame {
    /// The geodetic point at NED `(0, 0, 0)`.
    pub origin: GeoPoint,
}

impl NedFrame {
    /// A frame anchored at `origin`.
    pub const fn new(origin: GeoPoint) -> Self {
        Self { origin }
    }

    /// The frame in which a known geodetic point `reference` has local coordinates
    /// `reference_local`: the way to recover a PX4 local origin from `HOME_POSITION`
    /// (which carries both the home's lat/lon/alt and its local x/y/z).
    ///
    /// The first guess steps `-reference_local` in the reference's own tangent plane; two
    /// fixed-point corrections remove the tilt between the two tangent planes (micrometres
    /// at a few metres, centimetres at a few kilometres).
    pub fn from_reference(reference: GeoPoint, reference_local: Ned) -> Self {
        let around_reference = NedFrame::new(reference);
        let mut frame = NedFrame::new(around_reference.to_geo(Ned::ZERO - reference_local));
        for _ in 0..2 {
            let error = frame.to_ned(&reference) - reference_local;
            frame = NedFrame::new(frame.to_geo(error));
        }
        frame
    }

    /// Geodetic → this frame's NED.
    pub fn to_ned(&self, p: &GeoPoint) -> Ned {
        let (n, e, d) = map_3d::geodetic2ned(
            p.lat_deg.to_radians(),
            p.lon_deg.to_radians(),
            p.alt_amsl_m,
            self.origin.lat_deg.to_radians(),
            self.origin.lon_deg.to_radians(),
            self.origin.alt_amsl_m,
            map_3d::Ellipsoid::WGS84,
        );
        Ned::new(n, e, d)
    }

    /// This frame's NED → geodetic.
    pub fn to_geo(&self, ned: Ned) -> GeoPoint {
        let (lat, lon, alt) = map_3d::ned2geodetic(
            ned.north_m,
            ned.east_m,
            ned.down_m,
            self.origin.lat_deg.to_radians(),
            self.origin.lon_deg.to_radians(),
            self.origin.alt_amsl_m,
            map_3d::Ellipsoid::WGS84,
        );
        GeoPoint::new(lat.to_degrees(), lon.to_degrees(), alt)
    }

    /// Re-expresses a position given in this frame in `other`, through its geodetic point.
    pub fn convert_to(&self, other: &NedFrame, ned: Ned) -> Ned {
        other.to_ned(&self.to_geo(ned))
    }
}

/// Wraps an angle in degrees to `[0, 360)`.
pub fn wrap_deg_360(deg: f64) -> f64 {
    let w = deg.rem_euclid(360.0);
    if w >= 360.0 { 0.0 } else { w }
}

/// Wraps an angle in radians to `(-π, π]`.
pub fn wrap_pi(rad: f64) -> f64 {
    let two_pi = std::f64::consts::TAU;
    let mut w = rad.rem_euclid(two_pi);
    if w > std::f64::consts::PI {
        w -= two_pi;
    }
    w
}

#[cfg(test)]
mod tests {
    use super::*;

    const ZURICH: GeoPoint = GeoPoint::new(47.397_742, 8.545_594, 488.0);

    #[test]
    fn ned_round_trip_through_geodetic() {
        let frame = NedFrame::new(ZURICH);
        for ned in [
            Ned::new(0.0, 0.0, 0.0),
            Ned::new(100.0, -250.0, -30.0),
            Ned::new(-1500.0, 1200.0, 5.0),
        ] {
            let back = frame.to_ned(&frame.to_geo(ned));
            assert!((back - ned).norm() < 1e-6, "{ned:?} came back as {back:?}");
        }
    }

    #[test]
    fn one_degree_of_latitude_is_about_111_km_north() {
        let frame = NedFrame::new(GeoPoint::new(47.0, 8.0, 0.0));
        let p = frame.to_ned(&GeoPoint::new(48.0, 8.0, 0.0));
        assert!((p.north_m - 111_200.0).abs() < 300.0, "{p:?}");
        assert!(p.east_m.abs() < 1.0);
    }

    #[test]
    fn frames_compare_vehicles_with_different_origins() {
        // Two vehicles whose EKFs started 10 m apart (east): the same geodetic point has
        // different local coordinates, and the conversion through the swarm frame agrees.
        let swarm = NedFrame::new(ZURICH);
        let a = NedFrame::new(swarm.to_geo(Ned::new(0.0, 0.0, 0.0)));
        let b = NedFrame::new(swarm.to_geo(Ned::new(0.0, 10.0, 0.0)));
        let target_swarm = Ned::new(20.0, 15.0, -10.0);
        let in_a = swarm.convert_to(&a, target_swarm);
        let in_b = swarm.convert_to(&b, target_swarm);
        assert!((in_a.east_m - in_b.east_m - 10.0).abs() < 1e-3);
        assert!((in_a.north_m - in_b.north_m).abs() < 1e-3);
        assert!((b.convert_to(&swarm, in_b) - target_swarm).norm() < 1e-6);
    }

    #[test]
    fn origin_recovered_from_home_position() {
        let true_origin = NedFrame::new(ZURICH);
        for home_local in [Ned::new(3.0, -4.0, -0.2), Ned::new(-2500.0, 1800.0, -40.0)] {
            let home_geo = true_origin.to_geo(home_local);
            let recovered = NedFrame::from_reference(home_geo, home_local);
            let err = true_origin.to_ned(&recovered.origin).norm();
            assert!(err < 1e-6, "{home_local:?}: origin off by {err} m");
        }
    }

    #[test]
    fn yaw_rotation_turns_north_into_east() {
        let v = Ned::new(1.0, 0.0, 2.0).rotated_yaw(std::f64::consts::FRAC_PI_2);
        assert!((v.north_m).abs() < 1e-12 && (v.east_m - 1.0).abs() < 1e-12 && v.down_m == 2.0);
    }

    #[test]
    fn angle_wrapping() {
        assert_eq!(wrap_deg_360(-90.0), 270.0);
        assert_eq!(wrap_deg_360(720.0), 0.0);
        assert!((wrap_pi(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
        assert!((wrap_pi(-0.5) + 0.5).abs() < 1e-12);
    }

    #[test]
    fn mavlink_integer_encoding_round_trips() {
        let (lat, lon, alt) = ZURICH.to_mavlink();
        assert_eq!((lat, lon, alt), (473_977_420, 85_455_940, 488_000));
        let back = GeoPoint::from_mavlink(lat, lon, alt);
        assert!((back.lat_deg - ZURICH.lat_deg).abs() < 1e-9);
    }
}
