//! How far inside the fence a point is: the smallest of its distances to the inclusion
//! circle, the inclusion polygon's edges, the exclusion areas and the ceiling (the floor
//! is left out: vehicles cross it taking off and landing). What a rehearsal reports as
//! the smallest geofence margin of a flight.

use super::{FenceArea, Geofence, polygon};
use crate::geo::Ned;

impl Geofence {
    /// The margin of `p` (swarm-frame NED), metres: positive inside the fence (the
    /// distance to its nearest boundary), negative outside (how far out). The floor does
    /// not count.
    pub fn margin_m(&self, p: Ned) -> f64 {
        let h = [p.north_m, p.east_m];
        let mut margin = (self.radius_m - p.horizontal_norm()).min(self.max_altitude_m + p.down_m);
        if self.polygon.len() >= 3 {
            let (b, _) = polygon::nearest_on_boundary(&self.polygon, h);
            let d = polygon::distance(h, b);
            margin = margin.min(if polygon::inside(&self.polygon, h) {
                d
            } else {
                -d
            });
        }
        for area in &self.exclusions {
            margin = margin.min(area.clearance_m(h));
        }
        margin
    }
}

impl FenceArea {
    /// How far `p` is outside the area, metres (negative inside: how deep).
    fn clearance_m(&self, p: polygon::Point) -> f64 {
        match self {
            FenceArea::Polygon(v) if v.len() >= 3 => {
                let (b, _) = polygon::nearest_on_boundary(v, p);
                let d = polygon::distance(p, b);
                if polygon::inside(v, p) { -d } else { d }
            }
            FenceArea::Polygon(_) => f64::INFINITY,
            FenceArea::Circle {
                north_m,
                east_m,
                radius_m,
            } => polygon::distance(p, [*north_m, *east_m]) - radius_m,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_margin_is_the_distance_to_the_nearest_boundary() {
        let mut fence = Geofence {
            radius_m: 100.0,
            max_altitude_m: 50.0,
            ..Geofence::default()
        };
        // 10 m up at 60 m out: 40 m from the circle, 40 m under the ceiling.
        assert!((fence.margin_m(Ned::new(60.0, 0.0, -10.0)) - 40.0).abs() < 1e-9);
        assert!((fence.margin_m(Ned::new(0.0, 0.0, -45.0)) - 5.0).abs() < 1e-9);
        assert!((fence.margin_m(Ned::new(0.0, 110.0, -10.0)) + 10.0).abs() < 1e-9);
        fence.polygon = vec![[-20.0, -20.0], [-20.0, 20.0], [20.0, 20.0], [20.0, -20.0]];
        assert!((fence.margin_m(Ned::new(15.0, 0.0, -10.0)) - 5.0).abs() < 1e-9);
        assert!((fence.margin_m(Ned::new(25.0, 0.0, -10.0)) + 5.0).abs() < 1e-9);
        fence.exclusions = vec![FenceArea::Circle {
            north_m: 0.0,
            east_m: 10.0,
            radius_m: 3.0,
        }];
        assert!((fence.margin_m(Ned::new(0.0, 5.0, -10.0)) - 2.0).abs() < 1e-9);
        assert!((fence.margin_m(Ned::new(0.0, 10.0, -10.0)) + 3.0).abs() < 1e-9);
    }
}
