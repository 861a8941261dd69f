//! Clamping into the fence (radius, polygon, exclusion areas, altitude band, margins) and
//! the validation of an operator's fence.

use super::*;

fn square(half: f64) -> Vec<[f64; 2]> {
    vec![[-half, -half], [half, -half], [half, half], [-half, half]]
}

#[test]
fn fence_clamps_radius_ceiling_and_floor() {
    let fence = Geofence {
        radius_m: 100.0,
        max_altitude_m: 50.0,
        min_altitude_m: 5.0,
        ..Geofence::default()
    };
    let (p, v) = fence.clamp(Ned::new(300.0, 400.0, -10.0), true);
    assert_eq!(v, Some(FenceViolation::Radius));
    assert!((p.horizontal_norm() - 100.0).abs() < 1e-9);
    assert!((p.north_m - 60.0).abs() < 1e-9);
    let (p, v) = fence.clamp(Ned::new(0.0, 0.0, -80.0), true);
    assert_eq!((p.down_m, v), (-50.0, Some(FenceViolation::Ceiling)));
    assert!(fence.contains(Ned::new(10.0, 10.0, -10.0)));
    let (p, v) = fence.clamp(Ned::new(0.0, 0.0, -2.0), true);
    assert_eq!((p.down_m, v), (-5.0, Some(FenceViolation::Floor)));
    assert_eq!(
        fence.clamp(Ned::new(0.0, 0.0, -2.0), false).1,
        None,
        "takeoff passes the floor"
    );
    assert!(fence.validate().is_ok());
    assert_eq!(
        Geofence {
            min_altitude_m: 60.0,
            ..fence.clone()
        }
        .validate()
        .unwrap_err()
        .0,
        "min_altitude_m"
    );
}

#[test]
fn fence_polygon_clamps_to_the_nearest_edge() {
    // A 40 m × 20 m rectangle north-east of the origin.
    let fence = Geofence {
        polygon: vec![[-10.0, -10.0], [30.0, -10.0], [30.0, 10.0], [-10.0, 10.0]],
        ..Geofence::default()
    };
    assert!(fence.contains(Ned::new(0.0, 0.0, -10.0)));
    let (p, v) = fence.clamp(Ned::new(50.0, 0.0, -10.0), true);
    assert_eq!(v, Some(FenceViolation::Polygon));
    assert!((p - Ned::new(30.0, 0.0, -10.0)).norm() < 1e-9, "{p:?}");
    let (p, _) = fence.clamp(Ned::new(0.0, 25.0, -10.0), true);
    assert!((p - Ned::new(0.0, 10.0, -10.0)).norm() < 1e-9, "{p:?}");
    // Setpoints keep the margin inside the edge.
    let inner = fence.shrunk(0.5);
    let (p, v) = inner.clamp(Ned::new(50.0, 0.0, -10.0), true);
    assert_eq!(v, Some(FenceViolation::Polygon));
    assert!((p - Ned::new(29.5, 0.0, -10.0)).norm() < 1e-5, "{p:?}");
    let (p, v) = inner.clamp(Ned::new(29.8, 0.0, -10.0), true);
    assert_eq!(v, Some(FenceViolation::Polygon), "within the margin");
    assert!((p.north_m - 29.5).abs() < 1e-5, "{p:?}");
    assert_eq!(inner.clamp(Ned::new(20.0, 0.0, -10.0), true).1, None);
}

#[test]
fn exclusion_areas_push_setpoints_out_and_stay_inside_the_inclusion() {
    let fence = Geofence {
        polygon: square(50.0),
        exclusions: vec![
            FenceArea::Circle {
                north_m: 20.0,
                east_m: 0.0,
                radius_m: 5.0,
            },
            FenceArea::Polygon(vec![
                [-30.0, -30.0],
                [-20.0, -30.0],
                [-20.0, -20.0],
                [-30.0, -20.0],
            ]),
        ],
        ..Geofence::default()
    };
    assert!(fence.validate().is_ok(), "{:?}", fence.validate());
    let (p, v) = fence.clamp(Ned::new(21.0, 0.0, -10.0), true);
    assert_eq!(v, Some(FenceViolation::Exclusion));
    assert!(
        (p.north_m - 25.0).abs() < 1e-5,
        "pushed radially out: {p:?}"
    );
    assert!(fence.contains(p));
    let (p, v) = fence.clamp(Ned::new(-24.0, -25.0, -10.0), true);
    assert_eq!(v, Some(FenceViolation::Exclusion));
    assert!(
        (p.north_m + 20.0).abs() < 1e-5 && (p.east_m + 25.0).abs() < 1e-5,
        "{p:?}"
    );
    assert!(!fence.contains(Ned::new(-25.0, -25.0, -10.0)));
    // With the setpoint margin the exclusion grows by it.
    let inner = fence.shrunk(0.5);
    let (p, _) = inner.clamp(Ned::new(21.0, 0.0, -10.0), true);
    assert!((p.north_m - 25.5).abs() < 1e-5, "{p:?}");
    // An exclusion circle on the polygon's edge: the point ends inside both rules.
    let edge = Geofence {
        polygon: square(50.0),
        exclusions: vec![FenceArea::Circle {
            north_m: 50.0,
            east_m: 0.0,
            radius_m: 10.0,
        }],
        ..Geofence::default()
    };
    let (p, _) = edge.clamp(Ned::new(70.0, 0.0, -10.0), true);
    assert!(p.north_m <= 50.0 + 1e-6, "{p:?}");
}

