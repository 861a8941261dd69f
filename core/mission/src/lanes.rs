//! A survey's lanes: a polygon swept in parallel lanes (boustrophedon), the lanes along
//! the polygon's longest edge (fewest turns for an elongated area), evenly spaced no
//! further apart than asked, each lane the part of its line inside the polygon (a
//! concave polygon may cut one line into several lanes), then split among the vehicles
//! in contiguous blocks so that no two vehicles sweep neighbouring lanes at once except
//! at the blocks' seams.

pub use skein_model::geofence::polygon::{Point, distance};

/// One lane: from `start` to `end`, `[north_m, east_m]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lane {
    /// Where it starts.
    pub start: Point,
    /// Where it ends.
    pub end: Point,
}

impl Lane {
    /// Its length, metres.
    pub fn length_m(&self) -> f64 {
        distance(self.start, self.end)
    }
}

/// The lanes sweeping `polygon` (at least 3 vertices) no more than `spacing_m` apart, in
/// sweep order, alternating direction.
pub fn lanes(polygon: &[Point], spacing_m: f64) -> Vec<Lane> {
    let Some(Across { n, step, ymin }) = across(polygon, spacing_m) else {
        return Vec::new();
    };
    let heading = longest_edge_heading(polygon);
    // The polygon turned so that the lanes run along x.
    let turned: Vec<Point> = polygon.iter().map(|p| rotate(*p, -heading)).collect();
    let mut out = Vec::new();
    for k in 0..n {
        let y = ymin + (k as f64 + 0.5) * step;
        for (x0, x1) in crossings(&turned, y) {
            let (a, b) = if out.len() % 2 == 0 {
                (x0, x1)
            } else {
                (x1, x0)
            };
            out.push(Lane {
                start: rotate([a, y], heading),
                end: rotate([b, y], heading),
            });
        }
    }
    out
}

/// How [`lanes`] divides `polygon` across its lanes for an asked `spacing_m`: `(count,
/// spacing_m)`, the spacing the lanes actually get (the width divided evenly, so at most
/// the one asked); `None` for fewer than 3 vertices or a spacing not above 0.
pub fn lane_spacing(polygon: &[Point], spacing_m: f64) -> Option<(usize, f64)> {
    across(polygon, spacing_m).map(|a| (a.n, a.step))
}

/// The polygon's width across its lanes and its division into `n` lanes `step` apart.
struct Across {
    n: usize,
    step: f64,
    ymin: f64,
}

fn across(polygon: &[Point], spacing_m: f64) -> Option<Across> {
    if polygon.len() < 3 || spacing_m.is_nan() || spacing_m <= 0.0 {
        return None;
    }
    let heading = longest_edge_heading(polygon);
    let (ymin, ymax) = polygon
        .iter()
        .map(|p| rotate(*p, -heading)[1])
        .fold((f64::MAX, f64::MIN), |(lo, hi), y| (lo.min(y), hi.max(y)));
    // (Less a hair: a width of exactly n spacings, turned, must give n lanes, not n + 1.)
    let n = ((ymax - ymin) / spacing_m - 1e-9).ceil().max(1.0) as usize;
    Some(Across {
        n,
        step: (ymax - ymin) / n as f64,
        ymin,
    })
}

/// The direction of the polygon's longest edge, radians from the north axis.
fn longest_edge_heading(polygon: &[Point]) -> f64 {
    let n = polygon.len();
    let (a, b) = (0..n)
        .map(|i| (polygon[i], polygon[(i + 1) % n]))
        .max_by(|x, y| distance(x.0, x.1).total_cmp(&distance(y.0, y.1)))
        .expect("at least 3 vertices");
    (b[1] - a[1]).atan2(b[0] - a[0])
}

/// `p` turned by `angle` radians (north toward east).
fn rotate(p: Point, angle: f64) -> Point {
    let (s, c) = angle.sin_cos();
    [p[0] * c - p[1] * s, p[0] * s + p[1] * c]
}

