//! Distributed skein on one machine: one `skein coordinator` and three `skein agent`s
//! (one simulated vehicle each, sysids 1 to 3), each its own process, on DDS over
//! loopback (`--dds-network 127.0.0.1`, a domain of this test process's own). Only
//! through the coordinator's HTTP API:
//!
//! - the agents' vehicles join the coordinator as remote vehicles, at the places their
//!   simulators spawned them (each agent's swarm frame converted into the
//!   coordinator's);
//! - the swarm takes off (every vehicle acknowledges over DDS, and its events, the
//!   takeoff's outcome and its state changes, reach the coordinator's stream), flies a
//!   wedge behind a virtual leader cruising at 5 m/s, with the steady RMS slot error of
//!   single-process mode (under 0.3 m), never closer than the separation;
//! - RTK corrections from the coordinator's one source (RTCM3 datagrams to a UDP port,
//!   given through its API) reach every agent's vehicle relayed over DDS
//!   (`/skein/rtcm`): each reaches RTK float or fixed, and each agent's `GET
//!   /api/v1/rtk` shows the topic as its source, streaming;
//!
//! then the coordinator is killed (SIGKILL) mid-formation, and through each agent's own
//! loopback API:
//!
//! - every vehicle flies on along its slot for its agent's ride-through (2 s here): the
//!   wedge goes on north;
//! - then it holds (`Hovering`, under offboard control), and stays where it held;
//! - after `coordinator_lost_action_s` (4 s) more it lands (`coordinator_lost_action =
//!   land`);
//! - no simulated PX4 took the offboard-loss failsafe, and no setpoint gap in OFFBOARD
//!   reached 100 ms.
//!
//! Then a mission carried through a failover: two coordinator candidates and the three
//! agents; the active one flies a camera survey and is killed once a lane is done; the
//! standby flies the mission on (same id, same step, the lanes as they were) to the
//! landing, the survey covered at its planned overlap.
//!
//! Across hosts, through a WLAN's fades and coordinator failovers: `e2e_wlan.rs`.

mod support;

use serde_json::{Value, json};
use skein_model::geo::Ned;
use skein_rehearse::coverage::Coverage;
use std::time::{Duration, Instant};
use support::bench::bench_report;
use support::distributed::{
    AgentOptions, agent_on, candidate_on, cyclone_intruder, role, wait_roles,
};
use support::formation::{cruise, wedge_north};
use support::rtk::UdpBase;
use support::{EventLog, Skein, assert_no_failsafe_and_no_gap, eventually, summary};

/// DDS domain `k` (0 to 2) of this test process's own, apart from `e2e_dds`' 100–179,
/// `e2e_ros2`'s 180–218 and `e2e_failover`'s 220–231.
fn domain(k: u32) -> String {
    (20 + (std::process::id() % 26) * 3 + k).to_string()
}

/// Seconds without a coordinator before an agent holds (past when the next lease was
/// due), unless it rides through for longer; and then before it lands.
const TIMEOUT_S: f64 = 1.5;
const LOST_ACTION_S: f64 = 4.0;
/// How long the loopback agents fly their slots on without their coordinator.
const RIDE_S: f64 = 2.0;

fn agent(sysid: u8, d: &str) -> Skein {
    agent_configured(sysid, d, None)
}

/// [`agent`] with a configuration file.
fn agent_configured(sysid: u8, d: &str, config: Option<String>) -> Skein {
    let o = AgentOptions {
        timeout_s: TIMEOUT_S,
        ride_through_s: RIDE_S,
        lost_action: "land",
        lost_action_s: LOST_ACTION_S,
        config,
        ..AgentOptions::default()
    };
    agent_on(None, sysid, d, &o)
}

/// The coordinator `ground` (priority 2) on domain `d`, over loopback.
fn ground(d: &str) -> Skein {
    Skein::coordinator(&[
        "--id",
        "ground",
        "--priority",
        "2",
        "--domain-id",
        d,
        "--dds-network",
        "127.0.0.1",
    ])
}

/// A base station 600 m north-east of the simulator's home (PX4 SITL's, Zurich).
const BASE: (f64, f64, f64) = (47.4021, 8.5512, 535.0);

/// Gives the coordinator `base`'s corrections as its source.
fn corrections_to(coordinator: &Skein, base: &UdpBase) {
    let (status, r) = coordinator.put("/api/v1/rtk", json!({"source": base.source()}));
    assert_eq!(status, 200, "{r}");
}

