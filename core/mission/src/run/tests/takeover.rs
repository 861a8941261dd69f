//! A run mirrored mid-survey and taken over by a coordinator whose swarm frame lies
//! elsewhere: the survey goes on where it was, no lane flown twice, none skipped.

use super::*;

/// The other coordinator's frame: its origin 100 m south and 40 m west of this one's, so
/// a point here is 100 m further north and 40 m further east there.
fn there(p: Ned) -> Ned {
    p + Ned::new(100.0, 40.0, 0.0)
}

fn gotos(commands: &[(String, Command)]) -> Vec<Ned> {
    commands
        .iter()
        .filter_map(|(_, c)| match c {
            Command::GoTo(g) => Some(g.target()),
            _ => None,
        })
        .collect()
}

#[test]
fn a_survey_taken_over_in_another_frame_flies_on_without_a_lane_twice() {
    let mut fleet = Fleet::new(3);
    let mut run = run_of(plan(SURVEY), &fleet);
    fleet.fly(&mut run, 100.0, |r| r.status().step == 1);
    let survey_from = fleet.commands.len();
    fleet.fly(&mut run, 25.0, |_| false);
    let lanes = |run: &MissionRun| run.status().steps[1].progress.clone().unwrap();
    let before = lanes(&run);
    assert!(before.lanes_done >= Some(1), "{before:?}");
    let flown_before: Vec<Ned> = gotos(&fleet.commands[survey_from..])
        .into_iter()
        .map(there)
        .collect();

    // Mirrored (JSON, as on DDS), then taken over 1.5 s later in the other frame.
    let mirrored = serde_json::to_string(&run).unwrap();
    let mut taken: MissionRun = serde_json::from_str(&mirrored).unwrap();
    taken.reframe(&there);
    assert!(taken.positions_finite());
    let crate::plan::StepKind::Survey(s) = &taken.plan().steps[1].kind else {
        panic!("a survey")
    };
    assert_eq!(s.polygon[0], [120.0, 40.0], "the plan moved too");
    for t in fleet.toys.values_mut() {
        t.pos = there(t.pos);
        t.home = there(t.home);
        t.target = t.target.map(there);
    }
    let elapsed = run.status().elapsed_s;
    let at_once = taken.take_over(1.5);
    assert!(at_once.is_empty(), "{at_once:?}");
    assert!((taken.status().elapsed_s - elapsed - 1.5).abs() < 1e-9);
    assert_eq!(lanes(&taken), before, "the progress carried over");
    // At its first tick every survey vehicle is told its current point again, from
    // where it is.
    let resent = taken.tick(&fleet.tick());
    let resent_to = gotos(
        &resent
            .iter()
            .filter_map(|a| match a {
                Action::Command { vehicle, command } => Some((vehicle.clone(), command.clone())),
                _ => None,
            })
            .collect::<Vec<_>>(),
    );
    assert_eq!(resent_to.len(), 3, "{resent:?}");
    fleet.apply(resent);
    fleet.step(0.5);

    let after_from = fleet.commands.len();
    fleet.fly(&mut taken, 2000.0, |r| r.status().step == 2);
    let done = lanes(&taken);
    assert_eq!(
        done.lanes_done, done.lanes_total,
        "every lane flown: {done:?}"
    );
    assert_eq!(done.lanes_total, Some(10));
    // No point flown before the takeover was commanded after it, but the ones the
    // vehicles were flying to.
    let twice: Vec<Ned> = gotos(&fleet.commands[after_from..])
        .into_iter()
        .filter(|p| flown_before.iter().any(|q| (*p - *q).norm() < 1e-6))
        .filter(|p| !resent_to.iter().any(|q| (*p - *q).norm() < 1e-6))
        .collect();
    assert!(twice.is_empty(), "flown again: {twice:?}");
    fleet.fly(&mut taken, 200.0, |r| r.status().state == RunState::Done);
    assert_eq!(taken.status().state, RunState::Done);
}

#[test]
fn a_step_or_reaction_of_an_unknown_kind_is_no_mirrored_run() {
    let fleet = Fleet::new(1);
    let run = run_of(plan(r#"[{"kind": "takeoff", "altitude_m": 10}]"#), &fleet);
    let json = serde_json::to_string(&run)
        .unwrap()
        .replace("\"takeoff\"", "\"hover\"");
    let e = serde_json::from_str::<MissionRun>(&json).unwrap_err();
    assert!(e.to_string().contains("hover"), "{e}");
}
