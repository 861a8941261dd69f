//! The geofence: where skein lets its vehicles fly, in the swarm frame. Every setpoint is
//! clamped into it ([`crate::safety::SetpointShaper`]), every formation and go-to request
//! is checked against it, and the same fence is uploaded to every PX4 as its own geofence
//! (`skein_link::fence`), so the autopilot enforces it even when skein cannot.
//!
//! The fence is one inclusion area (a circle of `radius_m` about the swarm origin, cut to
//! an optional polygon lying inside it), exclusion areas (polygons and circles the
//! vehicles must stay out of), an altitude band above the swarm origin, the rally points
//! PX4 may return to, and the action PX4 takes on a breach (`GF_ACTION`).
//!
//! - [`polygon`]: plane geometry of the areas;
//! - `validate`: what an operator's fence must satisfy (simple polygons, …);
//! - [`sync`]: how far a vehicle's autopilot holds the fence.

mod braking;
mod margin;
pub mod polygon;
pub mod sync;
mod validate;

pub use sync::{FenceStatus, FenceSyncState};

use crate::geo::Ned;
use polygon::Point;
use serde::{Deserialize, Serialize};

/// The geofence (see the module docs). Positions are the swarm frame's: `[north_m,
/// east_m]` about the swarm origin, altitudes above it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Geofence {
    /// Largest horizontal distance from the swarm origin, metres (the inclusion circle).
    pub radius_m: f64,
    /// Highest altitude above the swarm origin, metres (PX4: `GF_MAX_VER_DIST` above each
    /// vehicle's home).
    pub max_altitude_m: f64,
    /// Lowest altitude above the swarm origin for airborne targets (not enforced while
    /// taking off or landing), metres. skein's own: PX4 has no floor.
    #[serde(default)]
    pub min_altitude_m: f64,
    /// Optional inclusion polygon, `[north_m, east_m]` vertices in order (at least 3, a
    /// simple polygon inside the circle; empty = the circle alone).
    #[serde(default)]
    pub polygon: Vec<[f64; 2]>,
    /// Areas the vehicles must stay out of.
    #[serde(default)]
    pub exclusions: Vec<FenceArea>,
    /// Where PX4 may return to instead of home (`MAV_MISSION_TYPE_RALLY`).
    #[serde(default)]
    pub rally_points: Vec<RallyPoint>,
    /// What PX4 does when a vehicle leaves the fence (`GF_ACTION`).
    #[serde(default)]
    pub breach_action: BreachAction,
    /// Distance kept inside the polygon and outside the exclusion areas, metres: 0 for a
    /// fence as given, set by [`Geofence::shrunk`] for setpoints (never serialised).
    #[serde(skip)]
    #[schema(ignore)]
    pub area_margin_m: f64,
}

impl Default for Geofence {
    fn default() -> Self {
        Geofence {
            radius_m: 500.0,
            max_altitude_m: 120.0,
            min_altitude_m: 0.0,
            polygon: vec![],
            exclusions: vec![],
            rally_points: vec![],
            breach_action: BreachAction::default(),
            area_margin_m: 0.0,
        }
    }
}

/// An area of the fence in the swarm frame's horizontal plane.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum FenceArea {
    /// `[north_m, east_m]` vertices in order: at least 3, a simple polygon
    /// (`MAV_CMD_NAV_FENCE_POLYGON_VERTEX_*`).
    Polygon(Vec<[f64; 2]>),
    /// A circle (`MAV_CMD_NAV_FENCE_CIRCLE_*`).
    Circle {
        /// Centre, metres north of the swarm origin.
        north_m: f64,
        /// Centre, metres east of the swarm origin.
        east_m: f64,
        /// Radius, metres.
        radius_m: f64,
    },
}

/// A rally point (`MAV_CMD_NAV_RALLY_POINT`): where PX4's return mode may go instead of
/// home.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct RallyPoint {
    /// Metres north of the swarm origin.
    pub north_m: f64,
    /// Metres east of the swarm origin.
    pub east_m: f64,
    /// Altitude above the swarm origin, metres.
    pub altitude_m: f64,
}

