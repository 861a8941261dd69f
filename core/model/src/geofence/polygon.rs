//! Plane geometry of fence areas in the swarm frame's horizontal plane (`[north_m,
//! east_m]` points): point-in-polygon, the nearest boundary point, area, and the
//! self-intersection test a fence polygon must pass (PX4 evaluates polygons with the
//! even-odd rule of `Geofence::insidePolygon`, which is only meaningful for simple ones).

/// A horizontal point, `[north_m, east_m]`.
pub type Point = [f64; 2];

/// True when `p` is inside `poly` (even-odd ray casting, as PX4's `insidePolygon`).
pub fn inside(poly: &[Point], p: Point) -> bool {
    let mut inside = false;
    let mut j = poly.len() - 1;
    for i in 0..poly.len() {
        let ([ni, ei], [nj, ej]) = (poly[i], poly[j]);
        if (ei > p[1]) != (ej > p[1]) && p[0] < (nj - ni) * (p[1] - ei) / (ej - ei) + ni {
            inside = !inside;
        }
        j = i;
    }
    inside
}

/// The point of segment `a`–`b` nearest to `p`.
pub fn nearest_on_segment(a: Point, b: Point, p: Point) -> Point {
    let (dn, de) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dn * dn + de * de;
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * dn + (p[1] - a[1]) * de) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    [a[0] + t * dn, a[1] + t * de]
}

/// The point of the polygon's boundary nearest to `p`, and the index of its edge (edge
/// `i` runs from vertex `i` to vertex `i + 1`, the last one back to vertex 0).
pub fn nearest_on_boundary(poly: &[Point], p: Point) -> (Point, usize) {
    let mut best = (poly[0], 0);
    let mut best_d2 = f64::INFINITY;
    for i in 0..poly.len() {
        let q = nearest_on_segment(poly[i], poly[(i + 1) % poly.len()], p);
        let d2 = distance(q, p).powi(2);
        if d2 < best_d2 {
            best_d2 = d2;
            best = (q, i);
        }
    }
    best
}

/// Euclidean distance, metres.
pub fn distance(a: Point, b: Point) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Signed area (shoelace), square metres: positive when the vertices run clockwise seen
/// from above (north, then east), negative otherwise.
pub fn signed_area(poly: &[Point]) -> f64 {
    let mut twice = 0.0;
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        twice += a[0] * b[1] - b[0] * a[1];
    }
    twice / 2.0
}

/// Orientation of `c` relative to the line `a`→`b`: > 0 on one side, < 0 on the other,
/// 0 on the line.
fn orient(a: Point, b: Point, c: Point) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// True when `c`, known to be on the line `a`–`b`, lies within the segment's box.
fn on_segment(a: Point, b: Point, c: Point) -> bool {
    c[0] >= a[0].min(b[0]) - 1e-9
        && c[0] <= a[0].max(b[0]) + 1e-9
        && c[1] >= a[1].min(b[1]) - 1e-9
        && c[1] <= a[1].max(b[1]) + 1e-9
}

/// True when the closed segments `a`–`b` and `c`–`d` share a point.
pub fn segments_intersect(a: Point, b: Point, c: Point, d: Point) -> bool {
    let tol = 1e-9 * (1.0 + distance(a, b) * distance(c, d));
    let (o1, o2) = (orient(a, b, c), orient(a, b, d));
    let (o3, o4) = (orient(c, d, a), orient(c, d, b));
    let sign = |x: f64| if x.abs() <= tol { 0 } else { x.signum() as i32 };
    let (s1, s2, s3, s4) = (sign(o1), sign(o2), sign(o3), sign(o4));
    if s1 * s2 < 0 && s3 * s4 < 0 {
        return true;
    }
    (s1 == 0 && on_segment(a, b, c))
        || (s2 == 0 && on_segment(a, b, d))
        || (s3 == 0 && on_segment(c, d, a))
        || (s4 == 0 && on_segment(c, d, b))
}

/// The first pair of edges `(i, j)` that cross or touch where they should not: two
/// edges that are not neighbours sharing any point, or two neighbours folding back over
/// each other. `None` for a simple polygon.
pub fn self_intersection(poly: &[Point]) -> Option<(usize, usize)> {
    let n = poly.len();
    let edge = |i: usize| (poly[i], poly[(i + 1) % n]);
    for i in 0..n {
        let (a, b) = edge(i);
        // The next edge shares vertex i + 1: it must not run back along this one.
        let (_, c) = edge((i + 1) % n);
        if orient(a, b, c).abs() <= 1e-9 * (1.0 + distance(a, b) * distance(b, c))
            && (c[0] - b[0]) * (a[0] - b[0]) + (c[1] - b[1]) * (a[1] - b[1]) > 0.0
        {
            return Some((i, (i + 1) % n));
        }
        for j in i + 2..n {
            if i == 0 && j == n - 1 {
                continue; // neighbours through vertex 0
            }
            let (c, d) = edge(j);
            if segments_intersect(a, b, c, d) {
                return Some((i, j));
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    const SQUARE: [Point; 4] = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]];

    #[test]
    fn inside_nearest_and_area() {
        assert!(inside(&SQUARE, [5.0, 5.0]));
        assert!(!inside(&SQUARE, [15.0, 5.0]));
        let (q, edge) = nearest_on_boundary(&SQUARE, [15.0, 5.0]);
        assert_eq!((q, edge), ([10.0, 5.0], 1));
        assert_eq!(signed_area(&SQUARE).abs(), 100.0);
    }

    #[test]
    fn a_bow_tie_crosses_itself_and_a_square_does_not() {
        assert_eq!(self_intersection(&SQUARE), None);
        let bow_tie = [[0.0, 0.0], [10.0, 10.0], [10.0, 0.0], [0.0, 10.0]];
        assert_eq!(self_intersection(&bow_tie), Some((0, 2)));
        // A vertex touching a non-neighbouring edge.
        let touching = [
            [0.0, 0.0],
            [10.0, 0.0],
            [5.0, 5.0],
            [10.0, 10.0],
            [5.0, 0.0],
        ];
        assert!(self_intersection(&touching).is_some());
        // An edge folding back over its neighbour (a spike of zero width).
        let spike = [[0.0, 0.0], [10.0, 0.0], [5.0, 0.0], [0.0, 10.0]];
        assert!(self_intersection(&spike).is_some());
        // A concave but simple polygon.
        let l_shape = [
            [0.0, 0.0],
            [10.0, 0.0],
            [10.0, 4.0],
            [4.0, 4.0],
            [4.0, 10.0],
            [0.0, 10.0],
        ];
        assert_eq!(self_intersection(&l_shape), None);
    }
}