#[test]
fn validation_names_the_broken_rule() {
    let field = |g: Geofence| g.validate().unwrap_err();
    let base = Geofence::default();
    assert_eq!(
        field(Geofence {
            radius_m: 2e5,
            ..base.clone()
        })
        .0,
        "radius_m",
        "beyond what a tangent plane is true over"
    );
    let (f, _) = field(Geofence {
        exclusions: vec![FenceArea::Circle {
            north_m: 5e3,
            east_m: 0.0,
            radius_m: 5.0,
        }],
        ..base.clone()
    });
    assert_eq!(f, "exclusions[0].circle");
    let (f, why) = field(Geofence {
        polygon: vec![[0.0, 0.0], [10.0, 10.0], [10.0, 0.0], [0.0, 10.0]],
        ..base.clone()
    });
    assert_eq!(f, "polygon");
    assert!(why.contains("self-intersecting"), "{why}");
    let (f, why) = field(Geofence {
        polygon: vec![[0.0, 0.0], [1.0, 1.0]],
        ..base.clone()
    });
    assert_eq!(f, "polygon");
    assert!(why.contains("at least 3"), "{why}");
    let (_, why) = field(Geofence {
        polygon: vec![[0.0, 0.0], [10.0, 0.0], [20.0, 0.0]],
        ..base.clone()
    });
    assert!(why.contains("degenerate"), "{why}");
    let (_, why) = field(Geofence {
        polygon: vec![[0.0, 0.0], [10.0, 0.0], [10.0, 0.0], [0.0, 10.0]],
        ..base.clone()
    });
    assert!(why.contains("same point"), "{why}");
    let (f, why) = field(Geofence {
        radius_m: 100.0,
        polygon: square(90.0),
        ..base.clone()
    });
    assert_eq!(f, "polygon");
    assert!(why.contains("inside the circle"), "{why}");
    let (f, _) = field(Geofence {
        exclusions: vec![FenceArea::Circle {
            north_m: 0.0,
            east_m: 0.0,
            radius_m: -1.0,
        }],
        ..base.clone()
    });
    assert_eq!(f, "exclusions[0].circle");
    let (f, _) = field(Geofence {
        exclusions: vec![
            FenceArea::Polygon(square(5.0)),
            FenceArea::Polygon(vec![[0.0, 0.0], [1.0, 1.0]]),
        ],
        ..base.clone()
    });
    assert_eq!(f, "exclusions[1].polygon");
    let (f, why) = field(Geofence {
        polygon: square(50.0),
        rally_points: vec![RallyPoint {
            north_m: 80.0,
            east_m: 0.0,
            altitude_m: 20.0,
        }],
        ..base.clone()
    });
    assert_eq!(f, "rally_points[0]");
    assert!(why.contains("outside"), "{why}");
}

#[test]
fn the_json_of_a_fence_round_trips_and_refuses_unknown_fields() {
    let fence = Geofence {
        polygon: square(50.0),
        exclusions: vec![
            FenceArea::Circle {
                north_m: 1.0,
                east_m: 2.0,
                radius_m: 3.0,
            },
            FenceArea::Polygon(square(5.0)),
        ],
        rally_points: vec![RallyPoint {
            north_m: 0.0,
            east_m: 0.0,
            altitude_m: 20.0,
        }],
        breach_action: BreachAction::Rtl,
        ..Geofence::default()
    };
    let json = serde_json::to_value(&fence).unwrap();
    assert_eq!(json["breach_action"], "rtl");
    assert_eq!(json["exclusions"][0]["circle"]["radius_m"], 3.0);
    assert!(json.get("area_margin_m").is_none());
    let back: Geofence = serde_json::from_value(json).unwrap();
    assert_eq!(back, fence);
    let minimal: Geofence =
        serde_json::from_str(r#"{"radius_m": 100, "max_altitude_m": 50}"#).unwrap();
    assert_eq!(minimal.breach_action, BreachAction::Hold);
    assert!(
        serde_json::from_str::<Geofence>(r#"{"radius_m": 1, "max_altitude_m": 1, "x": 1}"#)
            .is_err()
    );
}
