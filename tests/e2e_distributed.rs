//! Distributed skein on one machine: one `skein coordinator` and three `skein agent`s
//! (one simulated vehicle each, sysids 1 to 3), each its own process, on DDS over
//! loopback (`--dds-network 127.0.0.1`, a domain of this test process's own). Only
//! through the coordinator's HTTP API:
//!
//! - the agents' vehicles join the coordinator as remote vehicles, at the places their
//!   simulators spawned them (each agent's swarm frame converted into the
//!   coordinator's);
//! - the swarm takes off (every vehicle acknowledges over DDS), flies a wedge behind a
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

mod support;

use serde_json::{Value, json};
use std::time::{Duration, Instant};
use support::{Skein, assert_no_failsafe_and_no_gap, eventually, summary};

/// A DDS domain of this test process's own, apart from `e2e_dds`' 100–219 and
/// `e2e_failover`'s 220–231.
fn domain() -> String {
    (20 + std::process::id() % 80).to_string()
}

/// Seconds without a coordinator before an agent holds, and then before it lands.
const TIMEOUT_S: f64 = 1.5;
const LOST_ACTION_S: f64 = 4.0;

fn agent(sysid: u8, d: &str) -> Skein {
    let first = sysid.to_string();
    let id = format!("agent-{sysid}");
    let (timeout, action) = (TIMEOUT_S.to_string(), LOST_ACTION_S.to_string());
    Skein::launch_in(
        None,
        "agent",
        &[
            "--sim",
            "1",
            "--first-sysid",
            &first,
            "--sim-base-port",
            "0",
            "--sim-stats",
            "127.0.0.1:0",
            "--id",
            &id,
            "--domain-id",
            d,
            "--dds-network",
            "127.0.0.1",
            "--coordinator-timeout-s",
            &timeout,
            "--coordinator-lost-action",
            "land",
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

#[test]
fn agents_fly_for_the_coordinator_and_hold_then_land_without_it() {
    let _one = support::one_at_a_time();
    let d = domain();
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
        let (_, s) = coordinator.get("/api/v1/coordinator");
        if s["role"] == "active" {
            Ok(())
        } else {
            Err(s.to_string())
        }
    });

    // Each agent spawned its vehicle at its own grid point (sysid - 1, 4 columns): the
    // coordinator, whose frame is the first agent's, sees them apart, none at another's.
    coordinator.take_off(3, 10.0);
    let vs = coordinator.vehicles();
    let ids: Vec<&str> = vs.iter().filter_map(|v| v["id"].as_str()).collect();
    assert_eq!(ids, ["uav-1", "uav-2", "uav-3"], "{}", summary(&vs));
    for (i, a) in vs.iter().enumerate() {
        for b in &vs[i + 1..] {
            let ((an, ae), (bn, be)) = (north_east(a), north_east(b));
            let d = (an - bn).hypot(ae - be);
            assert!(d > 3.0, "{} and {} hover {d:.2} m apart", a["id"], b["id"]);
        }
    }

    let (status, body) = coordinator.put(
        "/api/v1/formation",
        json!({"shape": "wedge", "spacing_m": 6.0, "leader": "virtual", "altitude_m": 12.0}),
    );
    assert_eq!(status, 200, "{body}");
    coordinator.settled(3, 1.0, Duration::from_secs(60));
    let (status, body) = coordinator.post(
        "/api/v1/formation/leader/goto",
        json!({"north_m": 400.0, "east_m": 0.0, "speed_m_s": 5.0}),
    );
    assert_eq!(status, 200, "{body}");
    // Cruising at 5 m/s (the reference at speed for 2 s, past the catching up with the
    // acceleration), then for 5 s every member on its slot, apart.
    let cruising = || {
        let f = coordinator.formation();
        let v = &f["reference"]["velocity"];
        v["north_m"]
            .as_f64()
            .unwrap_or(0.0)
            .hypot(v["east_m"].as_f64().unwrap_or(0.0))
    };
    eventually("the reference at 5 m/s", Duration::from_secs(40), || {
        let speed = cruising();
        if speed > 4.99 {
            Ok(())
        } else {
            Err(format!("{speed:.2} m/s"))
        }
    });
    let at_speed = Instant::now();
    while at_speed.elapsed() < Duration::from_secs(2) {
        std::thread::sleep(Duration::from_millis(100));
    }
    let mut rms = Vec::new();
    let mut min_sep = f64::MAX;
    let steady = Instant::now();
    while steady.elapsed() < Duration::from_secs(5) {
        let f = coordinator.formation();
        rms.push(f["rms_error_m"].as_f64().unwrap_or(f64::INFINITY));
        min_sep = min_sep.min(f["min_separation_m"].as_f64().unwrap_or(0.0));
        std::thread::sleep(Duration::from_millis(100));
    }
    assert!(rms.len() > 10, "{rms:?}");
    assert!(
        cruising() > 4.99,
        "the wedge slowed down: {}",
        coordinator.formation()
    );
    let mean_rms = rms.iter().sum::<f64>() / rms.len() as f64;
    let worst_rms = rms.iter().copied().fold(0.0, f64::max);
    // Single-process mode measures 0.15-0.19 m (e2e_formation).
    assert!(
        mean_rms < 0.3,
        "steady RMS slot error {mean_rms:.2} m: {rms:?}"
    );
    assert!(
        worst_rms < 1.0,
        "RMS slot error reached {worst_rms:.2} m: {rms:?}"
    );
    assert!(min_sep > 3.0, "two members came within {min_sep:.2} m");
    for a in &agents {
        assert_eq!(own_vehicle(a)["state"], "InFormation", "{}", own_vehicle(a));
    }

    // The coordinator dies with no goodbye.
    let killed = Instant::now();
    let status = std::process::Command::new("kill")
        .args(["-KILL", &coordinator.process.pid().to_string()])
        .status()
        .expect("kill");
    assert!(status.success());
    coordinator.process.wait_exit(Duration::from_secs(10));
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
