//! The run against a fleet that does what it is told, on a synthetic clock: every step
//! kind to the end, pause and resume, skip, abort, and a vehicle lost mid-survey whose
//! lanes the others fly.

use super::*;
use crate::plan::MissionPlan;

/// A vehicle that obeys at once: climbs, flies and descends at fixed rates.
#[derive(Debug, Clone)]
struct Toy {
    state: VehicleState,
    pos: Ned,
    home: Ned,
    target: Option<Ned>,
    battery: f64,
    observer: bool,
}

/// Vehicles that do what they are told, and a formation reference that flies waypoints.
struct Fleet {
    toys: BTreeMap<String, Toy>,
    reference: Option<(Ned, Vec<Ned>)>,
    now_s: f64,
    commands: Vec<(String, Command)>,
    tracks: Vec<TrackSeen>,
    observations: BTreeMap<String, Vec<String>>,
}

const SPEED_M_S: f64 = 5.0;

impl Fleet {
    fn new(n: usize) -> Fleet {
        let toys = (1..=n)
            .map(|i| {
                let home = Ned::new(0.0, 6.0 * i as f64, 0.0);
                let toy = Toy {
                    state: VehicleState::Landed,
                    pos: home,
                    home,
                    target: None,
                    battery: 80.0,
                    observer: false,
                };
                (format!("uav-{i}"), toy)
            })
            .collect();
        Fleet {
            toys,
            reference: None,
            now_s: 0.0,
            commands: Vec::new(),
            tracks: Vec::new(),
            observations: BTreeMap::new(),
        }
    }

    fn tick(&self) -> Tick {
        Tick {
            now_s: self.now_s,
            vehicles: self
                .toys
                .iter()
                .map(|(id, t)| {
                    let view = VehicleView {
                        id: id.clone(),
                        state: t.state,
                        position: Some(t.pos),
                        velocity: None,
                        relative_alt_m: Some(-t.pos.down_m),
                        battery_percent: Some(t.battery),
                        observer: t.observer,
                    };
                    (id.clone(), view)
                })
                .collect(),
            reference: self.reference.as_ref().map(|r| r.0),
            tracks: self.tracks.clone(),
        }
    }

    fn apply(&mut self, actions: Vec<Action>) {
        for a in actions {
            match a {
                Action::Command { vehicle, command } => self.command(vehicle, command),
                Action::SetFormation(spec) => {
                    let c = self.toys.values().next().unwrap().pos;
                    let alt = spec.altitude_m.unwrap_or(10.0);
                    self.reference = Some((Ned::new(c.north_m, c.east_m, -alt), vec![]));
                }
                Action::LeaderMotion(LeaderMotion::Waypoints { points, .. }) => {
                    if let Some(r) = &mut self.reference {
                        r.1 = points;
                    }
                }
                Action::LeaderMotion(_) => {
                    if let Some(r) = &mut self.reference {
                        r.1.clear();
                    }
                }
                Action::ClearFormation => self.reference = None,
                Action::Observe {
                    target, vehicles, ..
                } => {
                    // Observers fly toward the track and hover 20 m short of it.
                    let at = self
                        .tracks
                        .iter()
                        .find(|t| t.id == target)
                        .unwrap()
                        .position;
                    for v in &vehicles {
                        let toy = self.toys.get_mut(v).unwrap();
                        toy.state = VehicleState::GoTo;
                        toy.target = Some(Ned::new(at.north_m - 20.0, at.east_m, toy.pos.down_m));
                    }
                    self.observations.insert(target, vehicles);
                }
                Action::StopObserving { target } => {
                    for v in self.observations.remove(&target).unwrap_or_default() {
                        let toy = self.toys.get_mut(&v).unwrap();
                        toy.state = VehicleState::Hovering;
                        toy.target = None;
                    }
                }
            }
        }
    }

    fn command(&mut self, id: String, command: Command) {
        let t = self.toys.get_mut(&id).unwrap();
        if t.state == VehicleState::Lost {
            return;
        }
        match &command {
            Command::Takeoff(to) => {
                t.state = VehicleState::TakingOff;
                t.target = Some(Ned::new(
                    t.pos.north_m,
                    t.pos.east_m,
                    -to.altitude_m.unwrap(),
                ));
            }
            Command::GoTo(g) => {
                t.state = VehicleState::GoTo;
                t.target = Some(g.target());
            }
            Command::Hold => {
                t.state = VehicleState::Hovering;
                t.target = None;
            }
            Command::Land => {
                t.state = VehicleState::Landing;
                t.target = Some(Ned::new(t.pos.north_m, t.pos.east_m, 0.0));
            }
            Command::Rtl => {
                t.state = VehicleState::ReturnToLaunch;
                t.target = Some(t.home);
            }
            _ => {}
        }
        self.commands.push((id, command));
    }