/// Every agent's vehicle in RTK float or fixed, on corrections relayed from the
/// coordinator; returns how long it was waited for, seconds (measured 0.003–0.006 s: the
/// takeoff and the cruise since the corrections started take longer than the 5 s the
/// simulated receivers need to float).
fn relayed_rtk_everywhere(coordinator: &Skein, agents: &[Skein]) -> f64 {
    let waited = Instant::now();
    for a in agents {
        let r = eventually(
            "RTK float from relayed corrections",
            Duration::from_secs(30),
            || {
                let (code, r) = a.get("/api/v1/rtk");
                let fix = r["vehicles"][0]["fix_type"].as_u64();
                if code == 200 && r["state"] == "streaming" && fix >= Some(5) {
                    Ok(r)
                } else {
                    Err(r.to_string())
                }
            },
        );
        assert_eq!(r["source"], "dds:/skein/rtcm", "{r}");
        assert_eq!(r["relay"]["role"], "receiving", "{r}");
        assert!(r["message_types"]["1074"].as_u64() > Some(0), "{r}");
        assert_eq!(r["base"]["station_id"], 7, "{r}");
        assert!(r["vehicles"][0]["messages"].as_u64() > Some(0), "{r}");
    }
    let (_, c) = coordinator.get("/api/v1/rtk");
    assert_eq!(c["relay"]["role"], "publishing", "{c}");
    assert!(c["relay"]["published"].as_u64() > Some(0), "{c}");
    waited.elapsed().as_secs_f64()
}

/// The one vehicle of an agent, from its own API.
fn own_vehicle(a: &Skein) -> Value {
    let (code, v) = a.get("/api/v1/vehicles");
    assert_eq!(code, 200, "{v}");
    v.as_array()
        .and_then(|l| l.first())
        .cloned()
        .unwrap_or(Value::Null)
}

fn north_east(v: &Value) -> (f64, f64) {
    (
        v["position"]["north_m"].as_f64().unwrap_or(f64::NAN),
        v["position"]["east_m"].as_f64().unwrap_or(f64::NAN),
    )
}

#[test]
fn agents_fly_for_the_coordinator_and_hold_then_land_without_it() {
    let _one = support::one_at_a_time();
    let d = domain(0);
    let mut coordinator = ground(&d);
    let agents: Vec<Skein> = (1..=3).map(|sysid| agent(sysid, &d)).collect();
    eventually("the coordinator active", Duration::from_secs(20), || {
        let r = role(&coordinator);
        if r == "active" {
            Ok(())
        } else {
            Err(r.to_string())
        }
    });
    // One corrections source for the swarm, at the coordinator (no vehicle of its own).
    let base = UdpBase::start(BASE);
    corrections_to(&coordinator, &base);

    homes_apart(&coordinator);
    agents_events_on_the_coordinators_stream(&coordinator);
    let (mean_rms, worst_rms, min_sep) = cruise(&coordinator);
    for a in &agents {
        assert_eq!(own_vehicle(a)["state"], "InFormation", "{}", own_vehicle(a));
    }
    let rtk_wait_s = relayed_rtk_everywhere(&coordinator, &agents);

    // The coordinator dies with no goodbye.
    let norths: Vec<f64> = agents
        .iter()
        .map(|a| north_east(&own_vehicle(a)).0)
        .collect();
    let killed = Instant::now();
    coordinator.kill_hard();
    let held_at = held_after_the_ride_through(&agents, &norths, killed);
    let times = landed_after_the_lost_action(&held_at, killed);
    for a in &agents {
        let worst = assert_no_failsafe_and_no_gap(&a.sim_stats_addr());
        eprintln!(
            "{}",
            json!({"agent": a.base, "worst_setpoint_gap_ms": worst})
        );
    }
    eprintln!(
        "{}",
        json!({"formation_mean_rms_m": mean_rms, "formation_worst_rms_m": worst_rms,
               "min_separation_m": min_sep, "after_the_coordinator_died": times,
               "relayed_rtk_wait_s": rtk_wait_s})
    );
}

