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
//!   wedge behind a
//!   virtual leader cruising at 5 m/s, with the steady RMS slot error of single-process
//!   mode (under 0.3 m), never closer than the separation;
//!
//! then the coordinator is killed (SIGKILL) mid-formation, and through each agent's own
//! loopback API:
//!
//! - every vehicle holds (`Hovering`, under offboard control) within 1 s of its agent's
//!   `coordinator_timeout_s` (1.5 s), and stays where it held;
//! - after `coordinator_lost_action_s` (4 s) more it lands (`coordinator_lost_action =
//!   land`);
//! - no simulated PX4 took the offboard-loss failsafe, and no setpoint gap in OFFBOARD
//!   reached 100 ms.
//!
//! Then across hosts: two coordinator candidates (priorities 2 and 1) and the three
//! agents, each in a network namespace of its own on a bridge the test makes (DDS
//! discovery by plain multicast), flown only through the active coordinator's API:
//! killing the active one mid-formation makes the standby active within 2 s, and it
//! flies the formation on from where it was (its mirror on `/skein/formation`), as
//! steady as before, never two closer than the separation; the killed one started again
//! takes the role back by handover, never two active; an agent whose host is cut off
//! the LAN for 5 s holds its vehicle, which the coordinator sees lost, then returns to
//! its slot. No simulated PX4 took the offboard-loss failsafe.

mod support;

use serde_json::{Value, json};
use std::time::{Duration, Instant};
use support::bench::bench_report;
use support::netns::{Host, Lan};
use support::{EventLog, Skein, assert_no_failsafe_and_no_gap, eventually, steady_for, summary};

/// DDS domain `k` (0 to 2) of this test process's own, apart from `e2e_dds`' 100–219
/// and `e2e_failover`'s 220–231.
fn domain(k: u32) -> String {
    (20 + (std::process::id() % 26) * 3 + k).to_string()
}

/// Seconds without a coordinator before an agent holds, and then before it lands.
const TIMEOUT_S: f64 = 1.5;
const LOST_ACTION_S: f64 = 4.0;

fn agent(sysid: u8, d: &str) -> Skein {
    agent_on(None, sysid, d, "land", LOST_ACTION_S)
}

