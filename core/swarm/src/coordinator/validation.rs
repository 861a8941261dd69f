//! Validation of formation requests and leader motions: pure functions of the
//! configuration and the vehicles' states, answered as a [`FieldError`] naming the field.
//!
//! A formation's spacing must keep the minimum separation through every change: the
//! transition plan keeps members `1/√2` of the slot distance apart, so the spacing must
//! be at least `√2 × (min_separation_m + separation_margin_m + u)`, where the margin is
//! for the tracking error and `u` for where the members really are: each member flies on
//! its own position estimate, off by about its receiver's accuracy `eph_m` (`GPS_RAW_INT`
//! `h_acc`, the RMS of the horizontal error: `eph/√2` along any one axis), so along the
//! line between two members their distance is off by `√((eph_a² + eph_b²) / 2)` (one
//! standard deviation); `u` is that for the two least certain members, times
//! `position_uncertainty_sigmas`. With plain GNSS (about 1.8 m each) a formation needs
//! 7.5 m, with PX4 SIH's reported 0.9 m 6.2 m, with RTK float (0.35 m) 5.45 m; with RTK
//! fixed (about 2 cm) `u` vanishes.

use super::messages::FieldError;
use crate::config::SwarmConfig;
use crate::formation::{FormationSpec, LeaderMotion, VIRTUAL};
use skein_model::fsm::VehicleState;
use skein_model::geo::Ned;
use skein_model::geofence::Geofence;

/// Checks a leader motion against the vehicle models' speed limit and the geofence in
/// force (`fence`).
///
/// # Errors
/// The first offending field (`speed_m_s`, `north_m`, `waypoints`, `radius_m`).
pub fn validate_motion(
    config: &SwarmConfig,
    fence: &Geofence,
    motion: &LeaderMotion,
) -> Result<(), FieldError> {
    let err = |field: &str, error: String| {
        Err(FieldError {
            field: field.into(),
            error,
        })
    };
    let max = config
        .models
        .values()
        .map(|m| m.limits.max_speed_m_s)
        .fold(f64::INFINITY, f64::min)
        .min(skein_model::safety::MotionLimits::default().max_speed_m_s);
    let speed = match motion {
        LeaderMotion::Hold => return Ok(()),
        LeaderMotion::GoTo { speed_m_s, .. }
        | LeaderMotion::Waypoints { speed_m_s, .. }
        | LeaderMotion::Orbit { speed_m_s, .. } => *speed_m_s,
    };
    if !(speed.is_finite() && speed > 0.0 && speed <= max) {
        return err(
            "speed_m_s",
            format!("speed_m_s {speed} outside (0, {max}] m/s (the slowest vehicle model's limit)"),
        );
    }
    let inside = |p: &Ned| fence.contains(*p);
    match motion {
        LeaderMotion::GoTo { target, .. } if !inside(target) => err(
            "north_m",
            format!(
                "the point ({:.1}, {:.1}, {:.1}) is outside the geofence",
                target.north_m, target.east_m, target.down_m
            ),
        ),
        LeaderMotion::Waypoints { points, .. } => {
            if points.is_empty() {
                return err("waypoints", "waypoints is empty".into());
            }
            match points.iter().position(|p| !inside(p)) {
                Some(i) => err(
                    "waypoints",
                    format!("waypoints[{i}] is outside the geofence"),
                ),
                None => Ok(()),
            }
        }
        LeaderMotion::Orbit {
            centre, radius_m, ..
        } => {
            if !(radius_m.is_finite() && *radius_m >= config.setpoint_separation_m()) {
                return err(
                    "radius_m",
                    format!(
                        "radius_m {radius_m} must be at least the minimum separation plus margin ({} m)",
                        config.setpoint_separation_m()
                    ),
                );
            }
            // The circle itself, every 10°, against the polygon and the exclusion areas.
            let leaves = (0..36).any(|k| {
                let a = f64::from(k).to_radians() * 10.0;
                !inside(&(*centre + Ned::new(radius_m * a.cos(), radius_m * a.sin(), 0.0)))
            });
            if !inside(centre) || centre.horizontal_norm() + radius_m > fence.radius_m || leaves {
                return err("radius_m", "the orbit leaves the geofence".into());
            }
            Ok(())
        }
        _ => Ok(()),
    }
}

/// A vehicle that might fly a formation, as its checks see it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate<'a> {
    /// Vehicle id.
    pub id: &'a str,
    /// Its FSM state.
    pub state: VehicleState,
    /// It has failed (its actor gave up).
    pub failed: bool,
    /// Its horizontal position accuracy, metres (`GpsStatus::eph_m`); `None`: unknown,
    /// not counted.
    pub eph_m: Option<f64>,
}

