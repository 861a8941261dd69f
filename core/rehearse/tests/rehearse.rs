//! Rehearsals of whole plans on simulated vehicles in virtual time.

use serde_json::json;
use skein_mission::MissionPlan;
use skein_mission::resolve::{self, Member};
use skein_model::geo::{GeoPoint, Ned};
use skein_model::geofence::Geofence;
use skein_model::safety::MotionLimits;
use skein_rehearse::{Scenario, SwarmSetup, VehicleSetup, rehearse};

/// `n` vehicles on a 5 m grid, the even ones observation UAVs.
fn swarm(n: usize) -> SwarmSetup {
    SwarmSetup {
        origin: GeoPoint::new(47.397_742, 8.545_594, 488.0),
        vehicles: (1..=n)
            .map(|i| VehicleSetup {
                id: format!("uav-{i}"),
                model: if i % 2 == 0 { "observation" } else { "generic" }.into(),
                home: Ned::new(-5.0 * ((i - 1) / 3) as f64, 5.0 * ((i - 1) % 3) as f64, 0.0),
                limits: MotionLimits::default(),
                battery_percent: None,
                battery_capacity_mah: None,
                observer: i % 2 == 0,
            })
            .collect(),
        fence: Geofence::default(),
        min_separation_m: 3.0,
        separation_margin_m: 0.5,
        control_rate_hz: 50.0,
        formation_rate_hz: 10.0,
    }
}

fn groups(plan: &MissionPlan, swarm: &SwarmSetup) -> Vec<Vec<String>> {
    let members: Vec<Member> = swarm
        .vehicles
        .iter()
        .map(|v| Member {
            id: v.id.clone(),
            model: v.model.clone(),
        })
        .collect();
    resolve::groups(plan, &members).unwrap()
}

#[test]
fn a_survey_is_rehearsed_to_the_end_with_its_figures() {
    let plan: MissionPlan = serde_json::from_value(json!({
        "name": "survey",
        "steps": [
            {"kind": "takeoff", "altitude_m": 10, "interval_s": 1},
            {"kind": "survey", "polygon": [[20, -20], [20, 30], [60, 30], [60, -20]],
             "altitude_m": 12, "camera": {"hfov_deg": 60, "overlap": 0.2}},
            {"kind": "land", "interval_s": 1}
        ]
    }))
    .unwrap();
    let swarm = swarm(3);
    let report = rehearse(&plan, groups(&plan, &swarm), &swarm, &Scenario::default()).unwrap();
    let mut shown = serde_json::to_value(&report).unwrap();
    shown["picture_svg"] = json!(report.picture_svg.len());
    println!("{shown:#}");
    assert_eq!(report.state, skein_mission::RunState::Done, "{shown}");
    assert!(report.coverage.unwrap() > 0.99, "{shown}");
    assert!(report.min_separation_m.unwrap() > 3.0, "{shown}");
    assert!(report.min_fence_margin_m.unwrap() > 0.0, "{shown}");
    assert_eq!(report.energy_left.len(), 3);
    assert!(
        report.energy_left.values().all(|e| *e < 100.0 && *e > 50.0),
        "{shown}"
    );
    assert!(report.picture_svg.starts_with("<svg") && report.picture_svg.contains("uav-2"));
}
