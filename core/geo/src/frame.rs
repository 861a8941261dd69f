//! [`NedFrame`]: a local tangent-plane NED frame anchored at a geodetic origin (WGS84,
//! through `map_3d`).

use crate::{GeoPoint, Ned};
use serde::{Deserialize, Serialize};

/// A local tangent-plane NED frame anchored at a geodetic origin.
///
/// The swarm frame is one (anchored at the swarm origin); each vehicle's PX4 local frame is
/// another (anchored at its EKF origin, see [`NedFrame::from_reference`]). Velocities are
/// carried between frames unrotated: two tangent planes a few kilometres apart differ by
/// well under a milliradian.
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

    /// The map from this frame's NED to `other`'s, worked out once for many positions
    /// (see [`FrameTransform`]).
    pub fn transform_to(&self, other: &NedFrame) -> FrameTransform {
        // Both frames are Cartesian (tangent planes through ECEF), so the map between
        // them is affine: a rotation and a translation, read off the images of the
        // origin and of a point along each axis.
        const STEP_M: f64 = 100.0;
        let origin = self.convert_to(other, Ned::ZERO);
        let axis = |unit: Ned| (self.convert_to(other, unit * STEP_M) - origin) * (1.0 / STEP_M);
        FrameTransform {
            from: *self,
            to: *other,
            columns: [
                axis(Ned::new(1.0, 0.0, 0.0)),
                axis(Ned::new(0.0, 1.0, 0.0)),
                axis(Ned::new(0.0, 0.0, 1.0)),
            ],
            translation: origin,
        }
    }
}

/// The map between two [`NedFrame`]s, as [`NedFrame::convert_to`] computes it but without
/// going through geodetic coordinates for each position: the two tangent planes are
/// Cartesian frames, so the map is a rotation and a translation (agreeing with
/// `convert_to` to micrometres over kilometres). A vehicle's control loop converts every
/// setpoint with it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameTransform {
    from: NedFrame,
    to: NedFrame,
    /// Images of the unit north, east and down vectors (the rotation's columns).
    columns: [Ned; 3],
    /// Image of the origin, metres.
    translation: Ned,
}

impl FrameTransform {
    /// True when this is the map from `from` to `to` (to tell when to work out a new one).
    pub fn maps(&self, from: &NedFrame, to: &NedFrame) -> bool {
        self.from == *from && self.to == *to
    }

    /// `ned` in the source frame, re-expressed in the target frame (metres).
    pub fn apply(&self, ned: Ned) -> Ned {
        let [n, e, d] = &self.columns;
        self.translation + *n * ned.north_m + *e * ned.east_m + *d * ned.down_m
    }
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
        // A thousandth of that is about 111 m.
        let p = frame.to_ned(&GeoPoint::new(47.001, 8.0, 0.0));
        assert!((p.north_m - 111.2).abs() < 0.3, "{p:?}");
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
    fn a_transform_agrees_with_the_conversion_through_geodetic_points() {
        let swarm = NedFrame::new(ZURICH);
        let local = NedFrame::new(swarm.to_geo(Ned::new(-830.0, 1250.0, 12.0)));
        let t = swarm.transform_to(&local);
        assert!(t.maps(&swarm, &local) && !t.maps(&local, &swarm));
        for p in [
            Ned::ZERO,
            Ned::new(15.0, -3.0, -10.0),
            Ned::new(2500.0, -1800.0, -120.0),
        ] {
            let err = (t.apply(p) - swarm.convert_to(&local, p)).norm();
            assert!(err < 1e-5, "{p:?}: {err} m off");
        }
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
}
