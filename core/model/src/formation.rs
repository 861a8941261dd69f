//! Formation geometry: shapes, slot offsets, the swarm-frame slot positions, and optimal
//! slot assignment.
//!
//! Offsets are expressed in the *formation frame*: `north_m` is forward along the
//! formation heading, `east_m` is to the right, `down_m` is down. Slot 0 is always the
//! leader at `(0, 0, 0)`. [`slot_positions`] turns offsets into swarm-frame positions
//! around the leader; [`assign_slots`] gives every follower a slot with minimum total
//! squared distance (Kuhn–Munkres from the `pathfinding` crate).

use crate::geo::Ned;
use pathfinding::prelude::{Matrix, kuhn_munkres_min};
use serde::{Deserialize, Serialize};

/// A formation shape.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum Shape {
    /// Line abreast: side by side across the heading, the leader in the middle, followers
    /// alternating right and left at `spacing_m`.
    Line,
    /// Column (line astern): one behind the other, the leader in front.
    Column,
    /// Wedge (V): the leader at the apex, followers alternating on the right and left
    /// arms, each arm at 45° behind the leader, `spacing_m` between neighbours on an arm.
    Wedge,
    /// Echelon right: a single 45° arm behind and to the right of the leader.
    EchelonRight,
    /// Echelon left: a single 45° arm behind and to the left of the leader.
    EchelonLeft,
    /// Diamond: a square lattice turned 45°, the leader at the front corner, filled rank
    /// by rank (4 vehicles: front, left, right, rear).
    Diamond,
    /// Circle (ring): equally spaced on a ring whose chord between neighbours is
    /// `spacing_m`, the leader at the front of the ring.
    Circle,
    /// Grid (box): rows across the heading, `ceil(sqrt(n))` per row, the leader in the
    /// middle of the front row.
    Grid,
    /// Custom: follower offsets given by the operator.
    Custom,
}

impl Shape {
    /// Every shape, with its API name.
    pub const ALL: [Shape; 9] = [
        Shape::Line,
        Shape::Column,
        Shape::Wedge,
        Shape::EchelonRight,
        Shape::EchelonLeft,
        Shape::Diamond,
        Shape::Circle,
        Shape::Grid,
        Shape::Custom,
    ];

    /// The API name (`"echelon_right"`).
    pub fn name(self) -> &'static str {
        match self {
            Shape::Line => "line",
            Shape::Column => "column",
            Shape::Wedge => "wedge",
            Shape::EchelonRight => "echelon_right",
            Shape::EchelonLeft => "echelon_left",
            Shape::Diamond => "diamond",
            Shape::Circle => "circle",
            Shape::Grid => "grid",
            Shape::Custom => "custom",
        }
    }

    /// Parses an API name.
    pub fn from_name(name: &str) -> Option<Shape> {
        Shape::ALL.into_iter().find(|s| s.name() == name)
    }

    /// Fewest vehicles the shape needs to be recognisable.
    pub fn min_vehicles(self) -> usize {
        match self {
            Shape::Line | Shape::Column | Shape::EchelonRight | Shape::EchelonLeft => 2,
            Shape::Wedge | Shape::Circle => 3,
            Shape::Diamond | Shape::Grid => 4,
            Shape::Custom => 1,
        }
    }
}