    /// Moves everything on by `dt` seconds.
    fn step(&mut self, dt: f64) {
        self.now_s += dt;
        for t in self.toys.values_mut() {
            let Some(target) = t.target else { continue };
            let d = target - t.pos;
            if d.norm() <= SPEED_M_S * dt {
                t.pos = target;
                t.target = None;
                t.state = match t.state {
                    VehicleState::Landing | VehicleState::ReturnToLaunch => VehicleState::Landed,
                    VehicleState::Lost => VehicleState::Lost,
                    _ => VehicleState::Hovering,
                };
            } else {
                t.pos = t.pos + d * (SPEED_M_S * dt / d.norm());
            }
        }
        if let Some((r, points)) = &mut self.reference
            && let Some(p) = points.first().copied()
        {
            let d = p - *r;
            if d.norm() <= SPEED_M_S * dt {
                *r = p;
                points.remove(0);
            } else {
                *r = *r + d * (SPEED_M_S * dt / d.norm());
            }
        }
    }

    /// Ticks the run and the fleet every 0.5 s until `until` holds or `max_s` passes.
    fn fly(&mut self, run: &mut MissionRun, max_s: f64, until: impl Fn(&MissionRun) -> bool) {
        let end = self.now_s + max_s;
        while self.now_s < end && !until(run) {
            let actions = run.tick(&self.tick());
            self.apply(actions);
            self.step(0.5);
        }
    }
}

fn plan(steps: &str) -> MissionPlan {
    serde_json::from_str(&format!(
        r#"{{"name": "t", "groups": {{"two": {{"vehicles": ["uav-1", "uav-2"]}}}}, "steps": {steps}}}"#
    ))
    .unwrap()
}

fn run_of(plan: MissionPlan, fleet: &Fleet) -> MissionRun {
    let members: Vec<crate::resolve::Member> = fleet
        .toys
        .keys()
        .map(|id| crate::resolve::Member {
            id: id.clone(),
            model: "generic".into(),
        })
        .collect();
    let groups = crate::resolve::groups(&plan, &members).unwrap();
    let mut run = MissionRun::new(plan, groups);
    run.start();
    run
}

/// Take off, survey a 30 x 60 m rectangle in 6 m lanes (10 of them), land.
const SURVEY: &str = r#"[{"kind": "takeoff", "altitude_m": 10},
    {"kind": "survey", "polygon": [[20, 0], [20, 60], [80, 60], [80, 0]], "altitude_m": 15,
     "lane_spacing_m": 6}, {"kind": "land"}]"#;

const EVERY_KIND: &str = r#"[
    {"kind": "takeoff", "altitude_m": 10, "interval_s": 1},
    {"kind": "transit", "waypoints": [[40, 0]], "altitude_m": 12, "speed_m_s": 5,
     "formation": {"shape": "line", "spacing_m": 7}},
    {"kind": "survey", "polygon": [[20, 0], [20, 60], [50, 60], [50, 0]], "altitude_m": 15,
     "lane_spacing_m": 6},
    {"kind": "patrol", "group": "two", "route": [[0, 0], [0, 40], [40, 40], [40, 0]],
     "altitude_m": 15, "duration_s": 20},
    {"kind": "station", "points": [[10, 10], [10, 20], [10, 30]], "altitude_m": 12,
     "duration_s": 5},
    {"kind": "transit", "group": "two", "waypoints": [[0, 10]], "altitude_m": 12,
     "speed_m_s": 5},
    {"kind": "return", "group": "two"},
    {"kind": "land"}]"#;