/// Each agent spawned its vehicle at its own grid point (sysid - 1, 4 columns): the
/// coordinator, whose frame is the first agent's, sees them apart, none at another's.
fn homes_apart(coordinator: &Skein) {
    // (A home can be reported before the first position in the swarm frame.)
    let vs = coordinator.wait_all("homes and positions", 3, Duration::from_secs(60), |v| {
        let (n, e) = north_east(v);
        v["home"].is_object() && n.is_finite() && e.is_finite()
    });
    let ids: Vec<&str> = vs.iter().filter_map(|v| v["id"].as_str()).collect();
    assert_eq!(ids, ["uav-1", "uav-2", "uav-3"], "{}", summary(&vs));
    for (i, a) in vs.iter().enumerate() {
        for b in &vs[i + 1..] {
            let ((an, ae), (bn, be)) = (north_east(a), north_east(b));
            let d = (an - bn).hypot(ae - be);
            assert!(d > 3.0, "{} and {} are {d:.2} m apart", a["id"], b["id"]);
        }
    }
}

/// The swarm takes off into a wedge: the vehicles' own events (on their agents) reach the
/// coordinator's stream.
fn agents_events_on_the_coordinators_stream(coordinator: &Skein) {
    let events = EventLog::connect(&coordinator.base);
    wedge_north(coordinator);
    eventually(
        "the agents' events on the coordinator's stream",
        Duration::from_secs(10),
        || {
            let took_off: Vec<Value> = events
                .of_type("command_result")
                .into_iter()
                .filter(|e| e["command"] == "takeoff" && e["ok"] == true)
                .collect();
            let formed = events
                .of_type("state_changed")
                .iter()
                .filter(|e| e["to"] == "InFormation")
                .count();
            if took_off.len() == 3 && formed == 3 {
                Ok(())
            } else {
                Err(format!("{took_off:?}, {formed} joined"))
            }
        },
    );
}

/// Each agent flies its vehicle on its slot for the ride-through (the wedge goes on north
/// at 5 m/s from `norths`), then holds it: where and when each held.
fn held_after_the_ride_through<'a>(
    agents: &'a [Skein],
    norths: &[f64],
    killed: Instant,
) -> Vec<(&'a Skein, (f64, f64), f64)> {
    let mut held_at = Vec::new();
    for (a, north0) in agents.iter().zip(norths.iter().copied()) {
        let v = eventually("a vehicle holding", Duration::from_secs(10), || {
            let v = own_vehicle(a);
            if v["state"] == "Hovering" {
                Ok(v)
            } else {
                Err(v.to_string())
            }
        });
        let after = killed.elapsed().as_secs_f64();
        assert!(
            after > RIDE_S - 0.3 && after < RIDE_S.max(TIMEOUT_S) + 1.0,
            "{} held {after:.2} s after the coordinator died (ride-through {RIDE_S} s)",
            v["id"]
        );
        assert_eq!(v["px4_mode"], "OFFBOARD", "{v}");
        // It rode on north: without the ride-through it stops within ~3 m (its last
        // target moved on 0.5 s, then braking).
        let rode = north_east(&v).0 - north0;
        assert!(
            rode > 6.0,
            "{} went on {rode:.2} m north before holding",
            v["id"]
        );
        held_at.push((a, north_east(&v), after));
    }
    held_at
}

/// Holding: each stops within a few metres of where it held (it was doing 5 m/s), and
/// lands after the lost-action time; the figures of each.
fn landed_after_the_lost_action(
    held_at: &[(&Skein, (f64, f64), f64)],
    killed: Instant,
) -> Vec<Value> {
    let mut times = Vec::new();
    for (a, (n0, e0), held_s) in held_at {
        let v = eventually("a vehicle landing", Duration::from_secs(20), || {
            let v = own_vehicle(a);
            if v["state"] == "Landing" || v["state"] == "Landed" {
                Ok(v)
            } else {
                Err(v.to_string())
            }
        });
        let after = killed.elapsed().as_secs_f64();
        assert!(
            after > RIDE_S.max(TIMEOUT_S) + LOST_ACTION_S - 0.5,
            "{} landed {after:.2} s after the coordinator died, before its lost-action time",
            v["id"]
        );
        let (n, e) = north_east(&v);
        let drift = (n - n0).hypot(e - e0);
        assert!(
            drift < 5.0,
            "{} moved {drift:.2} m while holding: {v}",
            v["id"]
        );
        times.push(
            json!({"vehicle": v["id"], "held_after_s": held_s, "landing_after_s": after,
                          "drift_while_holding_m": drift}),
        );
    }
    times
}

