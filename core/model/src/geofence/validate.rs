//! What an operator's fence must satisfy before skein flies by it or sends it to PX4:
//! finite numbers, a positive radius and a sensible altitude band; polygons of at least
//! 3 vertices that are simple (no edge crossing or touching another, as PX4's
//! `MAV_CMD_NAV_FENCE_POLYGON_VERTEX_*` require) and not degenerate (no repeated vertex,
//! an area); an inclusion polygon inside the circle (PX4 keeps a vehicle inside *any*
//! inclusion area, skein inside *both*: with the polygon inside the circle the two are
//! the same fence); circles of positive radius; rally points inside the fence.

use super::polygon::{self, Point};
use super::{FenceArea, Geofence};

/// Largest radius, metres: the swarm frame is a tangent plane, true to centimetres over
/// tens of kilometres, not beyond.
const MAX_RADIUS_M: f64 = 100_000.0;
/// Highest ceiling, metres above the swarm origin.
const MAX_CEILING_M: f64 = 10_000.0;
/// Most vertices of one polygon, and most exclusion areas and rally points: far above
/// what an autopilot stores (PX4 keeps 64 fence items), only a bound on the request.
const MAX_VERTICES: usize = 500;
const MAX_AREAS: usize = 100;
const MAX_RALLY_POINTS: usize = 100;
/// Shortest edge of a fence polygon, metres: shorter is a repeated vertex.
const MIN_EDGE_M: f64 = 0.01;
/// Smallest area of a fence polygon, square metres.
const MIN_AREA_M2: f64 = 1.0;

type Fault = (String, String);

fn fault(field: impl Into<String>, why: impl Into<String>) -> Fault {
    (field.into(), why.into())
}

/// See the module docs; the field at fault and why.
pub(super) fn validate(g: &Geofence) -> Result<(), Fault> {
    limits(g)?;
    if !g.polygon.is_empty() {
        simple_polygon("polygon", &g.polygon)?;
        for (i, v) in g.polygon.iter().enumerate() {
            let d = v[0].hypot(v[1]);
            if d > g.radius_m {
                return Err(fault(
                    "polygon",
                    format!(
                        "vertex {i} is {d:.1} m from the swarm origin, outside radius_m {}: \
                         the polygon must lie inside the circle",
                        g.radius_m
                    ),
                ));
            }
        }
    }
    if g.exclusions.len() > MAX_AREAS {
        return Err(fault(
            "exclusions",
            format!("at most {MAX_AREAS} areas, got {}", g.exclusions.len()),
        ));
    }
    for (i, area) in g.exclusions.iter().enumerate() {
        exclusion(g, i, area)?;
    }
    rally_points(g)
}

/// The radius and the altitude band.
fn limits(g: &Geofence) -> Result<(), Fault> {
    if !(g.radius_m.is_finite() && g.radius_m > 0.0 && g.radius_m <= MAX_RADIUS_M) {
        return Err(fault(
            "radius_m",
            format!("must be in (0, {MAX_RADIUS_M}] m, got {}", g.radius_m),
        ));
    }
    if !(g.max_altitude_m.is_finite()
        && g.max_altitude_m > 0.0
        && g.max_altitude_m <= MAX_CEILING_M)
    {
        return Err(fault(
            "max_altitude_m",
            format!(
                "must be in (0, {MAX_CEILING_M}] m, got {}",
                g.max_altitude_m
            ),
        ));
    }
    if !(g.min_altitude_m.is_finite()
        && g.min_altitude_m >= 0.0
        && g.min_altitude_m < g.max_altitude_m)
    {
        return Err(fault(
            "min_altitude_m",
            format!("must be in [0, max_altitude_m), got {}", g.min_altitude_m),
        ));
    }
    Ok(())
}