/// An agent with one simulated vehicle (sysid `sysid`), on loopback (`host` `None`) or on
/// a host of a [`Lan`] (its DDS and its simulator's stats socket on the host's address;
/// its own API stays on the host's loopback).
fn agent_on(
    host: Option<&Host>,
    sysid: u8,
    d: &str,
    lost_action: &str,
    lost_action_s: f64,
) -> Skein {
    let first = sysid.to_string();
    let id = format!("agent-{sysid}");
    let (timeout, action) = (TIMEOUT_S.to_string(), lost_action_s.to_string());
    let network = host.map_or("127.0.0.1".to_string(), |h| h.addr.to_string());
    let stats = format!("{network}:0");
    Skein::launch_in(
        host.map(|h| h.ns.as_str()),
        "agent",
        &[
            "--sim",
            "1",
            "--first-sysid",
            &first,
            "--sim-base-port",
            "0",
            "--sim-stats",
            &stats,
            "--id",
            &id,
            "--domain-id",
            d,
            "--dds-network",
            &network,
            "--coordinator-timeout-s",
            &timeout,
            "--coordinator-lost-action",
            lost_action,
            "--coordinator-lost-action-s",
            &action,
        ],
    )
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

/// Speed of the formation's reference point, m/s.
fn reference_speed(f: &Value) -> f64 {
    let v = &f["reference"]["velocity"];
    v["north_m"]
        .as_f64()
        .unwrap_or(0.0)
        .hypot(v["east_m"].as_f64().unwrap_or(0.0))
}

/// Waits until the formation of `c` cruises at 5 m/s (its reference at speed for 2 s,
/// past catching up with the acceleration), then samples it for 5 s at speed; asserts the
/// steady RMS slot error of single-process mode and the separation; returns (mean RMS,
/// worst RMS, smallest separation), metres.
fn cruise(c: &Skein) -> (f64, f64, f64) {
    let at_speed = |f: &Value| {
        let speed = reference_speed(f);
        if speed > 4.99 {
            Ok(())
        } else {
            Err(format!("{speed:.2} m/s: {f}"))
        }
    };
    steady_for(
        "the reference at 5 m/s",
        Duration::from_secs(2),
        Duration::from_secs(40),
        || at_speed(&c.formation()),
    );
    let samples = steady_for(
        "the wedge cruising at 5 m/s",
        Duration::from_secs(5),
        Duration::from_secs(20),
        || {
            let f = c.formation();
            at_speed(&f)?;
            Ok((
                f["rms_error_m"].as_f64().unwrap_or(f64::INFINITY),
                f["min_separation_m"].as_f64().unwrap_or(0.0),
            ))
        },
    );
    let rms: Vec<f64> = samples.iter().map(|(r, _)| *r).collect();
    let min_sep = samples.iter().map(|(_, s)| *s).fold(f64::MAX, f64::min);
    assert!(rms.len() > 10, "{rms:?}");
    let mean = rms.iter().sum::<f64>() / rms.len() as f64;
    let worst = rms.iter().copied().fold(0.0, f64::max);
    // Single-process mode measures 0.15-0.19 m (e2e_formation).
    assert!(mean < 0.3, "steady RMS slot error {mean:.2} m: {rms:?}");
    assert!(worst < 1.0, "RMS slot error reached {worst:.2} m: {rms:?}");
    assert!(min_sep > 3.0, "two members came within {min_sep:.2} m");
    (mean, worst, min_sep)
}

/// Waits until the members of the formation of `c` are back on their slots (RMS slot
/// error under 0.5 m) after a change of coordinator: the agents moved their last targets
/// on by their age for at most 500 ms, then held them, and the new coordinator resumed
/// the reference there, at rest, to accelerate it again. Asserts the separation
/// meanwhile; returns (worst RMS, when back, smallest separation).
fn catch_up(c: &Skein) -> (f64, Instant, f64) {
    let (mut worst, mut min_sep) = (0.0f64, f64::MAX);
    let back = eventually(
        "the members back on their slots",
        Duration::from_secs(30),
        || {
            let f = c.formation();
            let rms = f["rms_error_m"].as_f64().unwrap_or(f64::INFINITY);
            worst = worst.max(rms);
            min_sep = min_sep.min(f["min_separation_m"].as_f64().unwrap_or(0.0));
            if rms < 0.5 {
                Ok(Instant::now())
            } else {
                Err(f.to_string())
            }
        },
    );
    assert!(min_sep > 3.0, "two members came within {min_sep:.2} m");
    (worst, back, min_sep)
}

/// Takes the swarm of `c` off, forms a wedge behind a virtual leader and sends it north
/// at 5 m/s.
fn wedge_north(c: &Skein) {
    c.take_off(3, 10.0);
    let (status, body) = c.put(
        "/api/v1/formation",
        json!({"shape": "wedge", "spacing_m": 6.0, "leader": "virtual", "altitude_m": 12.0}),
    );
    assert_eq!(status, 200, "{body}");
    c.settled(3, 1.0, Duration::from_secs(60));
    let (status, body) = c.post(
        "/api/v1/formation/leader/goto",
        json!({"north_m": 400.0, "east_m": 0.0, "speed_m_s": 5.0}),
    );
    assert_eq!(status, 200, "{body}");
}

fn role(c: &Skein) -> Value {
    let (_, s) = c.get("/api/v1/coordinator");
    s["role"].clone()
}

#[test]
fn agents_fly_for_the_coordinator_and_hold_then_land_without_it() {
    let _one = support::one_at_a_time();
    let d = domain(0);
    let mut coordinator = Skein::coordinator(&[
        "--id",
        "ground",
        "--priority",
        "2",
        "--domain-id",
        &d,
        "--dds-network",
        "127.0.0.1",
    ]);
    let agents: Vec<Skein> = (1..=3).map(|sysid| agent(sysid, &d)).collect();
    eventually("the coordinator active", Duration::from_secs(20), || {
        let r = role(&coordinator);
        if r == "active" {
            Ok(())
        } else {
            Err(r.to_string())
        }
    });

    // Each agent spawned its vehicle at its own grid point (sysid - 1, 4 columns): the
    // coordinator, whose frame is the first agent's, sees them apart, none at another's.
    coordinator.wait_all("homes", 3, Duration::from_secs(60), |v| {
        v["home"].is_object()
    });
    let vs = coordinator.vehicles();
    let ids: Vec<&str> = vs.iter().filter_map(|v| v["id"].as_str()).collect();
    assert_eq!(ids, ["uav-1", "uav-2", "uav-3"], "{}", summary(&vs));
    for (i, a) in vs.iter().enumerate() {
        for b in &vs[i + 1..] {
            let ((an, ae), (bn, be)) = (north_east(a), north_east(b));
            let d = (an - bn).hypot(ae - be);
            assert!(d > 3.0, "{} and {} are {d:.2} m apart", a["id"], b["id"]);
        }
    }

    let events = EventLog::connect(&coordinator.base);
    wedge_north(&coordinator);
    // The vehicles' own events (on their agents) reach the coordinator's stream.
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
    let (mean_rms, worst_rms, min_sep) = cruise(&coordinator);
    for a in &agents {
        assert_eq!(own_vehicle(a)["state"], "InFormation", "{}", own_vehicle(a));
    }

    // The coordinator dies with no goodbye.
    let killed = Instant::now();
    coordinator.kill_hard();
    let mut held_at = Vec::new();
    for a in &agents {
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
            after < TIMEOUT_S + 1.0,
            "{} held {after:.2} s after the coordinator died",
            v["id"]
        );
        assert_eq!(v["px4_mode"], "OFFBOARD", "{v}");
        held_at.push((a, north_east(&v), after));
    }
    // Holding: each stops within a few metres of where it held (it was doing 5 m/s), and
    // lands after the lost-action time.
    let mut times = Vec::new();
    for (a, (n0, e0), held_s) in &held_at {
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
            after > TIMEOUT_S + LOST_ACTION_S - 0.5,
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
               "min_separation_m": min_sep, "after_the_coordinator_died": times})
    );
}

