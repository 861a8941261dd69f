//! Observation geometry: the stations from which observation UAVs fix a target best.
//!
//! A target (one track, or the members of a swarm) is seen by cameras whose bearings are
//! triangulated ([`super::geometry::fuse_rays`]): each bearing of an observer at range `r`
//! adds information `P⊥(d) / (σ r)²` across its ray, so the predicted covariance of the fix
//! is `(Σ P⊥(dᵢ) / (σ rᵢ)²)⁻¹`. It is small when the observers are close and their rays
//! cross at a wide angle (90° for two), and grows without bound as the rays become
//! parallel: a baseline of 6–16 m at 60–90 m (the observers where they hover) fixes the
//! range ten times worse than the bearing.
//!
//! [`plan`] places each observer on a station around the target's predicted position that
//! minimises the mean predicted horizontal variance over the target's points (its members'
//! forecasts), times `1 + travel / TRAVEL_SCALE_M` (of two equally good layouts, the one
//! nearer the observers), subject to:
//! - the stand-off: every station at least `standoff_m` horizontally from every target
//!   point, and from every point of `clear` (where the target is now: the station must
//!   not lie on its way there);
//! - the camera: every target point within `max_range_m`, and the target's points within
//!   [`FOV_USE`] of the camera's horizontal field of view seen from the station (the gimbal
//!   points at the target's centre, so all of it stays in the picture);
//! - the formation engine's checks: stations at least `min_separation_m` apart and from
//!   every other vehicle (`obstacles`), and inside the geofence shrunk by
//!   `fence_margin_m`.
//!
//! Candidates lie on rings about the target's centre every [`RING_STEP_DEG`] and
//! [`RING_STEP_M`], at each observer's own altitude; the search starts from each observer's
//! nearest feasible candidate and improves one observer at a time until no move helps
//! (coordinate descent, at most [`MAX_SWEEPS`] sweeps). Positions are swarm-frame NED,
//! metres.

use nalgebra::{Matrix3, Vector3};
use skein_model::geo::Ned;
use skein_model::geofence::Geofence;

/// Bearings of the candidate rings, degrees apart.
pub const RING_STEP_DEG: f64 = 10.0;
/// Radii of the candidate rings, metres apart.
pub const RING_STEP_M: f64 = 10.0;
/// Sweeps of the coordinate descent, at most.
pub const MAX_SWEEPS: usize = 6;
/// The target's points span at most this fraction of the camera's field of view.
pub const FOV_USE: f64 = 0.8;
/// Travel that costs as much as doubling the variance, metres (summed over observers).
pub const TRAVEL_SCALE_M: f64 = 400.0;

/// What the stations must respect.
#[derive(Debug, Clone, PartialEq)]
pub struct StationLimits {
    /// Least horizontal distance from every target point, metres.
    pub standoff_m: f64,
    /// Greatest distance to every target point (the cameras' useful range), metres.
    pub max_range_m: f64,
    /// Least distance between stations and from other vehicles, metres.
    pub min_separation_m: f64,
    /// The cameras' horizontal field of view, degrees.
    pub fov_deg: f64,
    /// Bearing noise of the detections, radians (scales the predicted variance).
    pub bearing_sigma_rad: f64,
    /// The geofence.
    pub fence: Geofence,
    /// How far inside the fence a station stays, metres.
    pub fence_margin_m: f64,
}

/// One observer: its id and where it is.
#[derive(Debug, Clone, PartialEq)]
pub struct Observer {
    /// Vehicle id.
    pub id: String,
    /// Its position now, swarm-frame NED.
    pub position: Ned,
}

/// The chosen stations and how well they fix the target.
#[derive(Debug, Clone, PartialEq)]
pub struct StationPlan {
    /// Vehicle id → station, swarm-frame NED, in the order of the observers given.
    pub stations: Vec<(String, Ned)>,
    /// Predicted horizontal error of a fix, one σ, metres (root of the mean predicted
    /// horizontal variance over the target's points).
    pub predicted_sigma_m: f64,
    /// Widest angle between two stations' lines of sight to the target's centre, degrees
    /// (in 0..=90: the angle between the rays or its supplement).
    pub triangulation_angle_deg: f64,
}

fn v3(p: Ned) -> Vector3<f64> {
    Vector3::new(p.north_m, p.east_m, p.down_m)
}