/// The vehicles that would fly a formation: the airborne healthy ones (those still
/// climbing included: they join when they reach their altitude), or every connected one
/// when the formation is set before takeoff.
fn flying<'a>(vehicles: &[Candidate<'a>]) -> Vec<Candidate<'a>> {
    let airborne = |s: VehicleState| {
        matches!(
            s,
            VehicleState::TakingOff
                | VehicleState::Hovering
                | VehicleState::InFormation
                | VehicleState::GoTo
        )
    };
    let healthy = vehicles.iter().filter(|v| !v.failed);
    let up: Vec<_> = healthy
        .clone()
        .filter(|v| airborne(v.state))
        .copied()
        .collect();
    if up.is_empty() {
        healthy
            .filter(|v| v.state.is_connected())
            .copied()
            .collect()
    } else {
        up
    }
}

/// The position uncertainty a spacing must allow for (see the module docs), metres, and
/// the words that say where it comes from (`""` when it is zero).
fn uncertainty(config: &SwarmConfig, members: &[Candidate]) -> (f64, String) {
    let mut known: Vec<(&str, f64)> = members
        .iter()
        .filter_map(|c| Some((c.id, c.eph_m.filter(|e| e.is_finite() && *e > 0.0)?)))
        .collect();
    known.sort_by(|a, b| b.1.total_cmp(&a.1));
    let k = config.position_uncertainty_sigmas;
    match known.as_slice() {
        [a, b, ..] if k > 0.0 => {
            let u = k * ((a.1 * a.1 + b.1 * b.1) / 2.0).sqrt();
            let words = format!(
                " + {u:.2} m for the position uncertainty of {} (eph {:.2} m) and {} (eph {:.2} m)",
                a.0, a.1, b.0, b.1
            );
            (u, words)
        }
        _ => (0.0, String::new()),
    }
}