/// Exclusion area `i`: a simple polygon, or a circle of positive radius, within twice
/// the fence's radius of the swarm origin.
fn exclusion(g: &Geofence, i: usize, area: &FenceArea) -> Result<(), Fault> {
    match area {
        FenceArea::Polygon(v) => {
            let field = format!("exclusions[{i}].polygon");
            simple_polygon(&field, v)?;
            if v.iter().any(|p| p[0].hypot(p[1]) > 2.0 * g.radius_m) {
                return Err(fault(
                    field,
                    "a vertex lies beyond twice radius_m from the swarm origin",
                ));
            }
        }
        FenceArea::Circle {
            north_m,
            east_m,
            radius_m,
        } => {
            let field = format!("exclusions[{i}].circle");
            if !(north_m.is_finite() && east_m.is_finite()) {
                return Err(fault(field, "the centre must be finite numbers"));
            }
            if !(radius_m.is_finite() && *radius_m > 0.0 && *radius_m <= 2.0 * g.radius_m) {
                return Err(fault(
                    field,
                    format!("radius_m must be in (0, 2 × radius_m], got {radius_m}"),
                ));
            }
            if north_m.hypot(*east_m) > 2.0 * g.radius_m {
                return Err(fault(
                    field,
                    "the centre lies beyond twice radius_m from the swarm origin",
                ));
            }
        }
    }
    Ok(())
}

/// The rally points: finite, inside the fence, not too many.
fn rally_points(g: &Geofence) -> Result<(), Fault> {
    if g.rally_points.len() > MAX_RALLY_POINTS {
        return Err(fault(
            "rally_points",
            format!(
                "at most {MAX_RALLY_POINTS} points, got {}",
                g.rally_points.len()
            ),
        ));
    }
    for (i, r) in g.rally_points.iter().enumerate() {
        let field = format!("rally_points[{i}]");
        if !(r.north_m.is_finite() && r.east_m.is_finite() && r.altitude_m.is_finite()) {
            return Err(fault(field, "must be finite numbers"));
        }
        let p = crate::geo::Ned::new(r.north_m, r.east_m, -r.altitude_m);
        if !g.contains(p) {
            return Err(fault(
                field,
                format!(
                    "({:.1}, {:.1}) at {:.1} m is outside the geofence",
                    r.north_m, r.east_m, r.altitude_m
                ),
            ));
        }
    }
    Ok(())
}

/// A polygon a fence can use: at least 3 finite vertices, no repeated vertex, an area,
/// no edge crossing another.
fn simple_polygon(field: &str, v: &[Point]) -> Result<(), Fault> {
    if v.len() < 3 {
        return Err(fault(
            field,
            format!("needs at least 3 vertices, got {}", v.len()),
        ));
    }
    if v.len() > MAX_VERTICES {
        return Err(fault(
            field,
            format!("at most {MAX_VERTICES} vertices, got {}", v.len()),
        ));
    }
    if v.iter().flatten().any(|x| !x.is_finite()) {
        return Err(fault(field, "vertices must be finite numbers"));
    }
    for i in 0..v.len() {
        let j = (i + 1) % v.len();
        if polygon::distance(v[i], v[j]) < MIN_EDGE_M {
            return Err(fault(
                field,
                format!("vertices {i} and {j} are the same point: the polygon is degenerate"),
            ));
        }
    }
    if collinear(v) {
        return Err(fault(
            field,
            "its vertices are all on one line: the polygon is degenerate",
        ));
    }
    if let Some((a, b)) = polygon::self_intersection(v) {
        return Err(fault(
            field,
            format!("edges {a} and {b} cross: the polygon must be simple (not self-intersecting)"),
        ));
    }
    let area = polygon::signed_area(v).abs();
    if area < MIN_AREA_M2 {
        return Err(fault(
            field,
            format!("encloses {area:.2} m²: the polygon is degenerate"),
        ));
    }
    Ok(())
}

/// True when every vertex lies within a centimetre of the line through vertex 0 and the
/// vertex farthest from it.
fn collinear(v: &[Point]) -> bool {
    let far = v
        .iter()
        .copied()
        .max_by(|a, b| polygon::distance(v[0], *a).total_cmp(&polygon::distance(v[0], *b)))
        .unwrap_or(v[0]);
    let len = polygon::distance(v[0], far);
    if len < MIN_EDGE_M {
        return true;
    }
    v.iter().all(|p| {
        let cross = (far[0] - v[0][0]) * (p[1] - v[0][1]) - (far[1] - v[0][1]) * (p[0] - v[0][0]);
        (cross / len).abs() < MIN_EDGE_M
    })
}