/// The mean predicted horizontal variance (m²) of fixing `points` from `stations` with
/// bearings of `sigma_rad`; `None` when the stations cannot fix a point (fewer than two,
/// or rays in line).
pub fn predicted_variance(
    stations: &[Vector3<f64>],
    points: &[Vector3<f64>],
    sigma_rad: f64,
) -> Option<f64> {
    if stations.len() < 2 || points.is_empty() {
        return None;
    }
    let mut total = 0.0;
    for p in points {
        let mut info = Matrix3::zeros();
        for s in stations {
            let d = p - s;
            let r = d.norm().max(1.0);
            let u = d / r;
            let w = (sigma_rad * r).powi(2);
            info += (Matrix3::identity() - u * u.transpose()) / w;
        }
        let cov = info.try_inverse()?;
        let var = cov[(0, 0)] + cov[(1, 1)];
        if !var.is_finite() || var <= 0.0 || var > 1e8 {
            return None;
        }
        total += var;
    }
    Some(total / points.len() as f64)
}

/// Whether `p` may be a station for `points` (stand-off from them and from `clear`, range,
/// field of view, fence), without the separation from the others.
fn admissible(
    limits: &StationLimits,
    fence: &Geofence,
    p: Ned,
    points: &[Vector3<f64>],
    clear: &[Vector3<f64>],
) -> bool {
    if !fence.contains(p) {
        return false;
    }
    // The polygon is not shrunk: look around the point.
    if !limits.fence.polygon.is_empty() {
        let m = limits.fence_margin_m;
        let ring = [(m, 0.0), (-m, 0.0), (0.0, m), (0.0, -m)];
        if ring.iter().any(|(dn, de)| {
            !limits
                .fence
                .contains(Ned::new(p.north_m + dn, p.east_m + de, p.down_m))
        }) {
            return false;
        }
    }
    let s = v3(p);
    if clear
        .iter()
        .any(|q| (q - s).xy().norm() < limits.standoff_m)
    {
        return false;
    }
    let mut bearings = Vec::with_capacity(points.len());
    for q in points {
        let d = q - s;
        if d.x.hypot(d.y) < limits.standoff_m || d.norm() > limits.max_range_m {
            return false;
        }
        bearings.push(d.y.atan2(d.x));
    }
    // Angular spread of the points seen from here.
    let c = bearings[0];
    let rel: Vec<f64> = bearings
        .iter()
        .map(|b| {
            (b - c + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
        })
        .collect();
    let spread = rel.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
        - rel.iter().cloned().fold(f64::INFINITY, f64::min);
    spread.to_degrees() <= FOV_USE * limits.fov_deg
}

/// The stations for `observers` to see the target at `points` (its predicted members'
/// positions; see the module docs), the stand-off also from `clear` (where it is now),
/// away from `obstacles` (the other vehicles).
///
/// # Errors
/// Fewer than two observers, no target point, or no layout meets the limits (the reason).
pub fn plan(
    observers: &[Observer],
    points: &[Ned],
    clear: &[Ned],
    obstacles: &[Ned],
    limits: &StationLimits,
) -> Result<StationPlan, String> {
    if observers.len() < 2 {
        return Err("observation geometry needs two observers with a gimbal at least".into());
    }
    if points.is_empty() {
        return Err("no target position to observe".into());
    }
    let pts: Vec<Vector3<f64>> = points.iter().map(|p| v3(*p)).collect();
    let clear: Vec<Vector3<f64>> = clear.iter().map(|p| v3(*p)).collect();
    let candidates = candidates(observers, &pts, &clear, obstacles, limits);
    if let Some(i) = candidates.iter().position(Vec::is_empty) {
        return Err(format!(
            "no station for {} keeps the {} m stand-off within {} m of the target inside the geofence",
            observers[i].id, limits.standoff_m, limits.max_range_m
        ));
    }
    let (layout, best) = search(observers, &candidates, &pts, limits);
    if !best.is_finite() {
        return Err(format!(
            "the observers cannot be placed {} m apart around the target within the limits",
            limits.min_separation_m
        ));
    }
    let stations: Vec<(String, Ned)> = observers
        .iter()
        .zip(&layout)
        .filter_map(|(o, p)| Some((o.id.clone(), (*p)?)))
        .collect();
    Ok(evaluate(&stations, points, limits.bearing_sigma_rad))
}

/// Each observer's candidate stations, at its own altitude: on rings about the centre of
/// `pts` from the stand-off (plus the target's reach) out to the cameras' range, every
/// [`RING_STEP_M`] and [`RING_STEP_DEG`], those [`admissible`] and `min_separation_m`
/// from every one of `obstacles`.
fn candidates(
    observers: &[Observer],
    pts: &[Vector3<f64>],
    clear: &[Vector3<f64>],
    obstacles: &[Ned],
    limits: &StationLimits,
) -> Vec<Vec<Ned>> {
    let n = pts.len() as f64;
    let centre = pts.iter().fold(Vector3::zeros(), |a, p| a + p) / n;
    let reach = pts
        .iter()
        .map(|p| (p - centre).xy().norm())
        .fold(0.0, f64::max);
    let fence = limits.fence.shrunk(limits.fence_margin_m);
    let r0 = limits.standoff_m + reach;
    let rings: Vec<f64> = (0..)
        .map(|k| r0 + k as f64 * RING_STEP_M)
        .take_while(|r| *r <= limits.max_range_m)
        .collect();
    let steps = (360.0 / RING_STEP_DEG).round() as usize;
    observers
        .iter()
        .map(|o| {
            let mut c = Vec::new();
            for r in &rings {
                for k in 0..steps {
                    let a = (k as f64 * RING_STEP_DEG).to_radians();
                    let p = Ned::new(
                        centre.x + r * a.cos(),
                        centre.y + r * a.sin(),
                        o.position.down_m,
                    );
                    if admissible(limits, &fence, p, pts, clear)
                        && obstacles
                            .iter()
                            .all(|q| (*q - p).norm() >= limits.min_separation_m)
                    {
                        c.push(p);
                    }
                }
            }
            c
        })
        .collect()
}

/// The layout of the observers over their `candidates` that minimises [`objective`]
/// (coordinate descent): each observer starts at its nearest candidate apart from those
/// already placed, then one observer at a time moves to a candidate that improves it,
/// until a sweep improves nothing or after [`MAX_SWEEPS`]. Returns the layout and its
/// objective (infinite when not every observer has a station).
fn search(
    observers: &[Observer],
    candidates: &[Vec<Ned>],
    pts: &[Vector3<f64>],
    limits: &StationLimits,
) -> (Vec<Option<Ned>>, f64) {
    let separation_m = limits.min_separation_m;
    let mut layout: Vec<Option<Ned>> = vec![None; observers.len()];
    for (i, o) in observers.iter().enumerate() {
        layout[i] = candidates[i]
            .iter()
            .filter(|p| apart(**p, &layout, i, separation_m))
            .min_by(|a, b| {
                (**a - o.position)
                    .norm()
                    .total_cmp(&(**b - o.position).norm())
            })
            .copied();
    }
    let mut best = objective(&layout, observers, pts, limits);
    for _ in 0..MAX_SWEEPS {
        let mut improved = false;
        for i in 0..observers.len() {
            for p in &candidates[i] {
                if !apart(*p, &layout, i, separation_m) {
                    continue;
                }
                let before = layout[i];
                layout[i] = Some(*p);
                let v = objective(&layout, observers, pts, limits);
                if v < best * (1.0 - 1e-9) {
                    best = v;
                    improved = true;
                } else {
                    layout[i] = before;
                }
            }
        }
        if !improved {
            break;
        }
    }
    (layout, best)
}

/// True when `p` is at least `separation_m` from every station of `layout` but the
/// observer `me`'s own.
fn apart(p: Ned, layout: &[Option<Ned>], me: usize, separation_m: f64) -> bool {
    layout
        .iter()
        .enumerate()
        .filter(|(j, _)| *j != me)
        .all(|(_, q)| q.is_none_or(|q| (q - p).norm() >= separation_m))
}

/// What the search minimises: the predicted variance of a fix from `layout` (see
/// [`predicted_variance`]) times `1 + travel / TRAVEL_SCALE_M`, the travel summed over
/// the observers; infinite while an observer has no station or the layout fixes nothing.
fn objective(
    layout: &[Option<Ned>],
    observers: &[Observer],
    pts: &[Vector3<f64>],
    limits: &StationLimits,
) -> f64 {
    let st: Vec<Vector3<f64>> = layout.iter().flatten().map(|p| v3(*p)).collect();
    if st.len() < layout.len() {
        return f64::INFINITY;
    }
    let travel: f64 = layout
        .iter()
        .zip(observers)
        .map(|(p, o)| p.map_or(0.0, |p| (p - o.position).norm()))
        .sum();
    predicted_variance(&st, pts, limits.bearing_sigma_rad)
        .map_or(f64::INFINITY, |v| v * (1.0 + travel / TRAVEL_SCALE_M))
}

/// How well `stations` fix the target at `points`: the plan they make (an infinite σ when
/// they cannot fix it).
pub fn evaluate(stations: &[(String, Ned)], points: &[Ned], sigma_rad: f64) -> StationPlan {
    let st: Vec<Vector3<f64>> = stations.iter().map(|(_, p)| v3(*p)).collect();
    let pts: Vec<Vector3<f64>> = points.iter().map(|p| v3(*p)).collect();
    let n = pts.len().max(1) as f64;
    let centre = pts.iter().fold(Vector3::zeros(), |a, p| a + p) / n;
    let mut widest: f64 = 0.0;
    for i in 0..st.len() {
        for j in i + 1..st.len() {
            let (a, b) = ((centre - st[i]).normalize(), (centre - st[j]).normalize());
            let angle = a.dot(&b).clamp(-1.0, 1.0).acos().to_degrees();
            widest = widest.max(angle.min(180.0 - angle));
        }
    }
    StationPlan {
        stations: stations.to_vec(),
        predicted_sigma_m: predicted_variance(&st, &pts, sigma_rad)
            .map_or(f64::INFINITY, f64::sqrt),
        triangulation_angle_deg: widest,
    }
}

/// Whether `stations` still meet the limits for the target at `points` (and clear of
/// `clear`), away from `obstacles`.
pub fn still_valid(
    stations: &[(String, Ned)],
    points: &[Ned],
    clear: &[Ned],
    obstacles: &[Ned],
    limits: &StationLimits,
) -> bool {
    let fence = limits.fence.shrunk(limits.fence_margin_m);
    let pts: Vec<Vector3<f64>> = points.iter().map(|p| v3(*p)).collect();
    let clear: Vec<Vector3<f64>> = clear.iter().map(|p| v3(*p)).collect();
    stations.iter().enumerate().all(|(i, (_, p))| {
        admissible(limits, &fence, *p, &pts, &clear)
            && obstacles
                .iter()
                .chain(
                    stations
                        .iter()
                        .enumerate()
                        .filter(|(j, _)| *j != i)
                        .map(|(_, (_, q))| q),
                )
                .all(|q| (*q - *p).norm() >= limits.min_separation_m)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits(fence: Geofence) -> StationLimits {
        StationLimits {
            standoff_m: 25.0,
            max_range_m: 80.0,
            min_separation_m: 4.95,
            fov_deg: 75.0,
            bearing_sigma_rad: 0.15f64.to_radians(),
            fence,
            fence_margin_m: 5.0,
        }
    }

    /// The two observation UAVs of `skein up --sim 4` hovering 6 m apart at 10 m.
    fn observers() -> Vec<Observer> {
        vec![
            Observer {
                id: "uav-2".into(),
                position: Ned::new(0.0, 3.0, -10.0),
            },
            Observer {
                id: "uav-4".into(),
                position: Ned::new(0.0, 9.0, -10.0),
            },
        ]
    }

    fn check(plan: &StationPlan, points: &[Ned], obstacles: &[Ned], l: &StationLimits) {
        assert!(
            still_valid(&plan.stations, points, &[], obstacles, l),
            "{plan:?}"
        );
        for (_, s) in &plan.stations {
            assert!((s.down_m + 10.0).abs() < 1e-9, "keeps its altitude: {s:?}");
            assert!(l.fence.shrunk(l.fence_margin_m).contains(*s), "{s:?}");
            for p in points {
                let d = *p - *s;
                assert!(d.horizontal_norm() >= l.standoff_m - 1e-9, "{s:?} to {p:?}");
                assert!(d.norm() <= l.max_range_m + 1e-9);
            }
            for o in obstacles {
                assert!((*o - *s).norm() >= l.min_separation_m);
            }
        }
        for (i, (_, a)) in plan.stations.iter().enumerate() {
            for (_, b) in &plan.stations[i + 1..] {
                assert!((*a - *b).norm() >= l.min_separation_m, "{plan:?}");
            }
        }
    }

    #[test]
    fn two_observers_spread_round_a_single_target_at_a_wide_angle() {
        let l = limits(Geofence::default());
        let target = [Ned::new(10.0, 60.0, -14.0)];
        let plan = plan(&observers(), &target, &[], &[], &l).expect("stations");
        check(&plan, &target, &[], &l);
        assert!(plan.triangulation_angle_deg > 70.0, "{plan:?}");
        // Where they hover now, 6 m apart at 60 m, they fix it far worse.
        let here: Vec<(String, Ned)> = observers()
            .into_iter()
            .map(|o| (o.id, o.position))
            .collect();
        let before = evaluate(&here, &target, l.bearing_sigma_rad);
        assert!(
            before.predicted_sigma_m > 5.0 * plan.predicted_sigma_m,
            "{before:?} vs {plan:?}"
        );
        // Two observers in line with the target fix nothing.
        let line = [
            ("a".to_string(), Ned::new(0.0, 0.0, -14.0)),
            ("b".to_string(), Ned::new(5.0, 30.0, -14.0)),
        ];
        assert!(
            evaluate(&line, &target, l.bearing_sigma_rad)
                .predicted_sigma_m
                .is_infinite()
        );
    }

    #[test]
    fn a_swarm_stays_in_every_camera_beyond_the_standoff_from_each_member() {
        let l = limits(Geofence::default());
        // A V of five 60 m north, 24 m wide.
        let swarm: Vec<Ned> = [
            (0.0, 0.0),
            (-6.0, 6.0),
            (-6.0, -6.0),
            (-12.0, 12.0),
            (-12.0, -12.0),
        ]
        .iter()
        .map(|(n, e)| Ned::new(60.0 + n, 10.0 + e, -15.0))
        .collect();
        let mut obs = observers();
        obs.push(Observer {
            id: "uav-6".into(),
            position: Ned::new(6.0, 0.0, -10.0),
        });
        // uav-1 and uav-3 hover nearby, flying in the formation.
        let others = [Ned::new(0.0, -3.0, -10.0), Ned::new(6.0, 6.0, -10.0)];
        let plan = plan(&obs, &swarm, &[], &others, &l).expect("stations");
        assert_eq!(plan.stations.len(), 3);
        check(&plan, &swarm, &others, &l);
        assert!(plan.triangulation_angle_deg > 60.0, "{plan:?}");
    }

    #[test]
    fn the_geofence_bounds_the_stations_or_refuses_them() {
        // A fence of 70 m about the origin: the target 60 m north is near its edge, so the
        // stations are on the inner side.
        let fence = Geofence {
            radius_m: 70.0,
            ..Geofence::default()
        };
        let l = limits(fence);
        let target = [Ned::new(60.0, 0.0, -14.0)];
        let p = plan(&observers(), &target, &[], &[], &l).expect("stations inside");
        check(&p, &target, &[], &l);
        // A fence too small to come within the cameras' range: refused with the reason.
        let tiny = limits(Geofence {
            radius_m: 20.0,
            ..Geofence::default()
        });
        let e = plan(
            &observers(),
            &[Ned::new(110.0, 0.0, -14.0)],
            &[],
            &[],
            &tiny,
        )
        .unwrap_err();
        assert!(e.contains("stand-off"), "{e}");
        // A polygon cuts the east half away.
        let poly = limits(Geofence {
            polygon: vec![
                [-200.0, -200.0],
                [200.0, -200.0],
                [200.0, 20.0],
                [-200.0, 20.0],
            ],
            ..Geofence::default()
        });
        let p = plan(&observers(), &target, &[], &[], &poly).expect("stations west");
        check(&p, &target, &[], &poly);
        assert!(p.stations.iter().all(|(_, s)| s.east_m <= 15.0), "{p:?}");
        // One observer is no triangulation.
        assert!(plan(&observers()[..1], &target, &[], &[], &l).is_err());
    }

    #[test]
    fn stations_lapse_when_the_target_comes_inside_the_standoff() {
        let l = limits(Geofence::default());
        let target = [Ned::new(10.0, 60.0, -14.0)];
        let p = plan(&observers(), &target, &[], &[], &l).expect("stations");
        let (_, s) = &p.stations[0];
        let on_top = [Ned::new(s.north_m + 5.0, s.east_m, -14.0)];
        assert!(!still_valid(&p.stations, &on_top, &[], &[], &l));
        let far = [Ned::new(s.north_m + 300.0, s.east_m, -14.0)];
        assert!(!still_valid(&p.stations, &far, &[], &[], &l));
        // Where the target is now counts too: no station on its way.
        assert!(!still_valid(&p.stations, &target, &on_top, &[], &l));
        let now = [Ned::new(10.0, 30.0, -14.0)];
        let p2 = plan(&observers(), &target, &now, &[], &l).expect("stations");
        for (_, st) in &p2.stations {
            assert!((*st - now[0]).horizontal_norm() >= 25.0, "{p2:?}");
        }
    }
}
