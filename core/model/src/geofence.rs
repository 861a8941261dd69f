//! The geofence: a cylinder about the swarm origin, optionally cut by a polygon, that
//! every setpoint is clamped into ([`crate::safety::SetpointShaper`]) and every formation
//! and go-to request is checked against.

use crate::geo::Ned;
use serde::{Deserialize, Serialize};

/// A cylinder around the swarm origin (swarm frame): horizontal radius, an altitude band
/// above the origin, and optionally a polygon the vehicles must stay inside too.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Geofence {
    /// Largest horizontal distance from the swarm origin, metres.
    pub radius_m: f64,
    /// Highest altitude above the swarm origin, metres.
    pub max_altitude_m: f64,
    /// Lowest altitude above the swarm origin for airborne targets (not enforced while
    /// taking off or landing), metres.
    #[serde(default)]
    pub min_altitude_m: f64,
    /// Optional polygon, `[north_m, east_m]` vertices in the swarm frame, in order
    /// (at least 3; empty = none).
    #[serde(default)]
    pub polygon: Vec<[f64; 2]>,
}

impl Default for Geofence {
    fn default() -> Self {
        Geofence {
            radius_m: 500.0,
            max_altitude_m: 120.0,
            min_altitude_m: 0.0,
            polygon: vec![],
        }
    }
}

/// Why a setpoint was changed by the geofence.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum FenceViolation {
    /// Outside the horizontal radius.
    Radius,
    /// Outside the polygon.
    Polygon,
    /// Above the ceiling.
    Ceiling,
    /// Below the floor.
    Floor,
}

impl FenceViolation {
    /// The name events use (`"radius"`).
    pub fn name(self) -> &'static str {
        match self {
            FenceViolation::Radius => "radius",
            FenceViolation::Polygon => "polygon",
            FenceViolation::Ceiling => "ceiling",
            FenceViolation::Floor => "floor",
        }
    }
}

/// True when (n, e) is inside the polygon (ray casting).
fn inside_polygon(poly: &[[f64; 2]], n: f64, e: f64) -> bool {
    let mut inside = false;
    let mut j = poly.len() - 1;
    for i in 0..poly.len() {
        let ([ni, ei], [nj, ej]) = (poly[i], poly[j]);
        if (ei > e) != (ej > e) && n < (nj - ni) * (e - ei) / (ej - ei) + ni {
            inside = !inside;
        }
        j = i;
    }
    inside
}