#[test]
fn every_step_kind_is_flown_to_the_end() {
    let mut fleet = Fleet::new(3);
    let mut run = run_of(plan(EVERY_KIND), &fleet);
    fleet.fly(&mut run, 2000.0, |r| r.status().state == RunState::Done);
    let s = run.status();
    assert_eq!(s.state, RunState::Done, "{s:#?}");
    assert!(
        s.steps.iter().all(|st| st.state == StepState::Done),
        "{s:#?}"
    );
    let survey = s.steps[2].progress.as_ref().unwrap();
    assert_eq!(survey.lanes_done, Some(5), "{survey:?}");
    assert_eq!(survey.lanes_total, Some(5));
    assert!(fleet.toys.values().all(|t| t.state == VehicleState::Landed));
    // Taken off in turn, one second apart.
    let takeoffs: Vec<&String> = fleet
        .commands
        .iter()
        .filter(|(_, c)| matches!(c, Command::Takeoff(_)))
        .map(|(id, _)| id)
        .collect();
    assert_eq!(takeoffs, ["uav-1", "uav-2", "uav-3"]);
    // The patrol lasted its 20 s once both were on the route.
    let patrol = &s.steps[3];
    assert!(
        patrol.ended_s.unwrap() - patrol.started_s.unwrap() >= 20.0,
        "{patrol:?}"
    );
    // uav-3 was not in the patrol's group.
    assert_eq!(patrol.vehicles, ["uav-1", "uav-2"]);
}

#[test]
fn a_pause_holds_and_freezes_the_clock_and_a_resume_carries_on() {
    let mut fleet = Fleet::new(2);
    let mut run = run_of(
        plan(
            r#"[{"kind": "takeoff", "altitude_m": 10},
                {"kind": "station", "points": [[30, 0], [30, 10]], "altitude_m": 10,
                 "duration_s": 10}, {"kind": "land"}]"#,
        ),
        &fleet,
    );
    fleet.fly(&mut run, 300.0, |r| r.status().step == 1);
    fleet.fly(&mut run, 2.0, |_| false);
    let held = run.pause();
    assert_eq!(held.len(), 2, "{held:?}");
    fleet.apply(held);
    let (elapsed, positions): (f64, Vec<Ned>) = (
        run.status().elapsed_s,
        fleet.toys.values().map(|t| t.pos).collect(),
    );
    fleet.fly(&mut run, 30.0, |_| false);
    assert_eq!(run.status().elapsed_s, elapsed, "a paused run does not age");
    let now: Vec<Ned> = fleet.toys.values().map(|t| t.pos).collect();
    assert_eq!(now, positions, "held where they were");
    let resumed = run.resume();
    fleet.apply(resumed);
    fleet.fly(&mut run, 300.0, |r| r.status().state == RunState::Done);
    assert_eq!(run.status().state, RunState::Done);
}

#[test]
fn a_skipped_step_ends_and_the_next_starts() {
    let mut fleet = Fleet::new(2);
    let mut run = run_of(
        plan(
            r#"[{"kind": "takeoff", "altitude_m": 10},
                {"kind": "patrol", "route": [[0, 0], [0, 40], [40, 40]], "altitude_m": 12},
                {"kind": "land"}]"#,
        ),
        &fleet,
    );
    fleet.fly(&mut run, 100.0, |r| r.status().step == 1);
    fleet.fly(&mut run, 30.0, |_| false);
    assert_eq!(run.status().step, 1, "a patrol without a duration goes on");
    let out = run.skip();
    fleet.apply(out);
    assert_eq!(run.status().steps[1].state, StepState::Skipped);
    fleet.fly(&mut run, 200.0, |r| r.status().state == RunState::Done);
    assert!(fleet.toys.values().all(|t| t.state == VehicleState::Landed));
}

#[test]
fn an_abort_holds_then_brings_everyone_back() {
    let mut fleet = Fleet::new(3);
    let mut run = run_of(plan(EVERY_KIND), &fleet);
    fleet.fly(&mut run, 600.0, |r| r.status().step == 2);
    fleet.fly(&mut run, 5.0, |_| false);
    let airborne: Vec<String> = fleet.toys.keys().cloned().collect();
    let out = run.abort(&airborne);
    assert!(
        out.iter()
            .filter(|a| matches!(
                a,
                Action::Command {
                    command: Command::Hold,
                    ..
                }
            ))
            .count()
            == 3
    );
    fleet.apply(out);
    assert!(run.aborting());
    fleet.fly(&mut run, 600.0, |r| r.status().state == RunState::Aborted);
    assert_eq!(run.status().state, RunState::Aborted);
    assert_eq!(run.status().steps[2].state, StepState::Skipped);
    for t in fleet.toys.values() {
        assert_eq!(
            (t.state, t.pos),
            (VehicleState::Landed, t.home),
            "returned home"
        );
    }
}

