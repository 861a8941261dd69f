//! Supervision from the outside: a simulated swarm of 4 flies a line formation while
//! faults are injected into a Vehicle actor, a Px4Link actor, the API actor and a payload
//! actor (panic, then hang). Every restart is visible in the supervision tree, on the
//! stream and in the metrics; the simulator sees no offboard-loss failsafe and no
//! setpoint gap of 100 ms; the formation is back within 1 m in 5 s. Budgets that run out
//! escalate as configured.

mod support;

use serde_json::{Value, json};
use std::time::{Duration, Instant};
use support::{EventLog, Process, Skein, eventually, one_at_a_time, sim_stats, skein_bin, summary};

const CONFIG: &str = r#"
[supervision]
watchdog_period_ms = 200
watchdog_deadline_ms = 1000
vehicle = { max_restarts = 5, window_s = 300.0, backoff_initial_ms = 50, backoff_max_ms = 200 }
px4link = { max_restarts = 5, window_s = 300.0, backoff_initial_ms = 50, backoff_max_ms = 200 }
api = { max_restarts = 5, window_s = 300.0, backoff_initial_ms = 50, backoff_max_ms = 200 }
payload = { max_restarts = 5, window_s = 300.0, backoff_initial_ms = 50, backoff_max_ms = 200 }

[models.tester]
payloads = [{ slot = "fixture", kind = "fault-fixture" }]
"#;

const TIGHT_BUDGETS: &str = r#"
[supervision]
watchdog_deadline_ms = 1000
vehicle_escalation = "hold"
vehicle = { max_restarts = 1, window_s = 300.0 }
payload = { max_restarts = 1, window_s = 300.0 }

[models.tester]
payloads = [{ slot = "fixture", kind = "fault-fixture" }]
"#;

