//! Hazards: a vehicle that no longer follows its setpoints (its link is lost, or PX4
//! failed safe) is most often still in the air. Its last known position is an obstacle
//! whose radius grows with the time since it was last seen, at an assumed drift speed,
//! up to a cap.
//!
//! The formation plans around hazards: [`clearing_shift`] gives the smallest horizontal
//! shift of the slot pattern that puts every slot at least the separation plus the
//! hazard's radius from every hazard (exact along each of a set of directions; the best
//! direction wins); transition paths that would pass one are flown on a layer over it
//! (see `climb`).

use serde::{Deserialize, Serialize};
use skein_model::geo::Ned;

/// Hazard settings (`[hazards]` in the config file).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HazardConfig {
    /// How fast an unseen vehicle is assumed to drift from where it was last seen, m/s.
    pub drift_m_s: f64,
    /// Largest hazard radius, metres (the drift stops growing it there).
    pub max_radius_m: f64,
    /// A vehicle unseen this long stops being a hazard, seconds (by then PX4's own
    /// failsafe, hold or land, has long acted; the operator may clear it earlier).
    pub max_unseen_s: f64,
    /// A formation change whose pacing has held a member this long is planned again from
    /// where the members are, seconds.
    pub replan_after_s: f64,
}

impl Default for HazardConfig {
    fn default() -> Self {
        HazardConfig {
            drift_m_s: 1.0,
            max_radius_m: 10.0,
            max_unseen_s: 300.0,
            replan_after_s: 10.0,
        }
    }
}

impl HazardConfig {
    /// The radius of a hazard unseen for `unseen_s` seconds, metres.
    pub fn radius_m(&self, unseen_s: f64) -> f64 {
        (self.drift_m_s.max(0.0) * unseen_s.max(0.0)).min(self.max_radius_m.max(0.0))
    }
}

/// A vehicle that may still be flying where the formation is not steering it.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct Hazard {
    /// The vehicle's id.
    pub id: String,
    /// Where it was last seen, swarm-frame NED metres.
    pub position: Ned,
    /// How far it may have drifted since, metres (the obstacle's radius).
    pub radius_m: f64,
    /// Seconds since it was last seen.
    pub unseen_s: f64,
    /// Why it is a hazard (`"Lost"`, `"Failsafe"`).
    pub reason: String,
}

impl Hazard {
    /// The distance every slot and path keeps from its position: `separation_m` plus the
    /// radius, metres.
    pub fn clearance_m(&self, separation_m: f64) -> f64 {
        separation_m + self.radius_m
    }
}

/// Directions tried by [`clearing_shift`] besides those straight away from a hazard.
const DIRECTIONS: usize = 72;
/// Margin added to an exact clearing distance, metres (so that rounding cannot leave a
/// slot a hair inside).
const MARGIN_M: f64 = 0.05;