/// Checks a formation request against the configuration and the vehicles that might fly
/// it.
///
/// # Errors
/// The first offending field (`spacing_m`, `leader`, `offsets`, `heading_deg`,
/// `altitude_m`, `shape`).
pub fn validate_formation(
    config: &SwarmConfig,
    fence: &Geofence,
    spec: &FormationSpec,
    vehicles: &[Candidate],
) -> Result<(), FieldError> {
    let err = |field: &str, error: String| {
        Err(FieldError {
            field: field.into(),
            error,
        })
    };
    let min_sep = config.min_separation_m;
    let custom = spec.shape == skein_model::formation::Shape::Custom;
    if !custom && (!spec.spacing_m.is_finite() || spec.spacing_m <= 0.0) {
        return err(
            "spacing_m",
            format!(
                "spacing_m must be a positive number of metres, got {}",
                spec.spacing_m
            ),
        );
    }
    let margin = config.separation_margin_m;
    let members = flying(vehicles);
    let (u, because) = uncertainty(config, &members);
    // Transitions keep members 1/√2 of the slot distance apart (see `formation`).
    let needed = config.min_slot_distance_m() + std::f64::consts::SQRT_2 * u;
    let rtk = if u > 0.0 {
        "; RTK corrections shrink the uncertainty"
    } else {
        ""
    };
    if !custom && spec.spacing_m < needed - 1e-9 {
        return err(
            "spacing_m",
            format!(
                "spacing_m {} is below √2 × (the minimum separation of {min_sep} m + the {margin} m tracking margin{because}) = {needed:.2} m, what formation changes need to keep the separation{rtk}",
                spec.spacing_m
            ),
        );
    }
    if let Some(leader) = &spec.leader
        && leader != VIRTUAL
        && spec.track_leader().is_none()
        && !vehicles.iter().any(|c| c.id == leader)
    {
        return err(
            "leader",
            format!("unknown leader `{leader}` (a vehicle id, \"virtual\", or a track id)"),
        );
    }
    if spec.shape == skein_model::formation::Shape::Custom {
        if spec.offsets.is_empty() {
            return err("offsets", "a custom formation needs offsets".into());
        }
        if let Some(i) = spec.offsets.iter().position(|o| !o.is_finite()) {
            return err("offsets", format!("offsets[{i}] must be finite numbers"));
        }
        let all = skein_model::formation::custom_offsets(&spec.offsets);
        if let Some(d) = skein_model::formation::min_slot_distance(&all)
            && d < needed
        {
            return err(
                "offsets",
                format!(
                    "two slots are {d:.2} m apart, below √2 × (the minimum separation of {min_sep} m + the {margin} m tracking margin{because}) = {needed:.2} m{rtk}"
                ),
            );
        }
    } else if !spec.offsets.is_empty() {
        return err(
            "offsets",
            format!(
                "offsets are for shape `custom`, not `{}`",
                spec.shape.name()
            ),
        );
    }
    if !spec.heading_deg.is_finite() {
        return err("heading_deg", "heading_deg must be a number".into());
    }
    if let Some(a) = spec.altitude_m
        && !(a.is_finite() && a > 0.0 && a <= fence.max_altitude_m)
    {
        return err(
            "altitude_m",
            format!("altitude_m {a} outside (0, {}] m", fence.max_altitude_m),
        );
    }
    let n = members.len();
    if n < spec.shape.min_vehicles() {
        return err(
            "shape",
            format!(
                "shape `{}` needs at least {} vehicles, {n} can fly it",
                spec.shape.name(),
                spec.shape.min_vehicles()
            ),
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formation::FormationFrame;
    use skein_model::formation::Shape;

    fn wedge(spacing_m: f64) -> FormationSpec {
        FormationSpec {
            shape: Shape::Wedge,
            spacing_m,
            leader: None,
            heading_deg: 0.0,
            altitude_m: None,
            frame: FormationFrame::World,
            offsets: vec![],
            standoff_m: None,
        }
    }

    const IDS: [&str; 4] = ["uav-1", "uav-2", "uav-3", "uav-4"];

    fn vehicles(n: usize, state: VehicleState) -> Vec<Candidate<'static>> {
        IDS[..n]
            .iter()
            .map(|id| Candidate {
                id,
                state,
                failed: false,
                eph_m: None,
            })
            .collect()
    }

    fn hovering(n: usize) -> Vec<Candidate<'static>> {
        vehicles(n, VehicleState::Hovering)
    }

    fn check(spec: &FormationSpec, v: &[Candidate]) -> Result<(), FieldError> {
        validate_formation(&SwarmConfig::default(), &Geofence::default(), spec, v)
    }

    fn field(r: Result<(), FieldError>) -> String {
        r.expect_err("refused").field
    }

    #[test]
    fn spacing_must_keep_the_separation_through_changes() {
        // √2 × (3 m + 0.5 m) = 4.95 m.
        assert!(check(&wedge(5.0), &hovering(3)).is_ok());
        assert_eq!(field(check(&wedge(4.9), &hovering(3))), "spacing_m");
        assert_eq!(field(check(&wedge(f64::NAN), &hovering(3))), "spacing_m");
        assert_eq!(field(check(&wedge(-1.0), &hovering(3))), "spacing_m");
    }

    #[test]
    fn the_spacing_allows_for_the_members_position_uncertainty() {
        let with_eph = |eph: [f64; 3]| {
            let mut v = hovering(3);
            for (c, e) in v.iter_mut().zip(eph) {
                c.eph_m = Some(e);
            }
            v
        };
        // Plain GNSS, 1.8 m each: √2 × (3.5 m + √((1.8² + 1.8²) / 2) m) = 7.5 m.
        let plain = with_eph([1.8, 1.8, 1.2]);
        let e = check(&wedge(7.0), &plain).expect_err("too tight for plain GNSS");
        assert_eq!(e.field, "spacing_m");
        assert!(
            e.error
                .contains("uav-1 (eph 1.80 m) and uav-2 (eph 1.80 m)"),
            "{}",
            e.error
        );
        assert!(
            e.error.contains("= 7.50 m") && e.error.contains("RTK"),
            "{}",
            e.error
        );
        assert!(check(&wedge(7.5), &plain).is_ok());
        // PX4 SIH's reported 0.9 m: 6.22 m.
        assert_eq!(field(check(&wedge(6.0), &with_eph([0.9; 3]))), "spacing_m");
        assert!(check(&wedge(6.3), &with_eph([0.9; 3])).is_ok());
        // RTK fixed, 2 cm each: the 5 m formation flies.
        assert!(check(&wedge(5.0), &with_eph([0.02, 0.014, 0.02])).is_ok());
        // RTK float (0.35 m) on two: 5.45 m; the two least certain count.
        assert_eq!(
            field(check(&wedge(5.0), &with_eph([0.35, 0.017, 0.35]))),
            "spacing_m"
        );
        // A landed vehicle that will not fly does not count once others are up.
        let mut v = with_eph([0.02, 0.02, 0.02]);
        v.push(Candidate {
            id: "uav-4",
            state: VehicleState::Landed,
            failed: false,
            eph_m: Some(3.0),
        });
        assert!(check(&wedge(5.0), &v).is_ok());
        // Custom offsets too.
        let mut spec = wedge(6.0);
        spec.shape = Shape::Custom;
        spec.offsets = vec![Ned::new(-6.0, 0.0, 0.0), Ned::new(-12.0, 0.0, 0.0)];
        assert_eq!(field(check(&spec, &plain)), "offsets");
        // With the factor at 0 the uncertainty is not counted.
        let config = SwarmConfig {
            position_uncertainty_sigmas: 0.0,
            ..SwarmConfig::default()
        };
        assert!(validate_formation(&config, &Geofence::default(), &wedge(5.0), &plain).is_ok());
    }

    #[test]
    fn the_leader_must_be_a_vehicle_or_virtual() {
        let mut spec = wedge(6.0);
        spec.leader = Some("uav-9".into());
        assert_eq!(field(check(&spec, &hovering(3))), "leader");
        spec.leader = Some("uav-2".into());
        assert!(check(&spec, &hovering(3)).is_ok());
        spec.leader = Some(VIRTUAL.into());
        assert!(check(&spec, &hovering(3)).is_ok());
    }

    #[test]
    fn custom_offsets_belong_to_custom_shapes_and_keep_apart() {
        let mut spec = wedge(6.0);
        spec.offsets = vec![Ned::new(-6.0, 6.0, 0.0)];
        assert_eq!(field(check(&spec, &hovering(3))), "offsets");
        spec.shape = Shape::Custom;
        assert!(check(&spec, &hovering(3)).is_ok());
        spec.offsets = vec![Ned::new(-6.0, 6.0, 0.0), Ned::new(-6.0, 7.0, 0.0)];
        assert_eq!(field(check(&spec, &hovering(3))), "offsets");
        spec.offsets = vec![];
        assert_eq!(field(check(&spec, &hovering(3))), "offsets");
    }

    #[test]
    fn altitude_and_heading_are_checked() {
        let mut spec = wedge(6.0);
        spec.altitude_m = Some(0.0);
        assert_eq!(field(check(&spec, &hovering(3))), "altitude_m");
        spec.altitude_m = Some(10_000.0);
        assert_eq!(field(check(&spec, &hovering(3))), "altitude_m");
        spec.altitude_m = Some(20.0);
        spec.heading_deg = f64::INFINITY;
        assert_eq!(field(check(&spec, &hovering(3))), "heading_deg");
    }

    #[test]
    fn the_shape_needs_enough_vehicles_that_can_fly_it() {
        let mut v = hovering(3);
        v[2].failed = true;
        let e = check(&wedge(6.0), &v).expect_err("two can fly");
        assert_eq!(e.field, "shape");
        assert!(e.error.contains("2 can fly it"), "{}", e.error);
        // Before takeoff every connected vehicle counts.
        assert!(check(&wedge(6.0), &vehicles(3, VehicleState::Landed)).is_ok());
    }

    #[test]
    fn vehicles_still_climbing_count_and_join_on_arrival() {
        // Right after a swarm takeoff one vehicle hovers while two are a metre short.
        let mut v = hovering(3);
        v[1].state = VehicleState::TakingOff;
        v[2].state = VehicleState::TakingOff;
        assert!(check(&wedge(6.0), &v).is_ok());
        v[2].state = VehicleState::Landing;
        assert_eq!(field(check(&wedge(6.0), &v)), "shape");
    }

    #[test]
    fn leader_motion_respects_speed_and_fence() {
        let config = SwarmConfig::default();
        let goto = |speed_m_s, north_m| LeaderMotion::GoTo {
            target: Ned::new(north_m, 0.0, -10.0),
            speed_m_s,
        };
        assert!(validate_motion(&config, &config.geofence, &goto(5.0, 20.0)).is_ok());
        assert_eq!(
            validate_motion(&config, &config.geofence, &goto(0.0, 20.0))
                .unwrap_err()
                .field,
            "speed_m_s"
        );
        assert_eq!(
            validate_motion(&config, &config.geofence, &goto(5.0, 1e6))
                .unwrap_err()
                .field,
            "north_m"
        );
        let orbit = |radius_m| LeaderMotion::Orbit {
            centre: Ned::new(0.0, 0.0, -10.0),
            radius_m,
            speed_m_s: 3.0,
            clockwise: true,
        };
        assert!(validate_motion(&config, &config.geofence, &orbit(20.0)).is_ok());
        assert_eq!(
            validate_motion(&config, &config.geofence, &orbit(1.0))
                .unwrap_err()
                .field,
            "radius_m"
        );
        let empty = LeaderMotion::Waypoints {
            points: vec![],
            speed_m_s: 3.0,
            next: 0,
            repeat: false,
        };
        assert_eq!(
            validate_motion(&config, &config.geofence, &empty)
                .unwrap_err()
                .field,
            "waypoints"
        );
    }
}