#[test]
fn a_vehicle_lost_mid_survey_leaves_its_lanes_to_the_others() {
    let mut fleet = Fleet::new(3);
    let mut run = run_of(plan(SURVEY), &fleet);
    fleet.fly(&mut run, 100.0, |r| r.status().step == 1);
    fleet.fly(&mut run, 20.0, |_| false);
    let t = fleet.toys.get_mut("uav-2").unwrap();
    t.state = VehicleState::Lost;
    t.target = None;
    fleet.fly(&mut run, 2000.0, |r| r.status().step == 2);
    let survey = run.status().steps[1].progress.clone().unwrap();
    assert_eq!(
        survey.lanes_done, survey.lanes_total,
        "every lane flown: {survey:?}"
    );
    assert_eq!(survey.lanes_total, Some(10));
}

/// Three vehicles, uav-2 and uav-3 carrying gimbals, and `steps` with the intruder
/// reaction: two observers, from stations, for tracks in `zone`.
fn observed(steps: &str, zone: Option<Vec<[f64; 2]>>) -> (Fleet, MissionPlan) {
    let mut fleet = Fleet::new(3);
    for id in ["uav-2", "uav-3"] {
        fleet.toys.get_mut(id).unwrap().observer = true;
    }
    let mut p = plan(steps);
    p.reactions.intruder = Some(crate::plan::IntruderReaction {
        zone,
        observers: 2,
        stations: true,
        standoff_m: None,
    });
    (fleet, p)
}

#[test]
fn an_intruder_in_the_zone_draws_observers_who_then_finish_their_lanes() {
    let (mut fleet, p) = observed(
        SURVEY,
        Some(vec![
            [0.0, 70.0],
            [0.0, 150.0],
            [100.0, 150.0],
            [100.0, 70.0],
        ]),
    );
    let mut run = run_of(p, &fleet);
    fleet.fly(&mut run, 100.0, |r| r.status().step == 1);
    fleet.fly(&mut run, 10.0, |_| false);
    let track = |id: &str, north_m: f64, confirmed: bool| TrackSeen {
        id: id.into(),
        position: Ned::new(north_m, 100.0, -14.0),
        confirmed,
    };
    // Outside the zone, or tentative: nothing.
    fleet.tracks = vec![track("track-1", 200.0, true), track("track-2", 50.0, false)];
    fleet.fly(&mut run, 5.0, |_| false);
    assert!(run.status().reactions.is_empty() && fleet.observations.is_empty());
    fleet.tracks = vec![track("track-2", 50.0, true)];
    fleet.fly(&mut run, 1.0, |r| !r.status().reactions.is_empty());
    assert_eq!(
        fleet.observations["track-2"],
        ["uav-2", "uav-3"],
        "the two observers"
    );
    assert_eq!(run.observers().len(), 2);
    // The rest carries on meanwhile; the observers' lanes wait.
    let lanes = |run: &MissionRun| run.status().steps[1].progress.clone().unwrap().lanes_done;
    let before = lanes(&run);
    let away = fleet.commands.len();
    fleet.fly(&mut run, 30.0, |_| false);
    assert!(lanes(&run) > before, "uav-1 flew on");
    assert!(
        fleet.commands[away..]
            .iter()
            .all(|(v, c)| v == "uav-1" || !matches!(c, Command::GoTo(_))),
        "no lane was sent to an observer"
    );
    // Lost: back to their lanes, and every lane gets flown.
    fleet.tracks = vec![track("track-2", 50.0, false)];
    fleet.fly(&mut run, 2000.0, |r| r.status().step == 2);
    assert!(fleet.observations.is_empty());
    let survey = run.status().steps[1].progress.clone().unwrap();
    assert_eq!(survey.lanes_done, survey.lanes_total, "{survey:?}");
    let r = &run.status().reactions;
    assert_eq!(r.len(), 2, "{r:?}");
    assert!(r[0].detail.contains("observe it") && r[1].detail.contains("back to the step"));
    assert_eq!(r[0].kind, "intruder");
}