const FRAC_1_SQRT_2: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// Slot offsets for `n` vehicles in the formation frame; element 0 is the leader's slot
/// `(0, 0, 0)`, every two slots at least `spacing_m` apart. Returns an empty vector for
/// `n == 0`. [`Shape::Custom`] has no generated offsets: use [`custom_offsets`].
pub fn slot_offsets(shape: Shape, n: usize, spacing_m: f64) -> Vec<Ned> {
    let s = spacing_m;
    // k-th neighbour on alternating sides: 1 → +1 (right), 2 → −1, 3 → +2, 4 → −2 …
    let alternate = |i: usize| -> (f64, f64) {
        let k = i.div_ceil(2) as f64;
        let side = if i % 2 == 1 { 1.0 } else { -1.0 };
        (k, side)
    };
    match shape {
        Shape::Line => (0..n)
            .map(|i| {
                let (k, side) = alternate(i);
                Ned::new(0.0, side * k * s, 0.0)
            })
            .collect(),
        Shape::Column => (0..n)
            .map(|i| Ned::new(-(i as f64) * s, 0.0, 0.0))
            .collect(),
        Shape::Wedge => (0..n)
            .map(|i| {
                let (k, side) = alternate(i);
                Ned::new(-k * s * FRAC_1_SQRT_2, side * k * s * FRAC_1_SQRT_2, 0.0)
            })
            .collect(),
        Shape::EchelonRight | Shape::EchelonLeft => {
            let side = if shape == Shape::EchelonRight {
                1.0
            } else {
                -1.0
            };
            (0..n)
                .map(|i| {
                    let k = i as f64;
                    Ned::new(-k * s * FRAC_1_SQRT_2, side * k * s * FRAC_1_SQRT_2, 0.0)
                })
                .collect()
        }
        Shape::Diamond => {
            // Lattice points (i, j), i, j < K, at forward −(i+j)·d, right (i−j)·d with
            // d = s/√2 (neighbours s apart); rank i+j from the front, centre-out in a rank.
            let k = (n as f64).sqrt().ceil().max(1.0) as usize;
            let d = s * FRAC_1_SQRT_2;
            let mut pts: Vec<(usize, i64, i64)> = Vec::new();
            for i in 0..k {
                for j in 0..k {
                    let side = i as i64 - j as i64;
                    pts.push((i + j, side.abs(), -side));
                }
            }
            // Rank, then distance from the centre line, then right (negative key) first.
            pts.sort();
            pts.into_iter()
                .take(n)
                .map(|(rank, _, neg_side)| {
                    Ned::new(-(rank as f64) * d, -(neg_side as f64) * d, 0.0)
                })
                .collect()
        }
        Shape::Circle => {
            if n < 2 {
                return vec![Ned::ZERO; n];
            }
            let r = s / (2.0 * (std::f64::consts::PI / n as f64).sin());
            (0..n)
                .map(|i| {
                    // Alternate around the ring from the leader: right, left, right …
                    let (k, side) = alternate(i);
                    let theta = side * k * std::f64::consts::TAU / n as f64;
                    Ned::new(-r + r * theta.cos(), r * theta.sin(), 0.0)
                })
                .collect()
        }
        Shape::Grid => {
            if n == 0 {
                return vec![];
            }
            let cols = (n as f64).sqrt().ceil() as usize;
            let centre = (cols as f64 - 1.0) / 2.0;
            let leader_col = (cols - 1) / 2;
            let leader = Ned::new(0.0, (leader_col as f64 - centre) * s, 0.0);
            let mut pts: Vec<Ned> = (0..n)
                .map(|i| {
                    let (row, col) = (i / cols, i % cols);
                    Ned::new(-(row as f64) * s, (col as f64 - centre) * s, 0.0) - leader
                })
                .collect();
            pts.swap(0, leader_col.min(n - 1));
            pts
        }
        Shape::Custom => vec![Ned::ZERO; n.min(1)],
    }
}

/// Slot offsets of a [`Shape::Custom`] formation: the leader at `(0, 0, 0)`, then the
/// operator's follower offsets (formation frame: forward, right, down).
pub fn custom_offsets(followers: &[Ned]) -> Vec<Ned> {
    std::iter::once(Ned::ZERO)
        .chain(followers.iter().copied())
        .collect()
}

/// Smallest distance between two slots (`None` for fewer than two).
pub fn min_slot_distance(offsets: &[Ned]) -> Option<f64> {
    let mut best: Option<f64> = None;
    for (i, a) in offsets.iter().enumerate() {
        for b in &offsets[i + 1..] {
            let d = (*a - *b).norm();
            best = Some(best.map_or(d, |m| m.min(d)));
        }
    }
    best
}

/// Swarm-frame positions of the slots: each offset rotated by the formation heading
/// (`heading_rad`, clockwise from north) and added to the leader's position.
pub fn slot_positions(offsets: &[Ned], leader: Ned, heading_rad: f64) -> Vec<Ned> {
    offsets
        .iter()
        .map(|o| leader + o.rotated_yaw(heading_rad))
        .collect()
}

