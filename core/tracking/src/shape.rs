//! The shape of a hostile swarm from its members' horizontal positions: a line, a wedge
//! (V) or a loose cluster, where it points, and its extent.
//!
//! - **Line**: the members' spread across their principal axis is under
//!   [`LINE_RATIO`] of the spread along it (the square roots of the position covariance's
//!   eigenvalues); two members are always a line. It points along that axis (0–180°).
//! - **Wedge**: seen along some forward direction (the course when the swarm moves, or
//!   its reverse; else either way along either principal axis), one member leads and every other lies
//!   behind it on one side or the other, swept back by at least [`MIN_SWEEP`] of its
//!   lateral offset, members on both sides, and each arm straight (every member's
//!   sweep-back ratio within [`ARM_TOLERANCE`] of its arm's mean). It points from the
//!   arms towards the leading member.
//! - **Cluster**: anything else; it points along its course (or its principal axis when it
//!   hovers).
//!
//! Positions are swarm-frame (north, east), metres; headings degrees clockwise from north.

use skein_protocol::tracks::{SwarmExtent, SwarmShape};

/// A line's spread across its axis is under this fraction of the spread along it.
pub const LINE_RATIO: f64 = 0.3;
/// A wedge's members lie behind the leader by at least this fraction of their lateral
/// offset from it.
pub const MIN_SWEEP: f64 = 0.3;
/// Each member's sweep-back ratio (behind / lateral) is within this fraction of its arm's
/// mean.
pub const ARM_TOLERANCE: f64 = 0.45;
/// Below this speed a swarm has no course, m/s.
pub const MIN_COURSE_SPEED_M_S: f64 = 1.0;

/// A swarm's shape, where it points and its extent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShapeEstimate {
    /// The shape.
    pub shape: SwarmShape,
    /// Degrees clockwise from north: a wedge's apex direction, a line's axis (0..180), a
    /// cluster's course.
    pub heading_deg: f64,
    /// Length along `heading_deg`, width across, radius about the centroid.
    pub extent: SwarmExtent,
}

fn unit(heading_rad: f64) -> [f64; 2] {
    [heading_rad.cos(), heading_rad.sin()]
}

fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

/// `deg` in [0, 360).
fn wrap360(deg: f64) -> f64 {
    deg.rem_euclid(360.0)
}

/// How well `rel` (positions about the centroid) form a wedge pointing along
/// `heading_rad`: the spread of the arms' sweep-back ratios (smaller is straighter), or
/// `None` when they are no wedge that way.
fn wedge_fit(rel: &[[f64; 2]], heading_rad: f64) -> Option<f64> {
    let f = unit(heading_rad);
    let r = [-f[1], f[0]];
    let a: Vec<f64> = rel.iter().map(|p| dot(*p, f)).collect();
    let c: Vec<f64> = rel.iter().map(|p| dot(*p, r)).collect();
    let apex = (0..rel.len()).max_by(|&i, &j| a[i].total_cmp(&a[j]))?;
    let spread = c.iter().map(|x| (x - c[apex]).abs()).fold(0.0, f64::max);
    if spread < 1e-6 {
        return None;
    }
    let tol = 0.15 * spread;
    let mut arms: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    for i in (0..rel.len()).filter(|&i| i != apex) {
        let back = a[apex] - a[i];
        let lat = c[i] - c[apex];
        if lat.abs() < tol || back < MIN_SWEEP * lat.abs() {
            return None;
        }
        arms[usize::from(lat > 0.0)].push(back / lat.abs());
    }
    if arms.iter().any(Vec::is_empty) {
        return None;
    }
    let mut worst: f64 = 0.0;
    for arm in &arms {
        let mean = arm.iter().sum::<f64>() / arm.len() as f64;
        for ratio in arm {
            let dev = (ratio - mean).abs() / mean;
            if dev > ARM_TOLERANCE {
                return None;
            }
            worst = worst.max(dev);
        }
    }
    Some(worst)
}