fn config_file(name: &str, text: &str) -> String {
    let dir = std::env::temp_dir().join(format!("skein-sup-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("skein.toml");
    std::fs::write(&path, text).unwrap();
    path.to_str().unwrap().to_string()
}

fn start(n: usize, config: &str, name: &str) -> Skein {
    let cfg = config_file(name, config);
    let n = n.to_string();
    Skein::up(&[
        "--sim",
        &n,
        "--sim-base-port",
        "0",
        "--sim-model",
        "tester",
        "--sim-stats",
        "127.0.0.1:0",
        "--enable-fault-injection",
        "--config",
        &cfg,
    ])
}

/// Waits until every member is within 1 m of its slot; returns how long it took.
fn formation_settled(skein: &Skein, n: usize, within: Duration) -> Duration {
    let t0 = Instant::now();
    eventually("formation within 1 m", within, || {
        let (_, f) = skein.get("/api/v1/formation");
        let members = f["members"].as_array().cloned().unwrap_or_default();
        let ok = members.len() == n
            && members
                .iter()
                .all(|m| m["error_m"].as_f64().is_some_and(|e| e < 1.0));
        if ok {
            Ok(())
        } else {
            Err(format!("{f} | {}", summary(&skein.vehicles())))
        }
    });
    t0.elapsed()
}

#[test]
fn every_kind_of_actor_recovers_from_panics_and_hangs_while_the_swarm_flies() {
    let _serial = one_at_a_time();
    let skein = start(4, CONFIG, "recover");
    let stats = skein.sim_stats_addr();
    skein.take_off(4, 10.0);
    let (status, body) = skein.put(
        "/api/v1/formation",
        json!({"shape": "line", "spacing_m": 7.0, "leader": "uav-1"}),
    );
    assert_eq!(status, 200, "{body}");
    formation_settled(&skein, 4, Duration::from_secs(60));
    let events = EventLog::connect(&skein.base);
    // Counters from here on only.
    assert_eq!(sim_stats(&stats, "reset")["ok"], true);

    let targets = [
        "coordinator/uav-2",
        "coordinator/uav-3/px4link",
        "coordinator/api",
        "coordinator/uav-4/payload/fixture",
    ];
    let mut report = Vec::new();
    for target in targets {
        for kind in ["panic", "hang"] {
            let before = skein.restarts(target);
            let t0 = Instant::now();
            // The API restarting may cut this very request: the tree says what happened.
            if let Some((status, body)) =
                skein.try_post("/api/v1/faults", json!({"target": target, "kind": kind}))
            {
                assert_eq!(status, 202, "{target} {kind}: {body}");
            }
            let rec = eventually(
                &format!("{target} restarted after {kind}"),
                Duration::from_secs(20),
                || match skein.supervised(target) {
                    Some(r)
                        if r["restarts"].as_u64() == Some(before + 1)
                            && r["status"] == "running" =>
                    {
                        Ok(r)
                    }
                    other => Err(format!("{other:?}")),
                },
            );
            let recovered = t0.elapsed();
            let reason = rec["last_failure"]["reason"]
                .as_str()
                .unwrap_or_default()
                .to_string();
            match kind {
                "panic" => assert!(reason.contains("injected panic"), "{target}: {reason}"),
                _ => assert!(reason.starts_with("hung"), "{target}: {reason}"),
            }
            let settled = formation_settled(&skein, 4, Duration::from_secs(5));
            report.push(json!({
                "target": target, "kind": kind,
                "restarted_after_ms": recovered.as_millis() as u64,
                "restart_latency_us": rec["last_restart_latency_us"],
                "formation_back_after_ms": settled.as_millis() as u64,
            }));
        }
    }
    // The control step is no actor: a direct call on the process's control clock. Its
    // panic fails its vehicle, which is restarted and flies its slot again.
    let before = skein.restarts("coordinator/uav-2");
    let (status, body) = skein.post(
        "/api/v1/faults",
        json!({"target": "coordinator/uav-2/control", "kind": "panic"}),
    );
    assert_eq!(status, 202, "{body}");
    let rec = eventually(
        "uav-2 restarted after its control step panicked",
        Duration::from_secs(20),
        || match skein.supervised("coordinator/uav-2") {
            Some(r) if r["restarts"].as_u64() == Some(before + 1) && r["status"] == "running" => {
                Ok(r)
            }
            other => Err(format!("{other:?}")),
        },
    );
    let reason = rec["last_failure"]["reason"].as_str().unwrap_or_default();
    assert!(
        reason.contains("control step") && reason.contains("injected panic"),
        "{reason}"
    );
    let settled = formation_settled(&skein, 4, Duration::from_secs(5));
    report.push(json!({
        "target": "coordinator/uav-2/control", "kind": "panic",
        "restart_latency_us": rec["last_restart_latency_us"],
        "formation_back_after_ms": settled.as_millis() as u64,
    }));
    // A hang there would hold up every vehicle's control: refused, naming why.
    let (status, body) = skein.post(
        "/api/v1/faults",
        json!({"target": "coordinator/uav-2/control", "kind": "hang"}),
    );
    assert_eq!(status, 404, "{body}");
    assert!(body.to_string().contains("takes only `panic`"), "{body}");
    let worst_gap = skein.assert_no_failsafe_and_no_gap(&stats);
    eprintln!(
        "{}",
        json!({"restarts": report, "largest_setpoint_gap_ms": worst_gap})
    );
    // Restarts went out on the stream.
    let restarted = eventually("actor_restarted events", Duration::from_secs(10), || {
        let ev = events.of_type("actor_restarted");
        if ev.len() >= targets.len() * 2 - 2 {
            Ok(ev)
        } else {
            Err(format!("{} so far", ev.len()))
        }
    });
    assert!(
        restarted
            .iter()
            .any(|e| e["path"] == "coordinator/uav-3/px4link")
    );
    assert!(!events.of_type("actor_failed").is_empty());
    // …and in the metrics, per actor kind.
    let agent: ureq::Agent = ureq::Agent::config_builder()
        .http_status_as_error(false)
        .build()
        .into();
    let text = agent
        .get(format!("{}/metrics", skein.base))
        .call()
        .unwrap()
        .body_mut()
        .read_to_string()
        .unwrap();
    // The vehicle's third restart is its control step's panic.
    for (kind, restarts) in [("vehicle", 3), ("px4link", 2), ("api", 2), ("payload", 2)] {
        assert!(
            text.contains(&format!(
                "skein_actor_restarts_total{{kind=\"{kind}\"}} {restarts}"
            )),
            "{kind}: {text}"
        );
        assert!(
            text.contains(&format!("skein_actor_hangs_total{{kind=\"{kind}\"}} 1")),
            "{kind}: {text}"
        );
    }
    // Still flying, still in formation, still commandable.
    let vs = skein.vehicles();
    assert!(
        vs.iter().all(|v| v["state"] == "InFormation"),
        "{}",
        summary(&vs)
    );
    let (status, body) = skein.post("/api/v1/swarm/commands", json!({"command": "land"}));
    assert_eq!(status, 202, "{body}");
}

#[test]
fn spent_budgets_escalate_a_payload_is_disabled_and_a_vehicle_is_held() {
    let _serial = one_at_a_time();
    let skein = start(2, TIGHT_BUDGETS, "escalate");
    let stats = skein.sim_stats_addr();
    skein.take_off(2, 8.0);
    assert_eq!(sim_stats(&stats, "reset")["ok"], true);

    // A payload failing faster than its budget (1 restart): disabled, the vehicle flies on.
    let payload = "coordinator/uav-1/payload/fixture";
    for n in 0..2u64 {
        // The fixture panics on its own command too (the plugin path, not only faults).
        // Right after a restart the API may still see the payload restarting and refuse
        // the command (409) before it reaches the payload: ask again until it panics.
        eventually("payload failure recorded", Duration::from_secs(10), || {
            let r = skein.supervised(payload).unwrap();
            let want = if n == 0 { "running" } else { "failed" };
            if r["failures"].as_u64() > Some(n) && r["status"] == want {
                return Ok(());
            }
            if r["failures"].as_u64() <= Some(n) {
                let (status, _) = skein.post(
                    "/api/v1/vehicles/uav-1/payloads/fixture",
                    json!({"action": "panic"}),
                );
                assert!(status >= 400, "a panicking payload answers an error");
            }
            Err(r.to_string())
        });
    }
    // Vehicle snapshots are published at 10 Hz: poll until this one shows it.
    let v = eventually(
        "the snapshot shows the payload failed",
        Duration::from_secs(5),
        || {
            let (_, v) = skein.get("/api/v1/vehicles/uav-1");
            if v["payloads"][0]["status"] == "failed" {
                Ok(v)
            } else {
                Err(v.to_string())
            }
        },
    );
    assert_eq!(v["state"], "Hovering", "{v}");
    let (status, body) = skein.post(
        "/api/v1/vehicles/uav-1/payloads/fixture",
        json!({"action": "echo"}),
    );
    assert_eq!(
        (status, body["field"].as_str()),
        (409, Some("slot")),
        "a disabled payload is refused: {body}"
    );

    // A Vehicle actor failing faster than its budget: commanded HOLD through a
    // safe-mode link, marked failed. The CLI form of fault injection does the second.
    let (status, body) = skein.post(
        "/api/v1/faults",
        json!({"target": "coordinator/uav-2", "kind": "panic"}),
    );
    assert_eq!(status, 202, "{body}");
    eventually("uav-2 restarted once", Duration::from_secs(10), || {
        let r = skein.supervised("coordinator/uav-2").unwrap();
        if r["restarts"] == 1 && r["status"] == "running" {
            Ok(())
        } else {
            Err(r.to_string())
        }
    });
    let mut cli = Process::start(&[
        "fault",
        "--url",
        &skein.base,
        "--target",
        "coordinator/uav-2",
        "--kind",
        "error",
    ]);
    assert_eq!(
        cli.wait_exit(Duration::from_secs(30)),
        Some(0),
        "{}",
        cli.stderr_text()
    );
    eventually("uav-2 escalated", Duration::from_secs(15), || {
        let r = skein.supervised("coordinator/uav-2").unwrap();
        if r["status"] == "failed" {
            Ok(())
        } else {
            Err(r.to_string())
        }
    });
    eventually("uav-2 in PX4 HOLD", Duration::from_secs(15), || {
        let s = sim_stats(&stats, "stats");
        let v = &s["vehicles"][1];
        if v["truth"]["mode_name"] == "HOLD" {
            Ok(())
        } else {
            Err(v["truth"].to_string())
        }
    });
    let (status, body) = skein.post(
        "/api/v1/vehicles/uav-2/commands",
        json!({"command": "land"}),
    );
    assert_eq!(status, 409, "{body}");
    assert!(body["error"].as_str().unwrap().contains("failed"), "{body}");
    // Escalating a vehicle never let PX4's offboard failsafe fire.
    let s = sim_stats(&stats, "stats");
    for v in s["vehicles"].as_array().unwrap() {
        assert_eq!(v["offboard_loss_failsafes"], 0, "{v}");
    }
    // uav-1 still flies under skein's control.
    let (_, v) = skein.get("/api/v1/vehicles/uav-1");
    assert_eq!(v["state"], "Hovering", "{v}");
}

#[test]
fn fault_injection_is_off_by_default_and_unknown_targets_are_named() {
    let _serial = one_at_a_time();
    let off = Skein::sim(1);
    let (status, body) = off.post(
        "/api/v1/faults",
        json!({"target": "coordinator/uav-1", "kind": "panic"}),
    );
    assert_eq!(status, 403, "{body}");
    assert!(
        body["error"]
            .as_str()
            .unwrap()
            .contains("--enable-fault-injection"),
        "{body}"
    );

    let on = start(1, CONFIG, "unknown");
    on.wait_all("connected", 1, Duration::from_secs(30), |v| {
        v["link"]["connected"] == true
    });
    for target in [
        "coordinator/uav-9",
        "coordinator/uav-1/gimbal",
        "coordinator/nope/px4link",
        "elsewhere",
    ] {
        let (status, body) = on.post("/api/v1/faults", json!({"target": target, "kind": "panic"}));
        assert_eq!(status, 404, "{target}: {body}");
        assert_eq!(body["field"], "target");
        assert!(body["error"].as_str().unwrap().contains(target), "{body}");
    }
    let (status, body) = on.post(
        "/api/v1/faults",
        json!({"target": "coordinator/uav-1", "kind": "explode"}),
    );
    assert_eq!(
        (status, body["field"].as_str()),
        (400, Some("kind")),
        "{body}"
    );
    // The tree shows the whole actor hierarchy.
    let (_, tree) = on.get("/api/v1/supervision");
    let names: Vec<&str> = tree["children"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["api", "uav-1"], "{tree}");
    let uav: &Value = &tree["children"][1];
    let kids: Vec<&str> = uav["children"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["name"].as_str().unwrap())
        .collect();
    assert_eq!(kids, ["payload/fixture", "px4link"], "{tree}");
    assert_eq!(uav["kind"], "vehicle");
    assert_eq!(uav["status"], "running");
}

#[test]
fn a_failed_coordinator_exits_non_zero_for_the_outer_supervisor() {
    let _serial = one_at_a_time();
    let mut skein = start(1, CONFIG, "exit");
    // The 202, or no answer at all: the panic may end the process before the answer
    // leaves it (CI saw "Peer disconnected"); the exit code says what happened.
    let answer = skein.try_post(
        "/api/v1/faults",
        json!({"target": "coordinator", "kind": "panic"}),
    );
    if let Some((status, body)) = answer {
        assert_eq!(status, 202, "{body}");
    }
    let code = skein.process.wait_exit(Duration::from_secs(30));
    assert_eq!(code, Some(70), "{}", skein.process.stderr_text());
    let _ = skein_bin();
}