/// Assigns `positions[i]` to slot `result[i]` so that the total squared distance is
/// minimal. Needs `positions.len() <= slots.len()`; returns an empty vector when there
/// are no positions. Distances are scaled to integer square millimetres for the
/// Kuhn–Munkres solver, which needs integer weights.
///
/// # Panics
/// If there are more positions than slots.
pub fn assign_slots(positions: &[Ned], slots: &[Ned]) -> Vec<usize> {
    assert!(
        positions.len() <= slots.len(),
        "{} vehicles for {} slots",
        positions.len(),
        slots.len()
    );
    if positions.is_empty() {
        return Vec::new();
    }
    let weights = Matrix::from_fn(positions.len(), slots.len(), |(i, j)| {
        ((positions[i] - slots[j]).norm_squared() * 1e6).round() as i64
    });
    kuhn_munkres_min(&weights).1
}

/// Total squared distance of an assignment (for tests and metrics).
pub fn assignment_cost(positions: &[Ned], slots: &[Ned], assignment: &[usize]) -> f64 {
    positions
        .iter()
        .zip(assignment)
        .map(|(p, &s)| (*p - slots[s]).norm_squared())
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn line_offsets_for_1_to_12_vehicles() {
        for n in 1..=12 {
            let offs = slot_offsets(Shape::Line, n, 5.0);
            assert_eq!(offs.len(), n);
            assert_eq!(offs[0], Ned::ZERO, "leader first");
            let mut east: Vec<f64> = offs.iter().map(|o| o.east_m).collect();
            assert!(offs.iter().all(|o| o.north_m == 0.0 && o.down_m == 0.0));
            east.sort_by(f64::total_cmp);
            for w in east.windows(2) {
                assert!((w[1] - w[0] - 5.0).abs() < 1e-9, "spacing, n={n}: {east:?}");
            }
            // Leader in the middle: as many slots left as right (one more right if even).
            let right = offs.iter().filter(|o| o.east_m > 0.0).count();
            let left = offs.iter().filter(|o| o.east_m < 0.0).count();
            assert_eq!(right, n / 2);
            assert_eq!(left, (n - 1) / 2);
        }
        assert!(slot_offsets(Shape::Line, 0, 5.0).is_empty());
    }

    /// Mirror image of a set of offsets across the forward axis matches itself.
    fn symmetric(offs: &[Ned]) -> bool {
        offs.iter().all(|o| {
            let mirrored = Ned::new(o.north_m, -o.east_m, o.down_m);
            offs.iter().any(|p| (*p - mirrored).norm() < 1e-6)
        })
    }

    #[test]
    fn every_shape_for_1_to_12_vehicles() {
        let s = 4.0;
        for shape in Shape::ALL.into_iter().filter(|s| *s != Shape::Custom) {
            for n in 1..=12 {
                let offs = slot_offsets(shape, n, s);
                assert_eq!(offs.len(), n, "{shape:?} n={n}");
                assert!(
                    offs[0].norm() < 1e-9,
                    "{shape:?} n={n}: leader at the origin"
                );
                if let Some(d) = min_slot_distance(&offs) {
                    assert!(d >= s - 1e-6, "{shape:?} n={n}: slots {d} m apart");
                }
                assert!(offs.iter().all(|o| o.down_m == 0.0 && o.is_finite()));
                // Nobody ahead of the leader (the leader leads), except across a ring.
                if !matches!(shape, Shape::Line | Shape::Grid) {
                    assert!(
                        offs.iter().all(|o| o.north_m <= 1e-9),
                        "{shape:?} n={n}: {offs:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn shapes_have_their_geometry() {
        let s = 5.0;
        // Column: straight back.
        let c = slot_offsets(Shape::Column, 4, s);
        assert!((c[3] - Ned::new(-15.0, 0.0, 0.0)).norm() < 1e-9);
        // Wedge: two 45° arms, symmetric for odd n.
        let w = slot_offsets(Shape::Wedge, 5, s);
        assert!(symmetric(&w));
        assert!((w[1].north_m + w[1].east_m).abs() < 1e-9, "45°: {:?}", w[1]);
        // Echelons: one arm, mirror images.
        let r = slot_offsets(Shape::EchelonRight, 4, s);
        let l = slot_offsets(Shape::EchelonLeft, 4, s);
        assert!(r[1..].iter().all(|o| o.east_m > 0.0) && l[1..].iter().all(|o| o.east_m < 0.0));
        for (a, b) in r.iter().zip(&l) {
            assert!((a.east_m + b.east_m).abs() < 1e-9 && a.north_m == b.north_m);
        }
        // Diamond of 4: front, right, left, rear; symmetric; rear 2·s/√2·√2 = s·√2 back.
        let d = slot_offsets(Shape::Diamond, 4, s);
        assert!(symmetric(&d), "{d:?}");
        assert!(
            (d[3] - Ned::new(-s * 2.0f64.sqrt(), 0.0, 0.0)).norm() < 1e-9,
            "{d:?}"
        );
        assert!(symmetric(&slot_offsets(Shape::Diamond, 9, s)));
        // Circle: every slot on one ring, neighbours a chord of s apart, symmetric.
        for n in 3..=12 {
            let ring = slot_offsets(Shape::Circle, n, s);
            let r = s / (2.0 * (std::f64::consts::PI / n as f64).sin());
            let centre = Ned::new(-r, 0.0, 0.0);
            assert!(
                ring.iter().all(|p| ((*p - centre).norm() - r).abs() < 1e-9),
                "n={n}"
            );
            assert!(
                (min_slot_distance(&ring).unwrap() - s).abs() < 1e-9,
                "n={n}"
            );
            assert!(symmetric(&ring) || n % 2 == 0, "n={n}");
        }
        // Grid of 9: 3×3, leader in the middle of the front row, symmetric.
        let g = slot_offsets(Shape::Grid, 9, s);
        assert!(symmetric(&g), "{g:?}");
        assert_eq!(g.iter().filter(|o| o.north_m == 0.0).count(), 3);
        assert!(
            g.iter()
                .any(|o| (*o - Ned::new(-2.0 * s, s, 0.0)).norm() < 1e-9)
        );
    }

    #[test]
    fn custom_offsets_put_the_leader_first() {
        let c = custom_offsets(&[Ned::new(-3.0, 4.0, 0.0), Ned::new(-3.0, -4.0, -2.0)]);
        assert_eq!(c.len(), 3);
        assert_eq!(c[0], Ned::ZERO);
        assert!((min_slot_distance(&c).unwrap() - 5.0).abs() < 1e-9);
    }

    #[test]
    fn heading_turns_the_line() {
        let offs = slot_offsets(Shape::Line, 3, 4.0);
        let leader = Ned::new(10.0, 20.0, -10.0);
        let slots = slot_positions(&offs, leader, std::f64::consts::FRAC_PI_2);
        // Heading east: "right" is south.
        assert!(
            (slots[1] - Ned::new(6.0, 20.0, -10.0)).norm() < 1e-9,
            "{slots:?}"
        );
        assert!((slots[2] - Ned::new(14.0, 20.0, -10.0)).norm() < 1e-9);
    }

    #[test]
    fn shape_names_round_trip() {
        for s in Shape::ALL {
            assert_eq!(Shape::from_name(s.name()), Some(s));
        }
        assert_eq!(Shape::from_name("hexagon"), None);
    }

    fn brute_force_min(positions: &[Ned], slots: &[Ned]) -> f64 {
        fn rec(i: usize, used: &mut Vec<bool>, p: &[Ned], s: &[Ned]) -> f64 {
            if i == p.len() {
                return 0.0;
            }
            let mut best = f64::INFINITY;
            for j in 0..s.len() {
                if !used[j] {
                    used[j] = true;
                    best = best.min((p[i] - s[j]).norm_squared() + rec(i + 1, used, p, s));
                    used[j] = false;
                }
            }
            best
        }
        rec(0, &mut vec![false; slots.len()], positions, slots)
    }

    fn ned_strategy() -> impl Strategy<Value = Ned> {
        (-50.0..50.0f64, -50.0..50.0f64, -20.0..0.0f64).prop_map(|(n, e, d)| Ned::new(n, e, d))
    }

    proptest! {
        #[test]
        fn assignment_equals_brute_force(
            (positions, slots) in (1usize..=7).prop_flat_map(|n| (
                proptest::collection::vec(ned_strategy(), n),
                proptest::collection::vec(ned_strategy(), n),
            ))
        ) {
            let a = assign_slots(&positions, &slots);
            let mut seen = a.clone();
            seen.sort_unstable();
            seen.dedup();
            prop_assert_eq!(seen.len(), positions.len(), "a permutation");
            let cost = assignment_cost(&positions, &slots, &a);
            let best = brute_force_min(&positions, &slots);
            // Integer scaling loses at most 0.5e-6 m² per pair.
            prop_assert!((cost - best).abs() < 1e-4, "hungarian {} vs brute force {}", cost, best);
        }
    }
}
