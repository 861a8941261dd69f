//! Dynamic payloads from the outside: `skein up --sim 2` with a model whose payload kind
//! no plugin provides at start; the slots wait; a plugin crate made by `skein plugin
//! new` is built, dropped into the plugin directory and loaded through the API; payloads
//! are attached to a flying vehicle and detached again; an unload with force sends the
//! slots back to waiting.

mod support;

use serde_json::{Value, json};
use std::time::{Duration, Instant};
use support::payloads::{library, payload, plugins, try_payload, write_config};
use support::plugins::{build_new_plugin, scratch};
use support::{Skein, eventually, one_at_a_time, sim_stats, summary};

/// The lamp model of the dynamic-payloads test: one slot of a kind no plugin provides
/// at start. A small payload restart budget: waiting must not spend it.
const LAMP_CONFIG: &str = r#"
[supervision]
payload = { max_restarts = 2, window_s = 300.0, backoff_initial_ms = 50, backoff_max_ms = 100 }

[models.lampy]
payloads = [{ slot = "lamp", kind = "lamp", config = { rate_hz = 5.0 } }]
"#;

/// Waits until `vehicle` no longer lists a payload in `slot` (the listing follows the
/// vehicle's snapshot, published at 10 Hz).
fn gone(skein: &Skein, vehicle: &str, slot: &str) {
    eventually(
        &format!("{vehicle}/{slot} unlisted"),
        Duration::from_secs(2),
        || match try_payload(skein, vehicle, slot) {
            Ok(p) => Err(p.to_string()),
            Err(_) => Ok(()),
        },
    );
}

/// The payload in `slot` of each of `vehicles`, once `pred` holds for all of them.
fn all_payloads(
    skein: &Skein,
    vehicles: &[&str],
    slot: &str,
    what: &str,
    timeout: Duration,
    pred: impl Fn(&Value) -> bool,
) -> Vec<Value> {
    eventually(what, timeout, || {
        let ps: Vec<Value> = vehicles
            .iter()
            .map(|v| try_payload(skein, v, slot))
            .collect::<Result<_, _>>()?;
        if ps.iter().all(&pred) {
            Ok(ps)
        } else {
            Err(json!(ps).to_string())
        }
    })
}

