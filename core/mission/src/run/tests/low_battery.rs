//! The low-battery reaction against the toy fleet: a reserve takes a low vehicle's
//! patrol, station or next step; without one the low vehicle goes home and its lanes go
//! to the others; the next step waits for those sent home.

use super::*;

/// A run of `steps` for `fleet` with the low-battery reaction at 35 % and `reserves`.
fn with_reserves(steps: &str, reserves: &[&str], fleet: &Fleet) -> MissionRun {
    let mut p = plan(steps);
    p.reactions.low_battery = Some(crate::plan::LowBattery {
        below_percent: 35.0,
        reserves: reserves.iter().map(|r| r.to_string()).collect(),
    });
    run_of(p, fleet)
}

#[test]
fn a_vehicle_low_on_battery_is_replaced_by_a_reserve_on_its_patrol() {
    let mut fleet = Fleet::new(4);
    let mut run = with_reserves(
        r#"[{"kind": "takeoff", "altitude_m": 10},
            {"kind": "patrol", "route": [[0, 0], [0, 40], [40, 40], [40, 0]], "altitude_m": 10,
             "duration_s": 120}, {"kind": "land"}]"#,
        &["uav-4"],
        &fleet,
    );
    assert_eq!(
        run.status().steps[1].vehicles,
        ["uav-1", "uav-2", "uav-3"],
        "the reserve waits"
    );
    fleet.fly(&mut run, 200.0, |r| r.status().step == 1);
    fleet.fly(&mut run, 20.0, |_| false);
    assert_eq!(fleet.toys["uav-4"].state, VehicleState::Landed);
    fleet.toys.get_mut("uav-2").unwrap().battery = 30.0;
    fleet.fly(&mut run, 60.0, |r| r.status().reactions.len() == 2);
    let r = &run.status().reactions;
    assert_eq!(r.len(), 2, "{r:?}");
    assert!(
        r[0].detail.contains("uav-4 takes off") && r[1].detail.contains("took over"),
        "{r:?}"
    );
    assert_eq!(run.status().steps[1].vehicles, ["uav-1", "uav-4", "uav-3"]);
    fleet.fly(&mut run, 60.0, |r| r.status().reactions.len() == 3);
    // The patrol's gap: from uav-2's leaving until uav-4 reached its route's next point.
    // uav-4 met uav-2 ahead on its route and waited there; uav-2 left within 8 m of it,
    // and uav-4 flew back to where it left: 2 s (flying from its home, 24 m east of the
    // origin, after uav-2 left: 5.5 s).
    let joined = &run.status().reactions[2];
    let gap_s = joined.gap_s.expect("a measured gap");
    assert!(
        joined.detail.contains("uav-4 on the route of uav-2"),
        "{joined:?}"
    );
    assert!(gap_s <= 3.0, "{joined:?}");
    assert!(
        run.status().reactions[..2]
            .iter()
            .all(|r| r.gap_s.is_none())
    );
    fleet.fly(&mut run, 2000.0, |r| r.status().state == RunState::Done);
    assert_eq!(run.status().state, RunState::Done);
    let home = |id: &str| {
        fleet
            .commands
            .iter()
            .filter(|(v, c)| v == id && matches!(c, Command::Rtl))
            .count()
    };
    assert_eq!(home("uav-2"), 1, "the low vehicle went home");
    assert!(
        fleet
            .commands
            .iter()
            .any(|(v, c)| v == "uav-4" && matches!(c, Command::GoTo(_))),
        "the reserve patrolled"
    );
    assert!(fleet.toys.values().all(|t| t.state == VehicleState::Landed));
}

/// A reserve sent up during a step that ends before it is up takes its place in the
/// next one, flown at another altitude (a rehearsed sortie had its reserve hover at the
/// survey's 15 m through a patrol at 18 m, while the low vehicle flew to 0 %).
#[test]
fn a_reserve_up_after_its_step_ended_takes_over_in_the_next_at_another_altitude() {
    let mut fleet = Fleet::new(4);
    let mut run = with_reserves(
        r#"[{"kind": "takeoff", "altitude_m": 10},
            {"kind": "transit", "waypoints": [[20, 12]], "altitude_m": 10, "speed_m_s": 5},
            {"kind": "patrol", "route": [[0, 0], [0, 40], [40, 40], [40, 0]], "altitude_m": 16,
             "duration_s": 60}, {"kind": "land"}]"#,
        &["uav-4"],
        &fleet,
    );
    fleet.fly(&mut run, 200.0, |r| r.status().step == 1);
    // Low 1.5 s before the transit's 20 m are flown: it ends before the reserve has
    // climbed its 10 m (2 s).
    fleet.fly(&mut run, 2.5, |_| false);
    fleet.toys.get_mut("uav-2").unwrap().battery = 30.0;
    fleet.fly(&mut run, 10.0, |r| r.status().step == 2);
    assert_eq!(
        run.status().reactions.len(),
        1,
        "{:?}",
        run.status().reactions
    );
    assert_ne!(
        fleet.toys["uav-4"].state,
        VehicleState::Hovering,
        "not up yet"
    );
    fleet.fly(&mut run, 60.0, |r| r.status().reactions.len() >= 2);
    let r = &run.status().reactions;
    assert!(r[1].detail.contains("uav-4 took over from uav-2"), "{r:?}");
    assert_eq!(run.status().steps[2].vehicles, ["uav-1", "uav-4", "uav-3"]);
}