/// The shape of the members at `points` (north, east) flying at `velocity_ne` (m/s).
pub fn estimate(points: &[[f64; 2]], velocity_ne: [f64; 2]) -> ShapeEstimate {
    let n = points.len().max(1) as f64;
    let c = points
        .iter()
        .fold([0.0, 0.0], |s, p| [s[0] + p[0] / n, s[1] + p[1] / n]);
    let rel: Vec<[f64; 2]> = points.iter().map(|p| [p[0] - c[0], p[1] - c[1]]).collect();
    let (snn, sne, see) = rel.iter().fold((0.0, 0.0, 0.0), |(a, b, d), p| {
        (
            a + p[0] * p[0] / n,
            b + p[0] * p[1] / n,
            d + p[1] * p[1] / n,
        )
    });
    let mid = (snn + see) / 2.0;
    let rad = ((snn - see) / 2.0).hypot(sne);
    let (l1, l2) = ((mid + rad).max(0.0), (mid - rad).max(0.0));
    // The major axis, radians clockwise from north.
    let axis = 0.5 * (2.0 * sne).atan2(snn - see);
    let speed = velocity_ne[0].hypot(velocity_ne[1]);
    let course = (speed >= MIN_COURSE_SPEED_M_S).then(|| velocity_ne[1].atan2(velocity_ne[0]));
    let (shape, heading) = if rel.len() <= 2 || l2.sqrt() < LINE_RATIO * l1.sqrt() {
        (SwarmShape::Line, wrap360(axis.to_degrees()) % 180.0)
    } else {
        let half = std::f64::consts::FRAC_PI_2;
        let candidates: Vec<f64> = match course {
            Some(h) => vec![h, h + 2.0 * half],
            None => (0..4).map(|k| axis + k as f64 * half).collect(),
        };
        let best = candidates
            .iter()
            .filter_map(|&h| Some((h, wedge_fit(&rel, h)?)))
            .min_by(|x, y| x.1.total_cmp(&y.1));
        match best {
            Some((h, _)) => (SwarmShape::Wedge, wrap360(h.to_degrees())),
            None => (
                SwarmShape::Cluster,
                wrap360(course.unwrap_or(axis).to_degrees()),
            ),
        }
    };
    let f = unit(heading.to_radians());
    let r = [-f[1], f[0]];
    let span = |d: [f64; 2]| {
        let along = rel.iter().map(|p| dot(*p, d));
        along.clone().fold(f64::NEG_INFINITY, f64::max) - along.fold(f64::INFINITY, f64::min)
    };
    let extent = if rel.is_empty() {
        SwarmExtent {
            length_m: 0.0,
            width_m: 0.0,
            radius_m: 0.0,
        }
    } else {
        SwarmExtent {
            length_m: span(f),
            width_m: span(r),
            radius_m: rel.iter().map(|p| p[0].hypot(p[1])).fold(0.0, f64::max),
        }
    };
    ShapeEstimate {
        shape,
        heading_deg: heading,
        extent,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A V of `n` flying along `heading_deg`: the leader at `at`, pairs behind it `rank ×
    /// spacing` back and to either side (as the simulator's formation intruders fly).
    fn vee(n: usize, at: [f64; 2], heading_deg: f64, spacing: f64) -> Vec<[f64; 2]> {
        let f = unit(heading_deg.to_radians());
        let r = [-f[1], f[0]];
        (0..n)
            .map(|i| {
                let rank = i.div_ceil(2) as f64;
                let side = if i % 2 == 1 { 1.0 } else { -1.0 };
                let (b, l) = (rank * spacing, side * rank * spacing);
                [at[0] - f[0] * b + r[0] * l, at[1] - f[1] * b + r[1] * l]
            })
            .collect()
    }

    #[test]
    fn a_v_is_a_wedge_pointing_where_it_flies_hovering_or_not() {
        for heading in [0.0, 37.0, 180.0, 290.0] {
            let v = unit(f64::to_radians(heading));
            let pts = vee(5, [40.0, -10.0], heading, 6.0);
            let s = estimate(&pts, [5.0 * v[0], 5.0 * v[1]]);
            assert_eq!(s.shape, SwarmShape::Wedge, "{heading}: {s:?}");
            assert!((s.heading_deg - heading).abs() < 1e-6, "{s:?}");
            // Two ranks back (12 m), 24 m wide.
            assert!((s.extent.length_m - 12.0).abs() < 1e-6, "{s:?}");
            assert!((s.extent.width_m - 24.0).abs() < 1e-6, "{s:?}");
            // Hovering: still a wedge, and its apex is found.
            let still = estimate(&pts, [0.0, 0.0]);
            assert_eq!(still.shape, SwarmShape::Wedge, "{still:?}");
            assert!(
                (wrap360(still.heading_deg - heading + 180.0) - 180.0).abs() < 1e-6,
                "{still:?}"
            );
        }
        // Three are a V too, with 1 m of noise.
        let mut three = vee(3, [0.0, 0.0], 90.0, 6.0);
        three[1][0] += 1.0;
        let s = estimate(&three, [0.0, 5.0]);
        assert_eq!(s.shape, SwarmShape::Wedge, "{s:?}");
    }

    #[test]
    fn lines_abreast_in_trail_and_echelon_are_lines_and_pairs_too() {
        let abreast: Vec<[f64; 2]> = (0..4).map(|i| [10.0, i as f64 * 8.0]).collect();
        let s = estimate(&abreast, [5.0, 0.0]);
        assert_eq!(s.shape, SwarmShape::Line);
        assert!((s.heading_deg - 90.0).abs() < 1e-6, "{s:?}");
        let echelon: Vec<[f64; 2]> = (0..4)
            .map(|i| [-(i as f64) * 6.0 + 0.3 * (i % 2) as f64, i as f64 * 6.0])
            .collect();
        let s = estimate(&echelon, [5.0, 0.0]);
        assert_eq!(s.shape, SwarmShape::Line, "{s:?}");
        assert!((s.heading_deg - 135.0).abs() < 3.0, "{s:?}");
        let pair = estimate(&[[0.0, 0.0], [5.0, 0.0]], [0.0, 3.0]);
        assert_eq!(pair.shape, SwarmShape::Line);
        assert!(pair.heading_deg.abs() < 1e-6);
    }

    #[test]
    fn a_loose_group_is_a_cluster_along_its_course() {
        let pts = [[0.0, 0.0], [7.0, 2.0], [3.0, 9.0], [-4.0, 6.0], [2.0, -5.0]];
        let s = estimate(&pts, [0.0, -4.0]);
        assert_eq!(s.shape, SwarmShape::Cluster, "{s:?}");
        assert!((s.heading_deg - 270.0).abs() < 1e-6);
        assert!(s.extent.radius_m > 5.0 && s.extent.radius_m < 10.0);
        // A V flying backwards is a wedge pointing where its apex is.
        let backwards = vee(5, [0.0, 0.0], 0.0, 6.0);
        let s = estimate(&backwards, [-5.0, 0.0]);
        assert_eq!(s.shape, SwarmShape::Wedge, "{s:?}");
        assert!(s.heading_deg.abs() < 1e-6, "{s:?}");
    }
}