/// What PX4 does on a geofence breach: the values of its `GF_ACTION` parameter that a
/// multicopter swarm may use (4, flight termination, is deliberately not offered).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum BreachAction {
    /// `GF_ACTION` 0: nothing.
    None,
    /// `GF_ACTION` 1: a critical status text only.
    Warn,
    /// `GF_ACTION` 2 (PX4's default): switch to Hold (stop and loiter).
    #[default]
    Hold,
    /// `GF_ACTION` 3: switch to Return.
    Rtl,
    /// `GF_ACTION` 5: switch to Land.
    Land,
}

impl BreachAction {
    /// The `GF_ACTION` value.
    pub fn gf_action(self) -> i32 {
        match self {
            BreachAction::None => 0,
            BreachAction::Warn => 1,
            BreachAction::Hold => 2,
            BreachAction::Rtl => 3,
            BreachAction::Land => 5,
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
    /// Inside an exclusion area.
    Exclusion,
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
            FenceViolation::Exclusion => "exclusion",
            FenceViolation::Ceiling => "ceiling",
            FenceViolation::Floor => "floor",
        }
    }
}

/// A sliver past a boundary, so that a point pushed onto an edge counts as on the right
/// side of it, metres.
const EDGE_EPSILON_M: f64 = 1e-6;

/// Moves `p` so that it lies `margin_m` from the boundary point `b` on the side given by
/// `want_inside` of the area `contains` tests; a point on the boundary goes along the
/// normal of `edge` (`[a, c]`).
fn off_boundary(
    p: Point,
    b: Point,
    edge: [Point; 2],
    margin_m: f64,
    want_inside: bool,
    contains: impl Fn(Point) -> bool,
) -> Point {
    let d = polygon::distance(p, b);
    let mut dir = if d > 1e-9 {
        [(p[0] - b[0]) / d, (p[1] - b[1]) / d]
    } else {
        let [a, c] = edge;
        let len = polygon::distance(a, c).max(1e-12);
        [-(c[1] - a[1]) / len, (c[0] - a[0]) / len]
    };
    // `dir` points from the boundary to p (or along a normal): flip it to the wanted side.
    let probe = [b[0] + dir[0] * 1e-3, b[1] + dir[1] * 1e-3];
    if contains(probe) != want_inside {
        dir = [-dir[0], -dir[1]];
    }
    let k = margin_m + EDGE_EPSILON_M;
    [b[0] + dir[0] * k, b[1] + dir[1] * k]
}

impl FenceArea {
    /// True when `p` is inside the area.
    pub fn contains(&self, p: Point) -> bool {
        match self {
            FenceArea::Polygon(v) => v.len() >= 3 && polygon::inside(v, p),
            FenceArea::Circle {
                north_m,
                east_m,
                radius_m,
            } => polygon::distance(p, [*north_m, *east_m]) < *radius_m,
        }
    }

    /// The point `margin_m` outside the area nearest to `p`, if `p` is inside the area
    /// or closer than `margin_m` to it; `None` when `p` is clear of it.
    fn push_out(&self, p: Point, margin_m: f64) -> Option<Point> {
        match self {
            FenceArea::Polygon(v) => {
                if v.len() < 3 {
                    return None;
                }
                let (b, i) = polygon::nearest_on_boundary(v, p);
                let inside = polygon::inside(v, p);
                if !inside && polygon::distance(p, b) >= margin_m {
                    return None;
                }
                let edge = [v[i], v[(i + 1) % v.len()]];
                Some(off_boundary(p, b, edge, margin_m, false, |q| {
                    polygon::inside(v, q)
                }))
            }
            FenceArea::Circle {
                north_m,
                east_m,
                radius_m,
            } => {
                let c = [*north_m, *east_m];
                let d = polygon::distance(p, c);
                let keep = radius_m + margin_m;
                if d >= keep {
                    return None;
                }
                let dir = if d > 1e-9 {
                    [(p[0] - c[0]) / d, (p[1] - c[1]) / d]
                } else {
                    [1.0, 0.0]
                };
                let k = keep + EDGE_EPSILON_M;
                Some([c[0] + dir[0] * k, c[1] + dir[1] * k])
            }
        }
    }
}