/// Without DDS Security the domain is an open door (what `e2e_dds_security.rs` closes): a
/// CycloneDDS participant (`tests/peers/dds_intruder.py`) outbids the coordinator's lease
/// and, as that rogue coordinator, tells a vehicle to land: the agent obeys at once (long
/// before its coordinator-lost action could land it), and the intruder reads the
/// vehicle's poses and the swarm's reports.
#[test]
fn without_dds_security_a_rogue_participant_lands_a_vehicle() {
    let _one = support::one_at_a_time();
    let d = domain(0);
    let coordinator = ground(&d);
    let agent = agent(1, &d);
    eventually(
        "the coordinator active",
        Duration::from_secs(20),
        || match role(&coordinator).as_str() {
            Some("active") => Ok(()),
            other => Err(format!("{other:?}")),
        },
    );
    coordinator.take_off(1, 8.0);
    let seen = cyclone_intruder(&d, "uav-1", &coordinator, 6.0);
    assert!(seen["matched"]["command"].as_u64() > Some(0), "{seen}");
    assert!(seen["read"]["pose"].as_u64() > Some(0), "{seen}");
    assert!(seen["read"]["report"].as_u64() > Some(0), "{seen}");
    // Landing 1 s after the intruder ended at the latest: the agent's own lost-action
    // would land it only TIMEOUT_S + LOST_ACTION_S (5.5 s) after its last lease.
    eventually("uav-1 landing", Duration::from_secs(1), || {
        let v = own_vehicle(&agent);
        match v["state"].as_str() {
            Some("Landing" | "Landed") => Ok(()),
            other => Err(format!("{other:?}")),
        }
    });
}

/// `skein bench dds --distributed`, small: two vehicles in one process, then two agents
/// and a coordinator, open and then under DDS Security, 3 s each. Every field present,
/// targets heard with a latency in both, and all three flew the line (timing is for the
/// benchmark itself).
#[test]
fn bench_dds_distributed_compares_agents_with_one_process() {
    let _one = support::one_at_a_time();
    // The secured flight takes the next domain, domain(2).
    let d = domain(1);
    let report = bench_report(
        &[
            "dds",
            "--distributed",
            "--vehicles",
            "2",
            "--seconds",
            "3",
            "--domain-id",
            &d,
        ],
        "bench",
        Duration::from_secs(400),
    );
    for mode in ["single_process", "distributed", "distributed_secured"] {
        let rms = &report[mode]["rms_slot_error_m"];
        assert!(rms["samples"].as_u64().unwrap() >= 10, "{report}");
        assert!(
            rms["mean"].as_f64().unwrap() < 0.5,
            "{mode} did not fly the line: {report}"
        );
    }
    for mode in ["distributed", "distributed_secured"] {
        let flight = &report[mode];
        assert!(
            flight["agent_cpu_cores_per_vehicle"].is_number(),
            "{report}"
        );
        assert!(flight["coordinator_cpu_cores"].is_number(), "{report}");
        let lat = &flight["target_latency_ms"];
        assert!(lat["samples"].as_u64().unwrap() > 0, "{mode}: {report}");
        assert!(
            lat["p50"].as_f64().unwrap() <= lat["max"].as_f64().unwrap(),
            "{report}"
        );
    }
    assert!(report["rms_difference_m"].is_number(), "{report}");
    for ratio in ["agent_cpu", "coordinator_cpu", "target_latency_p50"] {
        assert!(
            report["secured_over_open"][ratio]
                .as_f64()
                .is_some_and(|r| r > 0.0),
            "{ratio}: {report}"
        );
    }
}

/// Takeoff, a survey of a 40 x 40 m square by camera (70° across, 30 % overlap: lanes
/// 9.8 m apart at 10 m), landing.
fn survey_plan() -> Value {
    json!({
        "name": "carried survey",
        "steps": [
            {"kind": "takeoff", "altitude_m": 10, "interval_s": 1},
            {"kind": "survey", "polygon": [[15, -10], [15, 30], [55, 30], [55, -10]],
             "altitude_m": 10, "camera": {"hfov_deg": 70, "overlap": 0.3}},
            {"kind": "land", "interval_s": 1}
        ]
    })
}

/// What the test sees of the flight through the standby's API (it follows every remote
/// vehicle's reports, before and after the takeover, in its own swarm frame): each
/// airborne vehicle's positions, and the smallest distance between two vehicles.
#[derive(Default)]
struct Watch {
    samples: Vec<(String, Ned)>,
    min_separation_m: Option<f64>,
}