/// The smallest horizontal shift (NED metres, `down_m` 0) that puts every point of
/// `points` at least [`Hazard::clearance_m`] from every hazard; `Some(ZERO)` when they
/// are clear already, `None` when no shift up to `max_m` does it.
pub fn clearing_shift(
    points: &[Ned],
    hazards: &[Hazard],
    separation_m: f64,
    max_m: f64,
) -> Option<Ned> {
    let blocked = |p: Ned, h: &Hazard| (p - h.position).norm() < h.clearance_m(separation_m);
    if !points
        .iter()
        .any(|p| hazards.iter().any(|h| blocked(*p, h)))
    {
        return Some(Ned::ZERO);
    }
    let mut directions: Vec<Ned> = (0..DIRECTIONS)
        .map(|k| {
            let a = k as f64 * std::f64::consts::TAU / DIRECTIONS as f64;
            Ned::new(a.cos(), a.sin(), 0.0)
        })
        .collect();
    for p in points {
        for h in hazards.iter().filter(|h| blocked(*p, h)) {
            let mut away = *p - h.position;
            away.down_m = 0.0;
            if away.norm() > 1e-9 {
                directions.push(away * (1.0 / away.norm()));
            }
        }
    }
    directions
        .into_iter()
        .filter_map(|u| {
            let t = clear_along(points, hazards, separation_m, u)?;
            (t <= max_m).then_some((t, u))
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(t, u)| u * t)
}

/// The smallest `t ≥ 0` such that every point moved by `t·u` is clear of every hazard
/// (`u` a horizontal unit vector), plus [`MARGIN_M`].
fn clear_along(points: &[Ned], hazards: &[Hazard], separation_m: f64, u: Ned) -> Option<f64> {
    // Open intervals of t where some point is inside some hazard's clearance:
    // |d + t·u|² < R²  ⇔  t² + 2t(d·u) + |d|² − R² < 0.
    let mut intervals: Vec<(f64, f64)> = Vec::new();
    for p in points {
        for h in hazards {
            let d = *p - h.position;
            let r = h.clearance_m(separation_m);
            let b = d.north_m * u.north_m + d.east_m * u.east_m;
            let disc = b * b - (d.norm_squared() - r * r);
            if disc > 0.0 {
                let s = disc.sqrt();
                intervals.push((-b - s, -b + s));
            }
        }
    }
    let mut t = 0.0f64;
    loop {
        let inside = intervals
            .iter()
            .filter(|(a, b)| *a - MARGIN_M < t && t < *b + MARGIN_M)
            .map(|(_, b)| *b + MARGIN_M)
            .fold(f64::NAN, f64::max);
        if inside.is_nan() {
            return t.is_finite().then_some(t);
        }
        t = inside;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hazard(n: f64, e: f64, radius_m: f64) -> Hazard {
        Hazard {
            id: "uav-1".into(),
            position: Ned::new(n, e, -10.0),
            radius_m,
            unseen_s: radius_m,
            reason: "Lost".into(),
        }
    }

    fn clear(points: &[Ned], hazards: &[Hazard], sep: f64) -> bool {
        points.iter().all(|p| {
            hazards
                .iter()
                .all(|h| (*p - h.position).norm() >= h.clearance_m(sep))
        })
    }

    #[test]
    fn the_radius_grows_with_time_unseen_up_to_the_cap() {
        let c = HazardConfig::default();
        assert_eq!(c.radius_m(0.0), 0.0);
        assert!((c.radius_m(4.5) - 4.5).abs() < 1e-12);
        assert_eq!(c.radius_m(60.0), 10.0);
    }

    #[test]
    fn clear_points_need_no_shift() {
        let pts = [Ned::new(0.0, 20.0, -10.0)];
        assert_eq!(
            clearing_shift(&pts, &[hazard(0.0, 0.0, 2.0)], 3.5, 100.0),
            Some(Ned::ZERO)
        );
    }

    #[test]
    fn one_slot_moves_straight_away_by_what_is_missing() {
        // A slot 1 m east of a hazard of radius 2: it must be 5.5 m away, so 4.5 m east.
        let pts = [Ned::new(0.0, 1.0, -10.0)];
        let h = [hazard(0.0, 0.0, 2.0)];
        let s = clearing_shift(&pts, &h, 3.5, 100.0).unwrap();
        assert!((s.east_m - 4.5).abs() < 0.1, "{s:?}");
        assert!(s.north_m.abs() < 1e-6 && s.down_m == 0.0, "{s:?}");
        let moved: Vec<Ned> = pts.iter().map(|p| *p + s).collect();
        assert!(clear(&moved, &h, 3.5));
    }

    #[test]
    fn a_line_over_a_hazard_slides_the_short_way_off_it() {
        // A line east-west of 3 slots 7 m apart, the hazard just south of the middle one:
        // moving north clears every slot with the least motion.
        let pts = [
            Ned::new(0.0, -7.0, -10.0),
            Ned::new(0.0, 0.0, -10.0),
            Ned::new(0.0, 7.0, -10.0),
        ];
        let h = [hazard(-1.0, 0.0, 1.0)];
        let s = clearing_shift(&pts, &h, 3.5, 100.0).unwrap();
        assert!(s.north_m > 3.0 && s.north_m < 3.7, "{s:?}");
        let moved: Vec<Ned> = pts.iter().map(|p| *p + s).collect();
        assert!(clear(&moved, &h, 3.5));
    }

    #[test]
    fn two_hazards_are_cleared_together_or_not_at_all() {
        let pts = [Ned::new(0.0, 0.0, -10.0), Ned::new(0.0, 6.0, -10.0)];
        let h = [hazard(0.0, -2.0, 3.0), hazard(0.0, 9.0, 3.0)];
        let s = clearing_shift(&pts, &h, 3.5, 100.0).unwrap();
        let moved: Vec<Ned> = pts.iter().map(|p| *p + s).collect();
        assert!(clear(&moved, &h, 3.5), "{s:?}");
        assert_eq!(clearing_shift(&pts, &h, 3.5, 1.0), None);
    }
}
