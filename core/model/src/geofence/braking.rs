//! Braking before the fence: how fast a point may move toward each boundary of the fence
//! and still stop on it. The setpoint shaper's carrot keeps to this, so it never reaches
//! a boundary at speed: a carrot stopped there by the clamp alone leaves the vehicle
//! following it to carry its momentum on, out of the fence (a rehearsal saw a survey
//! vehicle pushed toward the fence end 0.1 m outside it, past the 2 m tracking buffer).

use super::{FenceArea, Geofence, polygon};
use crate::geo::Ned;

/// Rounds of the cuts: a cut toward one boundary can add speed toward another that
/// meets it at an acute corner; the second round takes that back.
const ROUNDS: usize = 2;

impl Geofence {
    /// `v` (NED m/s) at `p` (swarm-frame NED) with its component toward each boundary of
    /// the fence cut to `sqrt(2 · brake_m_s2 · d)`, `d` the distance (m) from `p` to that
    /// boundary: at most the speed from which decelerating at `brake_m_s2` stops on it.
    /// Boundaries: the radius, each edge of the inclusion polygon and of the exclusion
    /// areas (kept `area_margin_m` off, as [`Geofence::clamp`] keeps points), the ceiling,
    /// and the floor when `enforce_floor`. Motion along a boundary or away from it is
    /// untouched; a boundary `p` is already past is left to the clamp.
    pub fn braked_toward_boundaries(
        &self,
        p: Ned,
        v: Ned,
        brake_m_s2: f64,
        enforce_floor: bool,
    ) -> Ned {
        let mut v = v;
        for _ in 0..ROUNDS {
            self.each_boundary(p, enforce_floor, &mut |distance_m, outward| {
                let toward = v.dot(&outward);
                let allowed = (2.0 * brake_m_s2 * distance_m.max(0.0)).sqrt();
                if toward > allowed {
                    v = v - outward * (toward - allowed);
                }
            });
        }
        v
    }

    /// Calls `out` with each boundary near enough to matter: its distance from `p` (m)
    /// and the unit vector from `p` toward it (NED). Allocates nothing: this runs in
    /// every vehicle's control step.
    fn each_boundary(&self, p: Ned, enforce_floor: bool, out: &mut impl FnMut(f64, Ned)) {
        let h = [p.north_m, p.east_m];
        let r = p.horizontal_norm();
        if r > 1e-9 && r <= self.radius_m {
            out(self.radius_m - r, horizontal(h, [0.0, 0.0], -1.0));
        }
        if self.polygon.len() >= 3 && polygon::inside(&self.polygon, h) {
            edges_seen_from(&self.polygon, h, self.area_margin_m, out);
        }
        for area in &self.exclusions {
            match area {
                FenceArea::Polygon(v) if v.len() >= 3 && !polygon::inside(v, h) => {
                    edges_seen_from(v, h, self.area_margin_m, out);
                }
                FenceArea::Polygon(_) => {}
                FenceArea::Circle {
                    north_m,
                    east_m,
                    radius_m,
                } => {
                    let c = [*north_m, *east_m];
                    let d = polygon::distance(h, c);
                    if d > 1e-9 {
                        out(d - radius_m - self.area_margin_m, horizontal(c, h, 1.0));
                    }
                }
            }
        }
        if -p.down_m <= self.max_altitude_m {
            out(self.max_altitude_m + p.down_m, Ned::new(0.0, 0.0, -1.0));
        }
        if enforce_floor && -p.down_m >= self.min_altitude_m {
            out(-p.down_m - self.min_altitude_m, Ned::new(0.0, 0.0, 1.0));
        }
    }
}

/// Every edge of `poly` as seen from `p`: the distance to its nearest point less
/// `margin_m`, and the direction there.
fn edges_seen_from(
    poly: &[polygon::Point],
    p: polygon::Point,
    margin_m: f64,
    out: &mut impl FnMut(f64, Ned),
) {
    for i in 0..poly.len() {
        let b = polygon::nearest_on_segment(poly[i], poly[(i + 1) % poly.len()], p);
        let d = polygon::distance(p, b);
        if d > 1e-9 {
            out(d - margin_m, horizontal(b, p, 1.0));
        }
    }
}

/// The horizontal unit vector from `from` to `to`, times `sign`.
fn horizontal(to: polygon::Point, from: polygon::Point, sign: f64) -> Ned {
    let d = polygon::distance(to, from).max(1e-12);
    Ned::new(
        sign * (to[0] - from[0]) / d,
        sign * (to[1] - from[1]) / d,
        0.0,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> Geofence {
        Geofence {
            polygon: vec![[-50.0, -50.0], [-50.0, 50.0], [50.0, 50.0], [50.0, -50.0]],
            ..Geofence::default()
        }
    }

    #[test]
    fn speed_toward_an_edge_is_what_stops_on_it_and_along_it_is_kept() {
        let fence = square();
        // 8 m from the north edge, 8 m/s north and 5 m/s east: north cut to √(2·1.5·8).
        let v = fence.braked_toward_boundaries(
            Ned::new(42.0, 0.0, -10.0),
            Ned::new(8.0, 5.0, 0.0),
            1.5,
            false,
        );
        assert!((v.north_m - 24f64.sqrt()).abs() < 1e-9, "{v:?}");
        assert!((v.east_m - 5.0).abs() < 1e-9, "{v:?}");
        // Away from the edge: untouched.
        let away = Ned::new(-8.0, 5.0, 0.0);
        assert_eq!(
            fence.braked_toward_boundaries(Ned::new(42.0, 0.0, -10.0), away, 1.5, false),
            away
        );
    }

    #[test]
    fn a_corner_brakes_both_ways_and_an_exclusion_and_the_ceiling_too() {
        let mut fence = square();
        let v = fence.braked_toward_boundaries(
            Ned::new(48.0, 48.0, -10.0),
            Ned::new(8.0, 8.0, 0.0),
            1.5,
            false,
        );
        let allowed = 6f64.sqrt();
        assert!(
            v.north_m <= allowed + 1e-9 && v.east_m <= allowed + 1e-9,
            "{v:?}"
        );
        fence.exclusions = vec![FenceArea::Circle {
            north_m: 0.0,
            east_m: 20.0,
            radius_m: 5.0,
        }];
        let v = fence.braked_toward_boundaries(
            Ned::new(0.0, 0.0, -10.0),
            Ned::new(0.0, 8.0, 0.0),
            1.5,
            false,
        );
        assert!((v.east_m - 45f64.sqrt()).abs() < 1e-9, "{v:?}");
        let v = fence.braked_toward_boundaries(
            Ned::new(0.0, 0.0, -(fence.max_altitude_m - 3.0)),
            Ned::new(0.0, 0.0, -3.0),
            1.5,
            false,
        );
        assert!(
            (v.down_m + 3.0).abs() < 1e-9,
            "3 m under the ceiling, 3 m/s stops: {v:?}"
        );
        let v = fence.braked_toward_boundaries(
            Ned::new(0.0, 0.0, -(fence.max_altitude_m - 1.0)),
            Ned::new(0.0, 0.0, -3.0),
            1.5,
            false,
        );
        assert!((v.down_m + 3f64.sqrt()).abs() < 1e-9, "{v:?}");
    }
}