impl Watch {
    fn sample(&mut self, standby: &Skein) {
        let airborne: Vec<(String, Ned)> = standby
            .vehicles()
            .iter()
            .filter(|v| v["position"]["relative_alt_m"].as_f64() > Some(2.0))
            .filter_map(|v| {
                let p = &v["position"];
                Some((
                    v["id"].as_str()?.to_string(),
                    Ned::new(
                        p["north_m"].as_f64()?,
                        p["east_m"].as_f64()?,
                        -p["relative_alt_m"].as_f64()?,
                    ),
                ))
            })
            .collect();
        for (i, (_, p)) in airborne.iter().enumerate() {
            for (_, q) in &airborne[i + 1..] {
                let d = (*p - *q).norm();
                self.min_separation_m = Some(self.min_separation_m.map_or(d, |m| m.min(d)));
            }
        }
        self.samples.extend(airborne);
    }

    /// The fraction of survey `step` (a plan's step, in the standby's frame) seen at its
    /// planned overlap ([`Coverage`]).
    fn coverage(&self, step: &Value) -> f64 {
        let mut survey = step.clone();
        survey.as_object_mut().unwrap().remove("kind");
        let mut coverage = Coverage::new(&serde_json::from_value(survey).unwrap());
        for (id, p) in &self.samples {
            coverage.sample(id, *p);
        }
        coverage.fraction()
    }
}

/// The survey's progress in mission `m` (`GET /api/v1/missions/{id}`): lanes done, of
/// how many.
fn lanes(m: &Value) -> (u64, u64) {
    let p = &m["steps"][1]["progress"];
    (
        p["lanes_done"].as_u64().unwrap_or(0),
        p["lanes_total"].as_u64().unwrap_or(0),
    )
}

/// A mission survives its coordinator: two candidates and three agents; the active one
/// flies a survey, and is killed (SIGKILL) once a lane is done. The standby takes the
/// role and flies the mission on under the same id, at the same step, from where each
/// vehicle was: the survey is finished with no lane lost (coverage at the planned overlap
/// measured from the vehicles' positions, at least 99 %), the vehicles land, none came
/// within 3 m of another, every PX4 held the fence and none breached it, no simulated
/// PX4 took a failsafe and no setpoint gap in OFFBOARD reached 100 ms.
#[test]
fn a_mission_flies_on_when_its_coordinator_dies_mid_survey() {
    let _one = support::one_at_a_time();
    let d = domain(0);
    let dir = support::plugins::scratch("mission-failover");
    let (mut a, b, agents) = fenced_swarm(&d, &dir);
    wait_roles(&a, &b, Duration::from_secs(30));
    for c in [&a, &b] {
        c.wait_all("homes", 3, Duration::from_secs(60), |v| {
            v["home"].is_object()
        });
    }

    let plan = survey_plan();
    let (status, created) = a.post("/api/v1/missions", plan.clone());
    assert_eq!(status, 201, "{created}");
    let id = created["id"].as_str().unwrap().to_string();
    let path = format!("/api/v1/missions/{id}");
    let (status, started) = a.post(&format!("{path}/start"), json!({}));
    assert_eq!(status, 200, "{started}");

    let mut watch = Watch::default();
    let before = a_lane_and_a_second_more(&a, &b, &path, &mut watch);
    let killed = Instant::now();
    a.kill_hard();
    let resumed = eventually("the mission on gcs-b", Duration::from_secs(10), || {
        watch.sample(&b);
        let (status, m) = b.get(&path);
        if status == 200 && m["state"] == "running" {
            Ok((m, killed.elapsed()))
        } else {
            Err(format!("{status} {m}"))
        }
    });
    let (m, resumed_after) = resumed;
    assert_eq!(m["step"], 1, "the same step: {m}");
    assert!(lanes(&m).0 >= lanes(&before).0, "{before}\n{m}");
    assert_eq!(role(&b), "active");

    let done = eventually(
        "the mission done on gcs-b",
        Duration::from_secs(180),
        || {
            watch.sample(&b);
            let (_, m) = b.get(&path);
            if m["state"] == "done" {
                Ok(m)
            } else {
                Err(
                    json!({"state": m["state"], "step": m["step"], "steps": m["steps"]})
                        .to_string(),
                )
            }
        },
    );
    let (flown, total) = lanes(&done);
    assert_eq!(flown, total, "every lane flown: {done}");
    // The standby's frame may be anchored elsewhere than the killed one's: the plan it
    // flew is in its own.
    let coverage = watch.coverage(&done["plan"]["steps"][1]);
    // Every sampled position, for the failure's post-mortem.
    let samples = dir.join("samples.json");
    let rows: Vec<Value> = watch
        .samples
        .iter()
        .map(|(id, p)| json!([id, p.north_m, p.east_m, -p.down_m]))
        .collect();
    std::fs::write(&samples, json!({"samples": rows, "done": done}).to_string()).unwrap();
    let report = json!({"resumed_after_kill_s": resumed_after.as_secs_f64(),
        "lanes_done_at_kill": lanes(&before).0, "lanes": total, "coverage": coverage,
        "min_separation_m": watch.min_separation_m, "samples": samples,
        "polygon_posted": plan["steps"][1]["polygon"], "polygon_resumed": done["plan"]["steps"][1]["polygon"]});
    eprintln!("{report}");
    assert!(coverage >= 0.99, "{report}");
    assert!(watch.min_separation_m > Some(3.0), "{report}");
    b.wait_all("landed", 3, Duration::from_secs(60), |v| {
        v["state"] == "Landed"
    });
    for agent in &agents {
        assert_no_failsafe_and_no_gap(&agent.sim_stats_addr());
        assert_fence_held(agent);
    }
}