/// A coordinator candidate on a host of a [`Lan`], its API on the host's address (no
/// tokens on this private LAN: `--insecure-no-auth`).
fn candidate_on(h: &Host, id: &str, priority: &str, d: &str) -> Skein {
    let http = format!("{}:0", h.addr);
    let network = h.addr.to_string();
    Skein::launch_in(
        Some(&h.ns),
        "coordinator",
        &[
            "--http",
            &http,
            "--id",
            id,
            "--priority",
            priority,
            "--domain-id",
            d,
            "--dds-network",
            &network,
            "--insecure-no-auth",
        ],
    )
}

/// The vehicle `id` as coordinator `c` shows it.
fn vehicle(c: &Skein, id: &str) -> Value {
    c.vehicles()
        .into_iter()
        .find(|v| v["id"] == id)
        .unwrap_or(Value::Null)
}

#[test]
fn across_hosts_a_standby_flies_the_formation_on_and_a_cut_off_agent_returns() {
    let _one = support::one_at_a_time();
    // Hosts 0 and 1: the coordinators; 2, 3, 4: the agents of uav-1, uav-2, uav-3.
    let lan = Lan::new('d', 5);
    let d = domain(1);
    let mut gcs_a = candidate_on(&lan.hosts[0], "gcs-a", "2", &d);
    let gcs_b = candidate_on(&lan.hosts[1], "gcs-b", "1", &d);
    // Agents that only hold without a coordinator, so that what flies is the
    // coordinators' doing.
    let agents: Vec<Skein> = (1..=3u8)
        .map(|k| agent_on(Some(&lan.hosts[1 + usize::from(k)]), k, &d, "hold", 60.0))
        .collect();
    eventually(
        "gcs-a active, gcs-b standby",
        Duration::from_secs(30),
        || {
            let (a, b) = (role(&gcs_a), role(&gcs_b));
            if a == "active" && b == "standby" {
                Ok(())
            } else {
                Err(format!("{a} {b}"))
            }
        },
    );
    wedge_north(&gcs_a);
    cruise(&gcs_a);
    let (_, writes) = gcs_b.put("/api/v1/formation", json!({"shape": "line"}));
    assert!(writes.to_string().contains("gcs-a"), "{writes}");

    // The active coordinator dies: the standby flies the formation on.
    let before = gcs_a.formation()["reference"]["position"]["north_m"]
        .as_f64()
        .unwrap();
    let killed = Instant::now();
    gcs_a.kill_hard();
    let took = eventually("gcs-b active", Duration::from_secs(10), || {
        if role(&gcs_b) == "active" {
            Ok(killed.elapsed())
        } else {
            Err(role(&gcs_b).to_string())
        }
    });
    assert!(
        took < Duration::from_secs(2),
        "gcs-b took {took:?} to take over"
    );
    let resumed = eventually("the formation resumed", Duration::from_secs(10), || {
        let f = gcs_b.formation();
        let north = f["reference"]["position"]["north_m"]
            .as_f64()
            .unwrap_or(0.0);
        let members = f["members"].as_array().map_or(0, Vec::len);
        if f["active"] == true && f["shape"] == "wedge" && members == 3 && north > before {
            Ok(killed.elapsed())
        } else {
            Err(f.to_string())
        }
    });
    let (worst_catch_up, back, mut min_sep) = catch_up(&gcs_b);
    let (steady_rms, _, sep) = cruise(&gcs_b);
    min_sep = min_sep.min(sep);

    // gcs-a returns: it takes the role back only by handover, never two active.
    let gcs_a = candidate_on(&lan.hosts[0], "gcs-a", "2", &d);
    eventually("gcs-a active again", Duration::from_secs(30), || {
        let (a, b) = (role(&gcs_a), role(&gcs_b));
        assert!(!(a == "active" && b == "active"), "two active coordinators");
        if a == "active" && b == "standby" {
            Ok(())
        } else {
            Err(format!("{a} {b}"))
        }
    });
    let (_, _, sep) = catch_up(&gcs_a);
    min_sep = min_sep.min(sep);

    // uav-1's host loses its link for 5 s: its agent holds it, the coordinator sees it
    // lost; back on the LAN, it returns to its slot.
    let cut = Instant::now();
    lan.cut(2);
    eventually("uav-1 lost to gcs-a", Duration::from_secs(10), || {
        let v = vehicle(&gcs_a, "uav-1");
        if v["state"] == "Lost" {
            Ok(())
        } else {
            Err(v.to_string())
        }
    });
    eventually("5 s cut off", Duration::from_secs(10), || {
        if cut.elapsed() >= Duration::from_secs(5) {
            Ok(())
        } else {
            Err(format!("{:?}", cut.elapsed()))
        }
    });
    lan.heal(2);
    let healed = Instant::now();
    let returned = eventually("uav-1 back on its slot", Duration::from_secs(60), || {
        let f = gcs_a.formation();
        min_sep = min_sep.min(f["min_separation_m"].as_f64().unwrap_or(f64::MAX));
        let error = f["members"].as_array().and_then(|m| {
            m.iter()
                .find(|m| m["id"] == "uav-1")
                .and_then(|m| m["error_m"].as_f64())
        });
        match error {
            Some(e) if e < 0.5 => Ok(healed.elapsed()),
            _ => Err(f.to_string()),
        }
    });
    assert!(min_sep > 3.0, "two members came within {min_sep:.2} m");
    let log = agents[0].process.stderr_text();
    assert!(
        log.contains("holding uav-1"),
        "agent-1 did not hold uav-1:\n{log}"
    );

    let mut worst_gap = 0.0f64;
    for a in &agents {
        worst_gap = worst_gap.max(assert_no_failsafe_and_no_gap(&a.sim_stats_addr()));
    }
    eprintln!(
        "{}",
        json!({"failover_s": took.as_secs_f64(), "resumed_after_s": resumed.as_secs_f64(),
               "worst_rms_catching_up_m": worst_catch_up,
               "back_on_slots_after_s": (back - killed).as_secs_f64(),
               "steady_rms_after_failover_m": steady_rms,
               "cut_off_agent_back_on_its_slot_after_s": returned.as_secs_f64(),
               "min_separation_m": min_sep, "worst_setpoint_gap_ms": worst_gap})
    );
}

/// `skein bench dds --distributed`, small: two vehicles in one process, then two agents
/// and a coordinator, 3 s each. Every field present, targets heard with a latency, and
/// both flew the line (timing is for the benchmark itself).
#[test]
fn bench_dds_distributed_compares_agents_with_one_process() {
    let _one = support::one_at_a_time();
    let d = domain(2);
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
    for mode in ["single_process", "distributed"] {
        let rms = &report[mode]["rms_slot_error_m"];
        assert!(rms["samples"].as_u64().unwrap() >= 10, "{report}");
        assert!(
            rms["mean"].as_f64().unwrap() < 0.5,
            "{mode} did not fly the line: {report}"
        );
    }
    assert!(
        report["distributed"]["agent_cpu_cores_per_vehicle"].is_number(),
        "{report}"
    );
    assert!(
        report["distributed"]["coordinator_cpu_cores"].is_number(),
        "{report}"
    );
    assert!(report["rms_difference_m"].is_number(), "{report}");
    let lat = &report["target_latency_ms"];
    assert!(lat["samples"].as_u64().unwrap() > 0, "{report}");
    assert!(
        lat["p50"].as_f64().unwrap() <= lat["max"].as_f64().unwrap(),
        "{report}"
    );
}