impl Geofence {
    /// Clamps a swarm-frame position into the fence; returns the clamped point and the
    /// violation, if any (the first found: radius, polygon, exclusion, ceiling, floor).
    /// The floor is only applied when `enforce_floor` (airborne targets; not a takeoff or
    /// a landing).
    pub fn clamp(&self, p: Ned, enforce_floor: bool) -> (Ned, Option<FenceViolation>) {
        let mut out = p;
        let mut violation = None;
        // An exclusion area pushes a point out, possibly out of the inclusion area: a few
        // rounds settle where both hold (or the last inclusion clamp wins).
        for round in 0..4 {
            let mut moved = false;
            let h = out.horizontal_norm();
            if h > self.radius_m {
                let k = self.radius_m / h;
                out.north_m *= k;
                out.east_m *= k;
                violation.get_or_insert(FenceViolation::Radius);
                moved = true;
            }
            if let Some(q) = self.pulled_into_polygon([out.north_m, out.east_m]) {
                [out.north_m, out.east_m] = q;
                violation.get_or_insert(FenceViolation::Polygon);
                moved = true;
            }
            if round == 3 {
                break;
            }
            for area in &self.exclusions {
                if let Some(q) = area.push_out([out.north_m, out.east_m], self.area_margin_m) {
                    [out.north_m, out.east_m] = q;
                    violation.get_or_insert(FenceViolation::Exclusion);
                    moved = true;
                }
            }
            if !moved {
                break;
            }
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

    /// The point `area_margin_m` inside the polygon nearest to `p`, if `p` is outside it
    /// or closer than the margin to its edge; `None` when `p` is well inside (or there is
    /// no polygon).
    fn pulled_into_polygon(&self, p: Point) -> Option<Point> {
        let v = &self.polygon;
        if v.len() < 3 {
            return None;
        }
        let (b, i) = polygon::nearest_on_boundary(v, p);
        let inside = polygon::inside(v, p);
        if inside && polygon::distance(p, b) >= self.area_margin_m {
            return None;
        }
        if self.area_margin_m == 0.0 && !inside {
            return Some(b); // on the edge counts as inside (see `contains`)
        }
        let edge = [v[i], v[(i + 1) % v.len()]];
        Some(off_boundary(p, b, edge, self.area_margin_m, true, |q| {
            polygon::inside(v, q)
        }))
    }

    /// The fence moved `buffer_m` inwards: radius and ceiling lower, floor higher, the
    /// polygon's edges and the exclusion areas kept `buffer_m` further away.
    pub fn shrunk(&self, buffer_m: f64) -> Geofence {
        Geofence {
            radius_m: (self.radius_m - buffer_m).max(0.0),
            max_altitude_m: (self.max_altitude_m - buffer_m).max(self.min_altitude_m),
            min_altitude_m: (self.min_altitude_m + buffer_m).min(self.max_altitude_m),
            area_margin_m: self.area_margin_m + buffer_m,
            ..self.clone()
        }
    }

    /// A fence nothing a swarm does can reach (a 10 000 km radius, 100 km ceiling): what
    /// a vehicle's setpoints are clamped into while a test fault bypasses the geofence.
    pub fn unbounded() -> Geofence {
        Geofence {
            radius_m: 1e7,
            max_altitude_m: 1e5,
            ..Geofence::default()
        }
    }

    /// True when `p` is inside the fence (floor included). A point on an edge counts as
    /// inside.
    pub fn contains(&self, p: Ned) -> bool {
        self.contains_within(p, true)
    }

    /// True when `p` is inside the fence, the floor checked only when `enforce_floor`.
    pub fn contains_within(&self, p: Ned, enforce_floor: bool) -> bool {
        let (q, v) = self.clamp(p, enforce_floor);
        v.is_none() || (q - p).norm() < 1e-5
    }

    /// Checks the fence's own consistency: the field at fault (`"polygon"`,
    /// `"exclusions[1].polygon"`, `"rally_points[0]"` …) and why (see the `validate` module).
    ///
    /// # Errors
    /// The first rule broken.
    pub fn validate(&self) -> Result<(), (String, String)> {
        validate::validate(self)
    }
}

#[cfg(test)]
mod tests;