/// The mission failover test's processes: candidates gcs-a (priority 2) and gcs-b and
/// three agents on domain `d`, every one holding [`FENCE`] (each agent uploads it to its
/// PX4, whose own fence check takes GF_ACTION on a breach: a failsafe the test looks
/// for); the coordinators record into `dir`.
fn fenced_swarm(d: &str, dir: &std::path::Path) -> (Skein, Skein, Vec<Skein>) {
    let config = |id: &str| {
        let path = dir.join(format!("{id}.toml"));
        let recordings = dir.join(id);
        std::fs::write(
            &path,
            format!("{FENCE}[recording]\ndir = \"{}\"\n", recordings.display()),
        )
        .unwrap();
        path.display().to_string()
    };
    let (config_a, config_b) = (config("gcs-a"), config("gcs-b"));
    let a = candidate_on(None, "gcs-a", "2", d, None, &["--config", &config_a]);
    let b = candidate_on(None, "gcs-b", "1", d, None, &["--config", &config_b]);
    let fence = dir.join("fence.toml");
    std::fs::write(&fence, FENCE).unwrap();
    let fence = fence.display().to_string();
    let agents: Vec<Skein> = (1..=3)
        .map(|sysid| agent_configured(sysid, d, Some(fence.clone())))
        .collect();
    (a, b, agents)
}

/// Flies mission `path` on `a` until a survey lane is done and the mission has flown a
/// second more (the standby `b` has heard it: the mirror goes at 2 Hz), `watch`
/// sampling `b` all along; returns the mission as it was when the lane was done.
fn a_lane_and_a_second_more(a: &Skein, b: &Skein, path: &str, watch: &mut Watch) -> Value {
    let before = eventually(
        "a lane of the survey done",
        Duration::from_secs(120),
        || {
            watch.sample(b);
            let (_, m) = a.get(path);
            if m["step"] == 1 && lanes(&m).0 >= 1 {
                Ok(m)
            } else {
                Err(
                    json!({"state": m["state"], "step": m["step"], "steps": m["steps"]})
                        .to_string(),
                )
            }
        },
    );
    // The kill comes once the mission has flown a second more: the standby has heard
    // the lane done (the mirror goes at 2 Hz).
    let mirrored_s = before["elapsed_s"].as_f64().unwrap() + 1.0;
    eventually(
        "a second more of the mission",
        Duration::from_secs(10),
        || {
            watch.sample(b);
            let (_, m) = a.get(path);
            let t = m["elapsed_s"].as_f64().unwrap_or(0.0);
            (t >= mirrored_s).then_some(()).ok_or(t.to_string())
        },
    );
    before
}

/// Every vehicle of `agent` held its fence (its PX4 took it) and none breached it.
fn assert_fence_held(agent: &Skein) {
    for v in agent.vehicles() {
        let fence = &v["fence"];
        assert_eq!(fence["state"], "synced", "{v}");
        assert_eq!(fence["breached"], false, "{v}");
    }
}

/// The mission failover test's fence (a configuration file's lines): a circle 80 m
/// round each process's swarm-frame origin (the survey's far corners are 63 m from
/// it), 30 m high.
const FENCE: &str = "[swarm]\ngeofence = { radius_m = 80.0, max_altitude_m = 30.0 }\n";