/// The stretches of the line `y` inside `polygon`, as `(x_from, x_to)` pairs, west to
/// east (even-odd rule).
fn crossings(polygon: &[Point], y: f64) -> Vec<(f64, f64)> {
    let n = polygon.len();
    let mut xs: Vec<f64> = (0..n)
        .filter_map(|i| {
            let (a, b) = (polygon[i], polygon[(i + 1) % n]);
            let crosses = (a[1] <= y && y < b[1]) || (b[1] <= y && y < a[1]);
            crosses.then(|| a[0] + (y - a[1]) * (b[0] - a[0]) / (b[1] - a[1]))
        })
        .collect();
    xs.sort_by(f64::total_cmp);
    xs.chunks_exact(2).map(|c| (c[0], c[1])).collect()
}

/// `lanes` split among `vehicles` in contiguous blocks (the first blocks a lane longer
/// when they do not divide evenly); block `i` for vehicle `i`.
pub fn split(lanes: &[Lane], vehicles: usize) -> Vec<Vec<Lane>> {
    let vehicles = vehicles.max(1);
    let (base, extra) = (lanes.len() / vehicles, lanes.len() % vehicles);
    let mut out = Vec::with_capacity(vehicles);
    let mut at = 0;
    for i in 0..vehicles {
        let n = base + usize::from(i < extra);
        out.push(lanes[at..at + n].to_vec());
        at += n;
    }
    out
}