/// The next step waits for the vehicle the reaction sent home to be down.
#[test]
fn the_next_step_waits_for_a_vehicle_sent_home() {
    let mut fleet = Fleet::new(4);
    // uav-2's home is far south: its return outlasts the station.
    let far = Ned::new(-80.0, 12.0, 0.0);
    let t = fleet.toys.get_mut("uav-2").unwrap();
    (t.pos, t.home) = (far, far);
    let mut run = with_reserves(
        r#"[{"kind": "takeoff", "altitude_m": 10},
            {"kind": "station", "points": [[60, 0], [60, 10], [60, 20]], "altitude_m": 10,
             "duration_s": 1},
            {"kind": "station", "points": [[5, 0], [5, 10], [5, 20]], "altitude_m": 10,
             "duration_s": 1}, {"kind": "land"}]"#,
        &["uav-4"],
        &fleet,
    );
    fleet.fly(&mut run, 200.0, |r| r.status().step == 1);
    // Low once on its station, 140 m from home.
    while fleet.toys["uav-2"].target.is_some() || fleet.toys["uav-2"].pos.north_m < 50.0 {
        let actions = run.tick(&fleet.tick());
        fleet.apply(actions);
        fleet.step(0.5);
    }
    fleet.toys.get_mut("uav-2").unwrap().battery = 30.0;
    let mut landed_at = None;
    while fleet.now_s < 400.0 && run.status().state != RunState::Done {
        let actions = run.tick(&fleet.tick());
        fleet.apply(actions);
        fleet.step(0.5);
        if landed_at.is_none() && fleet.toys["uav-2"].state == VehicleState::Landed {
            landed_at = Some(fleet.now_s);
        }
    }
    let landed_at = landed_at.expect("uav-2 landed");
    let status = run.status();
    let left = status
        .reactions
        .iter()
        .find(|r| r.detail.contains("took over"))
        .expect("a swap")
        .at_s;
    // The first step to start after uav-2 left waited for it; the one before ended
    // while it was still on its way.
    let next = status
        .steps
        .iter()
        .position(|s| s.started_s.is_some_and(|t| t > left))
        .expect("a step after the swap");
    let steps = &status.steps;
    assert!(
        steps[next - 1].ended_s.unwrap() < landed_at,
        "nothing waited (uav-2 down at {landed_at} s): {steps:?}"
    );
    assert!(
        steps[next].started_s.unwrap() >= landed_at,
        "step {next} started before uav-2 was down ({landed_at} s): {steps:?}"
    );
}

/// A vehicle low while on its station (its route flown) is replaced too.
#[test]
fn a_vehicle_low_on_its_station_is_replaced() {
    let mut fleet = Fleet::new(4);
    let mut run = with_reserves(
        r#"[{"kind": "takeoff", "altitude_m": 10},
            {"kind": "station", "points": [[0, 0], [0, 10], [0, 20]], "altitude_m": 10,
             "duration_s": 60}, {"kind": "land"}]"#,
        &["uav-4"],
        &fleet,
    );
    fleet.fly(&mut run, 200.0, |r| r.status().step == 1);
    fleet.fly(&mut run, 10.0, |_| false);
    fleet.toys.get_mut("uav-2").unwrap().battery = 30.0;
    fleet.fly(&mut run, 30.0, |r| r.status().reactions.len() >= 2);
    let r = &run.status().reactions;
    assert!(r[1].detail.contains("uav-4 took over from uav-2"), "{r:?}");
}

#[test]
fn without_a_reserve_a_low_survey_vehicle_returns_and_its_lanes_are_flown_by_others() {
    let mut fleet = Fleet::new(3);
    let mut run = with_reserves(SURVEY, &[], &fleet);
    fleet.fly(&mut run, 100.0, |r| r.status().step == 1);
    fleet.fly(&mut run, 15.0, |_| false);
    fleet.toys.get_mut("uav-1").unwrap().battery = 20.0;
    fleet.fly(&mut run, 2000.0, |r| r.status().step == 2);
    let survey = run.status().steps[1].progress.clone().unwrap();
    assert_eq!(survey.lanes_done, survey.lanes_total, "{survey:?}");
    assert!(
        run.status().reactions[0].detail.contains("no reserve left"),
        "{:?}",
        run.status().reactions
    );
}

#[test]
fn vehicles_sent_home_without_a_reserve_fly_no_later_step() {
    let mut fleet = Fleet::new(2);
    let mut run = with_reserves(
        r#"[{"kind": "takeoff", "altitude_m": 10},
            {"kind": "patrol", "route": [[0, 0], [0, 40], [40, 40], [40, 0]], "altitude_m": 10,
             "duration_s": 600},
            {"kind": "station", "points": [[5, 0], [5, 8]], "altitude_m": 8, "duration_s": 5},
            {"kind": "land"}]"#,
        &[],
        &fleet,
    );
    fleet.fly(&mut run, 200.0, |r| r.status().step == 1);
    fleet.fly(&mut run, 10.0, |_| false);
    fleet.toys.get_mut("uav-1").unwrap().battery = 20.0;
    fleet.fly(&mut run, 60.0, |r| r.status().reactions.len() == 1);
    assert_eq!(
        run.status().steps[2].vehicles,
        ["uav-2"],
        "uav-1 flies no later step"
    );
    fleet.toys.get_mut("uav-2").unwrap().battery = 20.0;
    // The patrol ends with nobody left on it, and the station and the landing with it:
    // the mission does not wait for vehicles that went home.
    fleet.fly(&mut run, 3000.0, |r| r.status().state == RunState::Done);
    let s = run.status();
    assert_eq!(s.state, RunState::Done, "{s:?}");
    assert_eq!(s.steps[2].state, StepState::Skipped, "{s:?}");
    assert!(s.steps[2].vehicles.is_empty(), "{s:?}");
}