#[test]
fn observers_drawn_from_their_stations_fly_back_to_them_when_the_track_is_lost() {
    let (mut fleet, p) = observed(
        r#"[{"kind": "takeoff", "altitude_m": 10},
            {"kind": "station", "points": [[10, 0], [10, 8], [10, 16]], "altitude_m": 10,
             "duration_s": 600}, {"kind": "land"}]"#,
        None,
    );
    let mut run = run_of(p, &fleet);
    let stations = |fleet: &Fleet| {
        let at = |id: &str| fleet.toys[id].pos;
        [at("uav-1"), at("uav-2"), at("uav-3")]
    };
    let held = |r: &MissionRun| {
        r.status().steps[1]
            .progress
            .as_ref()
            .is_some_and(|p| p.detail.contains("of 600 s"))
    };
    fleet.fly(&mut run, 100.0, held);
    assert!(held(&run), "on station");
    let on_station = stations(&fleet);
    fleet.tracks = vec![TrackSeen {
        id: "track-1".into(),
        position: Ned::new(60.0, 40.0, -14.0),
        confirmed: true,
    }];
    fleet.fly(&mut run, 30.0, |_| false);
    let mut observers = fleet.observations["track-1"].clone();
    observers.sort();
    assert_eq!(observers, ["uav-2", "uav-3"]);
    assert!(
        (fleet.toys["uav-2"].pos - on_station[1]).norm() > 10.0,
        "drawn away"
    );
    // Lost: the observers hold where they are, then fly back to their stations.
    fleet.tracks.clear();
    fleet.fly(&mut run, 60.0, |_| false);
    for (at, station) in stations(&fleet).iter().zip(on_station) {
        assert!((*at - station).norm() < ARRIVED_M, "{at:?} off {station:?}");
    }
    assert_eq!(run.status().step, 1, "the step's clock runs on");
}

#[test]
fn a_timed_patrol_ends_on_time_while_its_observers_still_observe() {
    let (mut fleet, p) = observed(
        r#"[{"kind": "takeoff", "altitude_m": 10},
            {"kind": "patrol", "route": [[0, 0], [0, 40], [40, 40], [40, 0]],
             "altitude_m": 15, "duration_s": 20}, {"kind": "land"}]"#,
        None,
    );
    let mut run = run_of(p, &fleet);
    fleet.fly(&mut run, 100.0, |r| r.status().step == 1);
    // A track confirmed as the patrol starts, before anyone is on the route, and never
    // lost: two vehicles observe it for the rest of the step.
    fleet.tracks = vec![TrackSeen {
        id: "track-1".into(),
        position: Ned::new(100.0, 100.0, -14.0),
        confirmed: true,
    }];
    let started = fleet.now_s;
    fleet.fly(&mut run, 300.0, |r| r.status().step == 2);
    assert_eq!(run.status().step, 2, "the patrol never ended");
    // uav-1 on the route, then 20 s: the observers do not hold the step's clock.
    assert!(fleet.now_s - started < 60.0, "{} s", fleet.now_s - started);
}

#[test]
fn stations_go_to_the_nearest_vehicles_so_that_no_way_crosses_another() {
    // uav-1 hovers far east, uav-3 far west: in the group's order uav-1 would take the
    // west station across uav-2's and uav-3's ways.
    let mut fleet = Fleet::new(3);
    for (id, east) in [("uav-1", 40.0), ("uav-2", 20.0), ("uav-3", 0.0)] {
        let t = fleet.toys.get_mut(id).unwrap();
        t.state = VehicleState::Hovering;
        t.pos = Ned::new(20.0, east, -10.0);
    }
    let mut run = run_of(
        plan(
            r#"[{"kind": "station", "points": [[5, 0], [5, 8], [5, 16]], "altitude_m": 8,
                 "duration_s": 1}]"#,
        ),
        &fleet,
    );
    fleet.apply(run.tick(&fleet.tick()));
    let sent: BTreeMap<String, (f64, f64)> = fleet
        .commands
        .iter()
        .filter_map(|(id, c)| match c {
            Command::GoTo(g) => Some((id.clone(), (g.north_m, g.east_m))),
            _ => None,
        })
        .collect();
    assert_eq!(sent["uav-1"], (5.0, 16.0), "{sent:?}");
    assert_eq!(sent["uav-2"], (5.0, 8.0), "{sent:?}");
    assert_eq!(sent["uav-3"], (5.0, 0.0), "{sent:?}");
}

mod low_battery;
mod takeover;
