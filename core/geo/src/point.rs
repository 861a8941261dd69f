//! [`GeoPoint`]: a geodetic position on the WGS84 ellipsoid, and its MAVLink encoding.

use serde::{Deserialize, Serialize};

/// A geodetic position on the WGS84 ellipsoid.
///
/// `alt_amsl_m` is the altitude above mean sea level as PX4 reports it in
/// `GLOBAL_POSITION_INT.alt` (treated as ellipsoid height for the tangent-plane maths: the
/// geoid offset is a constant over a swarm's extent and cancels out).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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

    /// Earth-centred, earth-fixed coordinates `[x, y, z]`, metres (WGS84; the frame
    /// `earth` of ROS REP 105).
    pub fn to_ecef(&self) -> [f64; 3] {
        let (x, y, z) = map_3d::geodetic2ecef(
            self.lat_deg.to_radians(),
            self.lon_deg.to_radians(),
            self.alt_amsl_m,
            map_3d::Ellipsoid::WGS84,
        );
        [x, y, z]
    }

    /// The point at earth-centred, earth-fixed `[x, y, z]` metres (WGS84; RTCM's
    /// reference station coordinates); the altitude is the ellipsoid height.
    pub fn from_ecef(ecef_m: [f64; 3]) -> Self {
        let (lat, lon, alt) =
            map_3d::ecef2geodetic(ecef_m[0], ecef_m[1], ecef_m[2], map_3d::Ellipsoid::WGS84);
        Self::new(lat.to_degrees(), lon.to_degrees(), alt)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mavlink_integer_encoding_round_trips() {
        let zurich = GeoPoint::new(47.397_742, 8.545_594, 488.0);
        let (lat, lon, alt) = zurich.to_mavlink();
        assert_eq!((lat, lon, alt), (473_977_420, 85_455_940, 488_000));
        let back = GeoPoint::from_mavlink(lat, lon, alt);
        assert!((back.lat_deg - zurich.lat_deg).abs() < 1e-9);
    }

    #[test]
    fn ecef_of_known_points() {
        // On the equator at the prime meridian: x is the semi-major axis.
        let [x, y, z] = GeoPoint::new(0.0, 0.0, 0.0).to_ecef();
        assert!((x - 6_378_137.0).abs() < 1e-6 && y.abs() < 1e-6 && z.abs() < 1e-6);
        // At the north pole: z is the semi-minor axis plus the height.
        let [x, y, z] = GeoPoint::new(90.0, 0.0, 100.0).to_ecef();
        assert!(x.abs() < 1e-6 && y.abs() < 1e-6, "{x} {y}");
        assert!((z - 6_356_852.314_245).abs() < 1e-3, "{z}");
    }

    #[test]
    fn ecef_round_trips() {
        let base = GeoPoint::new(-33.868_82, 151.209_29, 58.3);
        let back = GeoPoint::from_ecef(base.to_ecef());
        assert!((back.lat_deg - base.lat_deg).abs() < 1e-9, "{back:?}");
        assert!((back.lon_deg - base.lon_deg).abs() < 1e-9, "{back:?}");
        assert!((back.alt_amsl_m - base.alt_amsl_m).abs() < 1e-4, "{back:?}");
    }

    #[test]
    fn unknown_fields_are_refused() {
        let e = serde_json::from_str::<GeoPoint>(
            r#"{"lat_deg": 1, "lon_deg": 2, "alt_amsl_m": 3, "alt_m": 4}"#,
        )
        .unwrap_err();
        assert!(e.to_string().contains("unknown field `alt_m`"), "{e}");
    }
}
