//! Validation of formation requests and leader motions: pure functions of the
//! configuration and the vehicles' states, answered as a [`FieldError`] naming the field.

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

/// Checks a formation request against the configuration and the vehicles that would fly
/// it (`vehicles`: id, FSM state, and whether the vehicle has failed).
///
/// # Errors
/// The first offending field (`spacing_m`, `leader`, `offsets`, `heading_deg`,
/// `altitude_m`, `shape`).
pub fn validate_formation(
    config: &SwarmConfig,
    fence: &Geofence,
    spec: &FormationSpec,
    vehicles: &[(&str, VehicleState, bool)],
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
    // Transitions keep members 1/√2 of the slot distance apart (see `formation`).
    let needed = config.min_slot_distance_m();
    if !custom && spec.spacing_m < needed - 1e-9 {
        return err(
            "spacing_m",
            format!(
                "spacing_m {} is below √2 × (the minimum separation of {min_sep} m + the {margin} m tracking margin) = {needed:.2} m, what formation changes need to keep the separation",
                spec.spacing_m
            ),
        );
    }
    if let Some(leader) = &spec.leader
        && leader != VIRTUAL
        && spec.track_leader().is_none()
        && !vehicles.iter().any(|(id, _, _)| id == leader)
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
                    "two slots are {d:.2} m apart, below √2 × (the minimum separation of {min_sep} m + the {margin} m tracking margin) = {needed:.2} m"
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
    // The vehicles that would fly it: the airborne healthy ones (those still climbing
    // included: they join when they reach their altitude), or every connected one when
    // the formation is set before takeoff.
    let usable = |s: VehicleState| {
        matches!(
            s,
            VehicleState::TakingOff
                | VehicleState::Hovering
                | VehicleState::InFormation
                | VehicleState::GoTo
        )
    };
    let airborne = vehicles
        .iter()
        .filter(|(_, s, failed)| !failed && usable(*s))
        .count();
    let n = if airborne > 0 {
        airborne
    } else {
        vehicles
            .iter()
            .filter(|(_, s, failed)| !failed && s.is_connected())
            .count()
    };
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

    fn hovering(n: usize) -> Vec<(String, VehicleState, bool)> {
        (1..=n)
            .map(|i| (format!("uav-{i}"), VehicleState::Hovering, false))
            .collect()
    }

    fn check(spec: &FormationSpec, v: &[(String, VehicleState, bool)]) -> Result<(), FieldError> {
        let v: Vec<(&str, VehicleState, bool)> =
            v.iter().map(|(i, s, f)| (i.as_str(), *s, *f)).collect();
        validate_formation(&SwarmConfig::default(), &Geofence::default(), spec, &v)
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
        v[2].2 = true; // failed
        let e = check(&wedge(6.0), &v).expect_err("two can fly");
        assert_eq!(e.field, "shape");
        assert!(e.error.contains("2 can fly it"), "{}", e.error);
        // Before takeoff every connected vehicle counts.
        let landed: Vec<_> = (1..=3)
            .map(|i| (format!("uav-{i}"), VehicleState::Landed, false))
            .collect();
        assert!(check(&wedge(6.0), &landed).is_ok());
    }

    #[test]
    fn vehicles_still_climbing_count_and_join_on_arrival() {
        // Right after a swarm takeoff one vehicle hovers while two are a metre short.
        let mut v = hovering(3);
        v[1].1 = VehicleState::TakingOff;
        v[2].1 = VehicleState::TakingOff;
        assert!(check(&wedge(6.0), &v).is_ok());
        v[2].1 = VehicleState::Landing;
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