/// A swarm whose model asks for a payload kind no plugin provides: the slots wait (no
/// restart budget spent); a plugin crate made by `skein plugin new`, built and dropped
/// into the plugin directory, is loaded through the API and both vehicles' slots run and
/// answer within a second; a slot is attached to a flying vehicle and detached again
/// (refusals naming the field); an unload with force sends the slots back to waiting.
/// The simulator sees no setpoint gap of 100 ms and no failsafe throughout.
#[test]
fn a_plugin_loaded_at_run_time_reaches_waiting_slots_and_payloads_attach_in_flight() {
    let _serial = one_at_a_time();
    let t_start = Instant::now();
    let plugin_dir = scratch("dynamic-plugins");
    let crate_dir = scratch("dynamic-crate").join("lamp");
    let built = build_new_plugin(support::skein_bin(), "lamp", "lamp", &crate_dir);
    let t_built = t_start.elapsed();
    let cfg_dir = scratch("dynamic-config");
    let cfg = write_config(&cfg_dir, LAMP_CONFIG);
    let skein = Skein::up(&[
        "--sim",
        "2",
        "--sim-base-port",
        "0",
        "--sim-stats",
        "127.0.0.1:0",
        "--sim-model",
        "lampy",
        "--plugin-dir",
        plugin_dir.to_str().unwrap(),
        "--config",
        &cfg,
    ]);
    let stats = skein.sim_stats_addr();
    let events = support::EventLog::connect(&skein.base);
    let warned = eventually("the missing-kind warning", Duration::from_secs(5), || {
        let text = skein.process.stderr_text();
        if text.contains("payload kind `lamp`") && text.contains("wait for one") {
            Ok(text)
        } else {
            Err(text)
        }
    });
    assert_eq!(warned.matches("provides payload kind `lamp`").count(), 1);
    skein.take_off(2, 8.0);
    assert_eq!(sim_stats(&stats, "reset")["ok"], true);
    let uavs = ["uav-1", "uav-2"];

    // The slots wait, naming the kind, and spend no restart budget.
    let waiting = |p: &Value| {
        p["status"] == "waiting_for_plugin"
            && p["waiting_for"]
                .as_str()
                .is_some_and(|w| w.contains("kind `lamp`"))
            && p["plugin"].is_null()
    };
    all_payloads(
        &skein,
        &uavs,
        "lamp",
        "lamp slots waiting",
        Duration::from_secs(10),
        waiting,
    );
    for v in uavs {
        assert_eq!(skein.restarts(&format!("coordinator/{v}/payload/lamp")), 0);
    }
    let (status, body) = skein.post(
        "/api/v1/vehicles/uav-1/payloads/lamp",
        json!({"command": "ping"}),
    );
    // Not running: a state of the payload, refused naming the slot (and why).
    assert_eq!(
        (status, body["field"].as_str()),
        (409, Some("slot")),
        "{body}"
    );
    assert!(
        body["error"].as_str().unwrap().contains("kind `lamp`"),
        "{body}"
    );
    // Attaching a kind nobody provides is refused naming the field.
    let (status, body) = skein.post(
        "/api/v1/vehicles/uav-1/payloads",
        json!({"slot": "lamp2", "kind": "lamp"}),
    );
    assert_eq!((status, &body["field"]), (400, &json!("kind")), "{body}");

    // Drop the library in and load it: both slots run and answer within a second.
    let file = support::plugins::lib_file("lamp");
    std::fs::copy(&built, plugin_dir.join(&file)).unwrap();
    let t0 = Instant::now();
    let (status, body) = skein.post("/api/v1/plugins/load", json!({"file": file}));
    assert_eq!(status, 200, "{body}");
    assert_eq!(body["kinds"], json!(["lamp"]), "{body}");
    let mut answered = vec![];
    eventually("both lamps answer", Duration::from_secs(1), || {
        for v in uavs {
            if answered.contains(&v) {
                continue;
            }
            let (status, body) = skein.post(
                &format!("/api/v1/vehicles/{v}/payloads/lamp"),
                json!({"command": "ping"}),
            );
            if status != 200 {
                return Err(format!("{v}: {status} {body}"));
            }
            assert_eq!((&body["pong"], &body["vehicle"]), (&json!(true), &json!(v)));
            answered.push(v);
        }
        Ok(())
    });
    let load_to_answer = t0.elapsed();
    let running = all_payloads(
        &skein,
        &uavs,
        "lamp",
        "lamps listed running",
        Duration::from_secs(5),
        |p| p["status"] == "running" && p["plugin"] == "lamp" && p["generation"] == 1,
    );
    assert!(
        running.iter().all(|p| p["waiting_for"].is_null()),
        "{running:?}"
    );
    for v in uavs {
        assert_eq!(skein.restarts(&format!("coordinator/{v}/payload/lamp")), 0);
    }
    let (status, body) = skein.post(
        "/api/v1/vehicles/uav-2/payloads/lamp",
        json!({"command": "set", "value": 2.5}),
    );
    assert_eq!((status, &body["value"]), (200, &json!(2.5)), "{body}");

    // Attach a second lamp to a flying uav-1, refusals naming the field first.
    let attach = |body: Value| skein.post("/api/v1/vehicles/uav-1/payloads", body);
    for (body, status, field) in [
        (json!({"slot": "lamp", "kind": "lamp"}), 409, "slot"),
        (json!({"slot": "lamp2", "kind": "laser"}), 400, "kind"),
        (
            json!({"slot": "lamp2", "kind": "lamp", "plugin": "nope"}),
            400,
            "plugin",
        ),
        (
            json!({"slot": "lamp2", "kind": "lamp", "config": {"colour": 1}}),
            400,
            "config",
        ),
        (
            json!({"slot": "lamp2", "kind": "lamp", "colour": 1}),
            400,
            "colour",
        ),
        (
            json!({"slot": "lamp2", "kind": "lamp", "isolation": "thread"}),
            400,
            "isolation",
        ),
    ] {
        let (s, b) = attach(body.clone());
        assert_eq!((s, &b["field"]), (status, &json!(field)), "{body}: {b}");
    }
    let (status, _) = skein.post(
        "/api/v1/vehicles/uav-9/payloads",
        json!({"slot": "x", "kind": "lamp"}),
    );
    assert_eq!(status, 404);
    // The refused config left no slot behind.
    gone(&skein, "uav-1", "lamp2");
    let (status, body) = attach(json!({
        "slot": "lamp2", "kind": "lamp", "plugin": "lamp", "config": {"value": 1.5, "rate_hz": 0.0}
    }));
    assert_eq!(status, 201, "{body}");
    assert_eq!(
        (&body["slot"], &body["plugin"], &body["status"]),
        (&json!("lamp2"), &json!("lamp"), &json!("running")),
        "{body}"
    );
    let (status, body) = skein.post(
        "/api/v1/vehicles/uav-1/payloads/lamp2",
        json!({"command": "status"}),
    );
    assert_eq!((status, &body["value"]), (200, &json!(1.5)), "{body}");
    let listed = payload(&skein, "uav-1", "lamp2");
    assert_eq!(listed["generation"], 1, "{listed}");
    // Detach it: its shutdown runs (the template raises an event), then it is gone from
    // the listing and the supervision tree; commands find no slot.
    let (status, body) = skein.delete("/api/v1/vehicles/uav-1/payloads/lamp2");
    assert_eq!(
        (status, &body["detached"]),
        (200, &json!("lamp2")),
        "{body}"
    );
    eventually("lamp2's shutdown event", Duration::from_secs(2), || {
        let ev = events.of_type("payload_event");
        ev.iter()
            .find(|e| e["slot"] == "lamp2" && e["data"]["shutdown"] == true)
            .cloned()
            .ok_or_else(|| json!(ev).to_string())
    });
    gone(&skein, "uav-1", "lamp2");
    assert!(
        skein
            .supervised("coordinator/uav-1/payload/lamp2")
            .is_none()
    );
    let (status, _) = skein.post(
        "/api/v1/vehicles/uav-1/payloads/lamp2",
        json!({"command": "status"}),
    );
    assert_eq!(status, 404);
    let (status, _) = skein.delete("/api/v1/vehicles/uav-1/payloads/lamp2");
    assert_eq!(status, 404);
    let lib = library(&plugins(&skein), "lamp").unwrap();
    assert_eq!(lib["instances"].as_array().unwrap().len(), 2, "{lib}");

    // Unload: refused while instances live; with force, they stop and the slots wait.
    let (status, body) = skein.post("/api/v1/plugins/unload", json!({"name": "lamp"}));
    assert_eq!((status, &body["field"]), (409, &json!("name")), "{body}");
    assert!(body["error"].as_str().unwrap().contains("force"), "{body}");
    let t1 = Instant::now();
    let (status, body) = skein.post(
        "/api/v1/plugins/unload",
        json!({"name": "lamp", "force": true}),
    );
    assert_eq!(status, 200, "{body}");
    assert_eq!(
        body["stopped_instances"].as_array().map(Vec::len),
        Some(2),
        "{body}"
    );
    assert_eq!(body["still_stopping"], json!([]), "{body}");
    let unload_took = t1.elapsed();
    all_payloads(
        &skein,
        &uavs,
        "lamp",
        "lamp slots waiting again",
        Duration::from_secs(5),
        waiting,
    );
    assert!(library(&plugins(&skein), "lamp").is_none());
    for v in uavs {
        assert_eq!(skein.restarts(&format!("coordinator/{v}/payload/lamp")), 0);
    }

    let vs = skein.vehicles();
    assert!(
        vs.iter().all(|v| v["state"] == "Hovering"),
        "{}",
        summary(&vs)
    );
    let worst = skein.assert_no_failsafe_and_no_gap(&stats);
    assert!(
        load_to_answer < Duration::from_secs(1),
        "load to both lamps answering took {load_to_answer:?}"
    );
    eprintln!(
        "{}",
        json!({
            "built_s": t_built.as_secs_f64(),
            "load_to_both_answering_ms": load_to_answer.as_millis() as u64,
            "forced_unload_ms": unload_took.as_millis() as u64,
            "worst_setpoint_gap_ms": worst,
            "total_s": t_start.elapsed().as_secs_f64(),
        })
    );
}