/// The point of the polygon's boundary nearest to (n, e).
fn nearest_on_polygon(poly: &[[f64; 2]], n: f64, e: f64) -> (f64, f64) {
    let mut best = (poly[0][0], poly[0][1]);
    let mut best_d2 = f64::INFINITY;
    for i in 0..poly.len() {
        let [an, ae] = poly[i];
        let [bn, be] = poly[(i + 1) % poly.len()];
        let (dn, de) = (bn - an, be - ae);
        let len2 = dn * dn + de * de;
        let t = if len2 > 0.0 {
            (((n - an) * dn + (e - ae) * de) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (pn, pe) = (an + t * dn, ae + t * de);
        let d2 = (pn - n).powi(2) + (pe - e).powi(2);
        if d2 < best_d2 {
            best_d2 = d2;
            best = (pn, pe);
        }
    }
    best
}

impl Geofence {
    /// Clamps a swarm-frame position into the fence; returns the clamped point and the
    /// violation, if any (the first found: radius, polygon, ceiling, floor). The floor is
    /// only applied when `enforce_floor` (airborne targets; not a takeoff or a landing).
    pub fn clamp(&self, p: Ned, enforce_floor: bool) -> (Ned, Option<FenceViolation>) {
        let mut out = p;
        let mut violation = None;
        let h = p.horizontal_norm();
        if h > self.radius_m {
            let k = self.radius_m / h;
            out.north_m *= k;
            out.east_m *= k;
            violation = Some(FenceViolation::Radius);
        }
        if self.polygon.len() >= 3 && !inside_polygon(&self.polygon, out.north_m, out.east_m) {
            let (n, e) = nearest_on_polygon(&self.polygon, out.north_m, out.east_m);
            out.north_m = n;
            out.east_m = e;
            violation.get_or_insert(FenceViolation::Polygon);
        }
        if -out.down_m > self.max_altitude_m {
            out.down_m = -self.max_altitude_m;
            violation.get_or_insert(FenceViolation::Ceiling);
        }
        if enforce_floor && -out.down_m < self.min_altitude_m {
            out.down_m = -self.min_altitude_m;
            violation.get_or_insert(FenceViolation::Floor);
        }
        (out, violation)
    }

    /// The fence moved `buffer_m` inwards: radius and ceiling lower, floor higher (the
    /// polygon is kept as is).
    pub fn shrunk(&self, buffer_m: f64) -> Geofence {
        Geofence {
            radius_m: (self.radius_m - buffer_m).max(0.0),
            max_altitude_m: (self.max_altitude_m - buffer_m).max(self.min_altitude_m),
            min_altitude_m: (self.min_altitude_m + buffer_m).min(self.max_altitude_m),
            polygon: self.polygon.clone(),
        }
    }

    /// True when `p` is inside the fence (floor included).
    pub fn contains(&self, p: Ned) -> bool {
        // A point on the polygon's edge counts as inside.
        let (q, v) = self.clamp(p, true);
        v.is_none() || (q - p).norm() < 1e-9
    }

    /// Checks the fence's own consistency.
    ///
    /// # Errors
    /// The field at fault and why.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        if !(self.radius_m.is_finite() && self.radius_m > 0.0) {
            return Err((
                "radius_m",
                format!("must be positive, got {}", self.radius_m),
            ));
        }
        if !(self.max_altitude_m.is_finite() && self.max_altitude_m > 0.0) {
            return Err((
                "max_altitude_m",
                format!("must be positive, got {}", self.max_altitude_m),
            ));
        }
        if !(self.min_altitude_m.is_finite()
            && self.min_altitude_m >= 0.0
            && self.min_altitude_m < self.max_altitude_m)
        {
            return Err((
                "min_altitude_m",
                format!(
                    "must be in [0, max_altitude_m), got {}",
                    self.min_altitude_m
                ),
            ));
        }
        if !self.polygon.is_empty() && self.polygon.len() < 3 {
            return Err((
                "polygon",
                format!("needs at least 3 vertices, got {}", self.polygon.len()),
            ));
        }
        if self.polygon.iter().flatten().any(|x| !x.is_finite()) {
            return Err(("polygon", "vertices must be finite numbers".into()));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fence_clamps_radius_ceiling_and_floor() {
        let fence = Geofence {
            radius_m: 100.0,
            max_altitude_m: 50.0,
            min_altitude_m: 5.0,
            polygon: vec![],
        };
        let (p, v) = fence.clamp(Ned::new(300.0, 400.0, -10.0), true);
        assert_eq!(v, Some(FenceViolation::Radius));
        assert!((p.horizontal_norm() - 100.0).abs() < 1e-9);
        assert!((p.north_m - 60.0).abs() < 1e-9);
        let (p, v) = fence.clamp(Ned::new(0.0, 0.0, -80.0), true);
        assert_eq!((p.down_m, v), (-50.0, Some(FenceViolation::Ceiling)));
        assert!(fence.contains(Ned::new(10.0, 10.0, -10.0)));
        let (p, v) = fence.clamp(Ned::new(0.0, 0.0, -2.0), true);
        assert_eq!((p.down_m, v), (-5.0, Some(FenceViolation::Floor)));
        assert_eq!(
            fence.clamp(Ned::new(0.0, 0.0, -2.0), false).1,
            None,
            "takeoff passes the floor"
        );
        assert!(fence.validate().is_ok());
        assert_eq!(
            Geofence {
                min_altitude_m: 60.0,
                ..fence.clone()
            }
            .validate()
            .unwrap_err()
            .0,
            "min_altitude_m"
        );
    }

    #[test]
    fn fence_polygon_clamps_to_the_nearest_edge() {
        // A 40 m × 20 m rectangle north-east of the origin.
        let fence = Geofence {
            polygon: vec![[-10.0, -10.0], [30.0, -10.0], [30.0, 10.0], [-10.0, 10.0]],
            ..Geofence::default()
        };
        assert!(fence.contains(Ned::new(0.0, 0.0, -10.0)));
        let (p, v) = fence.clamp(Ned::new(50.0, 0.0, -10.0), true);
        assert_eq!(v, Some(FenceViolation::Polygon));
        assert!((p - Ned::new(30.0, 0.0, -10.0)).norm() < 1e-9, "{p:?}");
        let (p, _) = fence.clamp(Ned::new(0.0, 25.0, -10.0), true);
        assert!((p - Ned::new(0.0, 10.0, -10.0)).norm() < 1e-9, "{p:?}");
        assert_eq!(
            Geofence {
                polygon: vec![[0.0, 0.0], [1.0, 1.0]],
                ..Geofence::default()
            }
            .validate()
            .unwrap_err()
            .0,
            "polygon"
        );
    }
}