/// The points each vehicle flies to sweep its block (`blocks[i]` from `from[i]`), in
/// lockstep: every block swept across its lanes in the same order, and the `j`-th lane of
/// every block flown in the same direction, so that neighbouring vehicles move alike,
/// a block apart, and never meet head-on on adjacent lanes. Of the four ways (order ×
/// direction), the one whose starts lie nearest the vehicles in sum.
pub fn sweep(blocks: &[Vec<Lane>], from: &[Point]) -> Vec<Vec<Point>> {
    let Some(reference) = blocks.iter().flatten().next() else {
        return blocks.iter().map(|_| Vec::new()).collect();
    };
    let u = [
        reference.end[0] - reference.start[0],
        reference.end[1] - reference.start[1],
    ];
    let way = |block: &[Lane], ascending: bool, sign: f64| -> Vec<Point> {
        let ordered: Vec<&Lane> = if ascending {
            block.iter().collect()
        } else {
            block.iter().rev().collect()
        };
        ordered
            .iter()
            .enumerate()
            .flat_map(|(j, l)| {
                let along = (l.end[0] - l.start[0]) * u[0] + (l.end[1] - l.start[1]) * u[1];
                let wanted = if j % 2 == 0 { sign } else { -sign };
                if along * wanted >= 0.0 {
                    [l.start, l.end]
                } else {
                    [l.end, l.start]
                }
            })
            .collect()
    };
    let options = [(true, 1.0), (true, -1.0), (false, 1.0), (false, -1.0)];
    let cost = |(ascending, sign): (bool, f64)| -> f64 {
        blocks
            .iter()
            .zip(from)
            .filter_map(|(b, f)| way(b, ascending, sign).first().map(|p| distance(*p, *f)))
            .sum()
    };
    let best = options
        .into_iter()
        .min_by(|a, b| cost(*a).total_cmp(&cost(*b)))
        .expect("four options");
    blocks.iter().map(|b| way(b, best.0, best.1)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const SQUARE: [Point; 4] = [[0.0, 0.0], [0.0, 100.0], [60.0, 100.0], [60.0, 0.0]];

    #[test]
    fn a_rectangle_is_swept_along_its_long_side_in_alternating_lanes() {
        let l = lanes(&SQUARE, 10.0);
        // 60 m across at 10 m: 6 lanes, 100 m long, running east or west.
        assert_eq!(l.len(), 6);
        for (i, lane) in l.iter().enumerate() {
            assert!((lane.length_m() - 100.0).abs() < 1e-6, "{lane:?}");
            assert!(
                (lane.start[0] - lane.end[0]).abs() < 1e-6,
                "along east: {lane:?}"
            );
            if i > 0 {
                // Each lane starts across from where the last one ended.
                assert!((lane.start[1] - l[i - 1].end[1]).abs() < 1e-6, "{l:?}");
            }
        }
        let norths: Vec<f64> = l.iter().map(|x| x.start[0].abs()).collect();
        assert!(
            (norths[0] - 5.0).abs() < 1e-6 && (norths[5] - 55.0).abs() < 1e-6,
            "{norths:?}"
        );
    }

    #[test]
    fn lanes_never_lie_further_apart_than_asked() {
        let l = lanes(&SQUARE, 7.0);
        // 60 / 7 → 9 lanes, 6.67 m apart.
        assert_eq!(l.len(), 9);
        let gap = (l[1].start[0] - l[0].start[0]).abs();
        assert!(gap <= 7.0 && (gap - 60.0 / 9.0).abs() < 1e-6, "{gap}");
    }

    #[test]
    fn a_concave_polygon_cuts_a_line_into_two_lanes() {
        // A U open to the north: the lanes across its arms are two each.
        let u = [
            [0.0, 0.0],
            [0.0, 90.0],
            [60.0, 90.0],
            [60.0, 60.0],
            [20.0, 60.0],
            [20.0, 30.0],
            [60.0, 30.0],
            [60.0, 0.0],
        ];
        let l = lanes(&u, 10.0);
        let inside = |p: Point| skein_model::geofence::polygon::inside(&u, p);
        for lane in &l {
            let mid = [
                (lane.start[0] + lane.end[0]) / 2.0,
                (lane.start[1] + lane.end[1]) / 2.0,
            ];
            assert!(inside(mid), "a lane crosses the notch: {lane:?}");
        }
        assert!(l.len() > 9, "the arms' lines are cut in two: {}", l.len());
    }

    #[test]
    fn lanes_split_in_contiguous_blocks() {
        let l = lanes(&SQUARE, 10.0);
        let blocks = split(&l, 4);
        let sizes: Vec<usize> = blocks.iter().map(Vec::len).collect();
        assert_eq!(sizes, [2, 2, 1, 1]);
        assert_eq!(blocks[0][1], l[1]);
        assert_eq!(blocks[3][0], l[5]);
        let w = &sweep(&blocks[..1], &[[0.0, 0.0]])[0];
        assert_eq!(w.len(), 4);
        // Flown from the corner nearest the vehicle, lane by lane.
        assert!(distance(w[0], [5.0, 0.0]) < 1e-6, "{w:?}");
        assert!(distance(w[1], [5.0, 100.0]) < 1e-6 && distance(w[2], [15.0, 100.0]) < 1e-6);
        assert!(lanes(&SQUARE[..2], 10.0).is_empty());
    }

    #[test]
    fn blocks_are_swept_in_lockstep() {
        let l = lanes(&SQUARE, 10.0);
        let blocks = split(&l, 3);
        let ways = sweep(&blocks, &[[0.0, 0.0], [0.0, 5.0], [0.0, 10.0]]);
        // Every block's j-th lane runs the same way, blocks swept in the same order.
        for j in 0..2 {
            let dirs: Vec<f64> = ways.iter().map(|w| w[2 * j + 1][1] - w[2 * j][1]).collect();
            assert!(
                dirs.iter().all(|d| d.signum() == dirs[0].signum()),
                "{ways:?}"
            );
        }
        let across: Vec<f64> = ways.iter().map(|w| w[2][0] - w[0][0]).collect();
        assert!(
            across.iter().all(|d| d.signum() == across[0].signum()),
            "{ways:?}"
        );
        // From the south-west: the lanes start at the west end.
        assert!(ways.iter().all(|w| w[0][1].abs() < 1e-6), "{ways:?}");
    }
}
