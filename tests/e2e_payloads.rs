//! Payload plugins on a running swarm, from the outside: the plugin cdylibs are built with
//! cargo and dropped into a plugin directory, `skein up --sim 3 --plugin-dir DIR` loads
//! them with real `dlopen` (and `skein plugin-host` children for process isolation), and
//! everything is checked over HTTP and the simulator's stats socket while the vehicles
//! hover: the default model mix, the gimbal's rate-limited pitch, a camera snapshot, the
//! plugin listing, an ABI-mismatch refusal, a panicking, a hanging and an aborting plugin
//! (restarted, the vehicles fly on with no setpoint gap of 100 ms and no offboard-loss
//! failsafe), a hot reload of a rebuilt library, and the radio degrading a vehicle's link.
//!
//! One `skein up` serves every check (they run in order in one test). Plugins loaded at
//! run time, waiting slots and payloads attached in flight: `e2e_dynamic_payloads.rs`.

mod support;

use serde_json::{Value, json};
use std::path::Path;
use std::time::{Duration, Instant};
use support::payloads::{jpeg_size, library, payload, plugins, write_config};
use support::plugins::{build_into, scratch};
use support::{Skein, eventually, one_at_a_time, sim_stats, summary};

const PACKAGES: [&str; 6] = [
    "skein-plugin-example",
    "skein-plugin-gimbal",
    "skein-plugin-camera",
    "skein-plugin-radio",
    "skein-plugin-fault",
    "skein-plugin-abi-mismatch",
];

/// The observation model gets a small camera and a radio; the generic one carries the
/// example plugin and two fault fixtures (in-process and process-isolated), so the default
/// mix of `--sim 3` (uav-2 observation, uav-1 and uav-3 generic) exercises every plugin.
/// The example is never ticked (`rate_hz = 0`): after a reload only skein's reaction to
/// the reload, not a failing call, can move it to the new build.
const CONFIG: &str = r#"
[supervision]
watchdog_period_ms = 200
watchdog_deadline_ms = 1000
payload = { max_restarts = 10, window_s = 300.0, backoff_initial_ms = 50, backoff_max_ms = 200 }

[models.observation]
payloads = [
    { slot = "gimbal", kind = "gimbal", config = { max_rate_deg_s = 30.0 } },
    { slot = "camera", kind = "camera", config = { width_px = 320, height_px = 240, frame_rate_hz = 2.0 } },
    { slot = "radio", kind = "radio" },
]

[models.generic]
payloads = [
    { slot = "example", kind = "example", config = { rate_hz = 0.0 } },
    { slot = "fault", kind = "fault" },
    { slot = "fault_proc", kind = "fault", isolation = "process" },
]
"#;

/// The first stdout line of `skein` containing `needle` (printed before the dashboard
/// line, so already there).
fn stdout_line(skein: &Skein, needle: &str) -> String {
    let out = skein.process.stdout.lock().unwrap();
    out.iter()
        .find(|l| l.contains(needle))
        .cloned()
        .unwrap_or_else(|| panic!("no stdout line with `{needle}`: {out:?}"))
}

/// Waits until the payload at `path` has been restarted past `before` and runs again.
fn restarted(skein: &Skein, path: &str, before: u64, what: &str) -> Value {
    eventually(what, Duration::from_secs(20), || {
        match skein.supervised(path) {
            Some(r) if r["restarts"].as_u64() > Some(before) && r["status"] == "running" => Ok(r),
            other => Err(format!("{other:?}")),
        }
    })
}

/// The MAVLink datagrams skein received on `port` (one simulated vehicle's link).
fn datagrams(skein: &Skein, port: &str) -> u64 {
    let (status, links) = skein.get("/api/v1/links");
    assert_eq!(status, 200, "{links}");
    links
        .as_array()
        .unwrap()
        .iter()
        .find(|l| {
            l["local_addr"]
                .as_str()
                .is_some_and(|a| a.ends_with(&format!(":{port}")))
        })
        .unwrap_or_else(|| panic!("no link on port {port}: {links}"))["decode"]["datagrams"]
        .as_u64()
        .unwrap()
}

/// Datagrams per second on `port`, over the time it takes to receive `count` of them
/// (polled, with a deadline of 30 s).
fn datagram_rate(skein: &Skein, port: &str, count: u64) -> f64 {
    let t0 = Instant::now();
    let d0 = datagrams(skein, port);
    eventually(
        &format!("{count} datagrams on port {port}"),
        Duration::from_secs(30),
        || {
            let d = datagrams(skein, port) - d0;
            if d >= count {
                Ok(d as f64 / t0.elapsed().as_secs_f64())
            } else {
                Err(format!("{d} so far"))
            }
        },
    )
}

#[test]
fn payload_plugins_reach_the_running_swarm() {
    let _serial = one_at_a_time();
    let t_start = Instant::now();
    let dir = scratch("plugins");
    build_into(&PACKAGES, &[], &dir);
    let t_built = t_start.elapsed();
    let cfg_dir = scratch("config");
    let cfg = write_config(&cfg_dir, CONFIG);
    let skein = Skein::up_sim(
        3,
        &["--plugin-dir", dir.to_str().unwrap(), "--config", &cfg],
    );
    let skein = &skein;
    let plugin_line = stdout_line(skein, "skein: plugins from");
    assert!(
        plugin_line.contains("5 loaded") && plugin_line.contains("1 refused"),
        "{plugin_line}"
    );
    let ports_line = stdout_line(skein, "simulated vehicles, MAVLink links");
    let ports: Vec<String> = ports_line
        .rsplit(' ')
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    assert_eq!(ports.len(), 3, "{ports_line}");
    let stats = skein.sim_stats_addr();
    skein.take_off(3, 8.0);
    let t_flying = t_start.elapsed();

    every_payload_runs(skein);
    the_listing_and_its_refusals(skein);
    let reached = gimbal_at_its_rate(skein);
    camera_snapshot(skein);
    let worst_faults = faults_restart_only_their_payload(skein, &stats);
    let (worst_reload, reload_took) = reload_replaces_the_example(skein, &stats, &dir);
    let (radio, sim_v, before_rate, after_rate) = radio_drops_the_link(skein, &stats, &ports);

    eprintln!(
        "{}",
        json!({
            "built_s": t_built.as_secs_f64(),
            "flying_after_s": t_flying.as_secs_f64(),
            "gimbal_reached_s": reached.as_secs_f64(),
            "worst_setpoint_gap_faults_ms": worst_faults,
            "worst_setpoint_gap_reload_ms": worst_reload,
            "reload_to_running_ms": reload_took.as_millis() as u64,
            "radio": radio["state"],
            "sim_link": {"loss": sim_v["link_loss_fraction"], "dropped": sim_v["datagrams_dropped_link"]},
            "datagrams_per_s": [before_rate, after_rate],
            "total_s": t_start.elapsed().as_secs_f64(),
        })
    );
}

/// The default model mix, and every payload instance running.
fn every_payload_runs(skein: &Skein) {
    // The default mix: every other vehicle is an observation UAV.
    let vs = skein.vehicles();
    let models: Vec<&str> = vs.iter().map(|v| v["model"].as_str().unwrap()).collect();
    assert_eq!(models, ["generic", "observation", "generic"], "{vs:?}");

    // Every payload instance runs.
    eventually("all payloads running", Duration::from_secs(20), || {
        let vs = skein.vehicles();
        let bad: Vec<String> = vs
            .iter()
            .flat_map(|v| {
                let id = v["id"].as_str().unwrap_or("?").to_string();
                v["payloads"]
                    .as_array()
                    .cloned()
                    .unwrap_or_default()
                    .into_iter()
                    // The fault fixture and an unticked example publish no state.
                    .filter(|p| {
                        p["status"] != "running"
                            || (p["kind"] != "fault"
                                && p["kind"] != "example"
                                && p["state"].is_null())
                    })
                    .map(move |p| format!("{id}/{}: {}", p["slot"], p["status"]))
            })
            .collect();
        if bad.is_empty() {
            Ok(())
        } else {
            Err(bad.join(", "))
        }
    });
}

/// The plugin listing (five plugins, the built-in provider, the refused fixture), and
/// bad loads and unloads refused naming the field.
fn the_listing_and_its_refusals(skein: &Skein) {
    // The listing: five plugins, the built-in provider, the refused fixture.
    let listing = plugins(skein);
    for name in ["example", "gimbal", "camera", "radio", "fault"] {
        let lib = library(&listing, name).unwrap_or_else(|| panic!("{name}: {listing}"));
        assert_eq!(lib["generation"], 1, "{lib}");
    }
    assert_ne!(
        library(&listing, "example").unwrap()["version"],
        "9.9.9",
        "the default build runs first"
    );
    let gimbal = library(&listing, "gimbal").unwrap();
    let inst = &gimbal["instances"].as_array().unwrap();
    assert_eq!(inst.len(), 1, "{gimbal}");
    assert_eq!(inst[0]["vehicle_id"], "uav-2");
    assert_eq!(inst[0]["slot"], "gimbal");
    assert_eq!(inst[0]["status"], "running");
    let fault = library(&listing, "fault").unwrap();
    assert_eq!(fault["instances"].as_array().unwrap().len(), 4, "{fault}");
    assert!(
        listing["providers"]
            .as_array()
            .unwrap()
            .iter()
            .any(|p| p["source"] == "builtin" && p["kinds"][0] == "fault-fixture"),
        "{listing}"
    );
    let refused = listing["refused"].as_array().unwrap();
    assert!(
        refused.iter().any(|r| {
            r["file"]
                .as_str()
                .is_some_and(|f| f.ends_with("libskein_plugin_abi_mismatch.so"))
                && r["reason"]
                    .as_str()
                    .is_some_and(|s| s.contains("ABI version mismatch"))
        }),
        "{listing}"
    );

    // (d) Loading the ABI-mismatch fixture is refused naming the file and the difference.
    let (status, body) = skein.post(
        "/api/v1/plugins/load",
        json!({"file": "libskein_plugin_abi_mismatch.so"}),
    );
    assert_eq!(status, 422, "{body}");
    assert_eq!(body["field"], "file", "{body}");
    let error = body["error"].as_str().unwrap();
    assert!(
        error.contains("libskein_plugin_abi_mismatch.so")
            && error.contains("ABI version mismatch")
            && error.contains("999"),
        "{error}"
    );
    let (status, body) = skein.post("/api/v1/plugins/load", json!({"file": "../../etc/x.so"}));
    assert!((400..500).contains(&status), "{status} {body}");
    assert_eq!(body["field"], "file", "{body}");
    let (status, body) = skein.post("/api/v1/plugins/load", json!({"fil": "x.so"}));
    assert_eq!((status, &body["field"]), (400, &json!("fil")), "{body}");
    let (status, body) = skein.post("/api/v1/plugins/load", json!({"file": 3}));
    assert_eq!((status, &body["field"]), (400, &json!("file")), "{body}");
    // Unload is refused while instances live, naming them; an unknown name is a 404.
    let (status, body) = skein.post("/api/v1/plugins/unload", json!({"name": "gimbal"}));
    assert_eq!(status, 409, "{body}");
    assert_eq!(body["field"], "name", "{body}");
    assert!(
        body["error"].as_str().unwrap().contains("uav-2/gimbal"),
        "{body}"
    );
    let (status, body) = skein.post("/api/v1/plugins/unload", json!({"name": "nope"}));
    assert_eq!((status, &body["field"]), (404, &json!("name")), "{body}");
    let (status, _) = skein.get("/api/v1/health");
    assert_eq!(status, 200, "skein keeps running after the refusals");
}

/// uav-2's gimbal pitched to -45° no faster than its rate; how long it took.
fn gimbal_at_its_rate(skein: &Skein) -> Duration {
    // (a) Gimbal: pitch -45° is reached no sooner than its 30 °/s rate allows (1.5 s).
    let start_pitch = payload(skein, "uav-2", "gimbal")["state"]["pitch_deg"]
        .as_f64()
        .unwrap();
    let t0 = Instant::now();
    let (status, body) = skein.post(
        "/api/v1/vehicles/uav-2/payloads/gimbal",
        json!({"command": "set_angles", "pitch_deg": -45.0, "yaw_deg": 0.0}),
    );
    assert_eq!(status, 200, "{body}");
    let mut seen_between = false;
    let reached = eventually("gimbal pitch at -45°", Duration::from_secs(15), || {
        let p = payload(skein, "uav-2", "gimbal")["state"]["pitch_deg"]
            .as_f64()
            .unwrap_or(f64::NAN);
        if p < start_pitch - 5.0 && p > -40.0 {
            seen_between = true;
        }
        if (p + 45.0).abs() < 0.5 {
            Ok(t0.elapsed())
        } else {
            Err(format!("pitch {p}"))
        }
    });
    let min_time = (start_pitch + 45.0).abs() / 30.0;
    assert!(
        reached.as_secs_f64() >= min_time - 0.1,
        "pitch reached in {reached:?}, faster than 30 °/s allows ({min_time:.2} s)"
    );
    assert!(
        reached.as_secs_f64() < min_time + 5.0,
        "pitch took {reached:?}"
    );
    assert!(seen_between, "the pitch moved through intermediate angles");

    reached
}

/// uav-2's camera snapshot, a JPEG of the configured size; none on a generic vehicle.
fn camera_snapshot(skein: &Skein) {
    // (b) Camera: the snapshot is a JPEG of the configured size.
    let frame = eventually("a camera frame", Duration::from_secs(10), || {
        let (status, ctype, body) =
            skein.get_bytes("/api/v1/vehicles/uav-2/payloads/camera/snapshot");
        if status == 200 {
            Ok((ctype, body))
        } else {
            Err(format!("{status}: {}", String::from_utf8_lossy(&body)))
        }
    });
    assert_eq!(frame.0, "image/jpeg");
    assert_eq!(jpeg_size(&frame.1), (320, 240));
    let (status, _, _) = skein.get_bytes("/api/v1/vehicles/uav-1/payloads/camera/snapshot");
    assert_eq!(status, 404, "a generic vehicle has no camera");
}

/// In-process and process-isolated plugins that panic, hang or abort: only their
/// payload restarts. The worst setpoint gap meanwhile, ms.
fn faults_restart_only_their_payload(skein: &Skein, stats: &str) -> f64 {
    // (e) An in-process plugin that panics: its payload is restarted, nothing else moves.
    assert_eq!(sim_stats(stats, "reset")["ok"], true);
    let path = "coordinator/uav-1/payload/fault";
    let before = skein.restarts(path);
    let (status, body) = skein.post(
        "/api/v1/vehicles/uav-1/payloads/fault",
        json!({"command": "panic"}),
    );
    assert!((400..600).contains(&status), "{status} {body}");
    assert!(body["error"].as_str().unwrap().contains("panic"), "{body}");
    let rec = restarted(
        skein,
        path,
        before,
        "fault payload restarted after its panic",
    );
    assert!(
        rec["last_failure"]["reason"]
            .as_str()
            .is_some_and(|r| r.contains("panic")),
        "{rec}"
    );

    // An in-process plugin that hangs: the call deadline gives its thread up, the payload
    // is restarted, and no tokio worker was held (the setpoint streams never paused).
    let path3 = "coordinator/uav-3/payload/fault";
    let before = skein.restarts(path3);
    let (status, body) = skein.post(
        "/api/v1/vehicles/uav-3/payloads/fault",
        json!({"command": "hang"}),
    );
    assert!(status >= 500, "{status} {body}");
    let rec = restarted(skein, path3, before, "hung fault payload restarted");
    let reason = rec["last_failure"]["reason"].as_str().unwrap_or_default();
    assert!(
        reason.contains("did not return within") && reason.contains("abandoned"),
        "{rec}"
    );
    // The abandoned thread is counted at /metrics.
    let (status, _, text) = skein.get_bytes("/metrics");
    let text = String::from_utf8_lossy(&text);
    let abandoned = text
        .lines()
        .find_map(|l| l.strip_prefix("skein_payload_driver_threads_abandoned "))
        .and_then(|v| v.trim().parse::<u64>().ok());
    assert!(
        status == 200 && abandoned.is_some_and(|n| n >= 1),
        "{status}: {text}"
    );
    process_isolated_abort(skein);
    skein.assert_no_failsafe_and_no_gap(stats)
}

/// A process-isolated plugin that aborts: only its child dies, the payload restarts
/// with a new child, skein and the vehicles fly on.
fn process_isolated_abort(skein: &Skein) {
    let pid_of = |listing: &Value| -> Option<u64> {
        library(listing, "fault")?["instances"]
            .as_array()?
            .iter()
            .find(|i| i["vehicle_id"] == "uav-1" && i["slot"] == "fault_proc")?["pid"]
            .as_u64()
    };
    let old_pid = pid_of(&plugins(skein)).expect("a child pid for uav-1/fault_proc");
    let path = "coordinator/uav-1/payload/fault_proc";
    let before = skein.restarts(path);
    let (status, body) = skein.post(
        "/api/v1/vehicles/uav-1/payloads/fault_proc",
        json!({"command": "abort"}),
    );
    assert!((400..600).contains(&status), "{status} {body}");
    assert!(
        body["error"].as_str().unwrap().contains("SIGABRT"),
        "{body}"
    );
    restarted(skein, path, before, "process-isolated payload restarted");
    let new_pid = eventually("a new child", Duration::from_secs(10), || {
        match pid_of(&plugins(skein)) {
            Some(p) if p != old_pid => Ok(p),
            other => Err(format!("{other:?}")),
        }
    });
    assert!(
        !Path::new(&format!("/proc/{old_pid}")).exists()
            || std::fs::read_to_string(format!("/proc/{old_pid}/stat"))
                .is_ok_and(|s| s.contains(") Z ")),
        "the aborted child {old_pid} is gone"
    );
    assert_ne!(new_pid, u64::from(skein.process.pid()));
    let (status, _) = skein.get("/api/v1/health");
    assert_eq!(status, 200, "skein is alive");
    let vs = skein.vehicles();
    assert!(
        vs.iter().all(|v| v["state"] == "Hovering"),
        "{}",
        summary(&vs)
    );
}

/// The example plugin rebuilt and reloaded while the vehicles fly: the worst setpoint
/// gap meanwhile (ms) and how long the reload took.
fn reload_replaces_the_example(skein: &Skein, stats: &str, dir: &Path) -> (f64, Duration) {
    // (g) Reload: a rebuilt example plugin replaces the old one; its instances come back
    // on the new generation, the vehicles fly on.
    assert_eq!(sim_stats(stats, "reset")["ok"], true);
    build_into(
        &["skein-plugin-example"],
        &[("SKEIN_EXAMPLE_VERSION", "9.9.9")],
        dir,
    );
    let t0 = Instant::now();
    let (status, body) = skein.post("/api/v1/plugins/reload", json!({"name": "example"}));
    assert_eq!(status, 200, "{body}");
    assert_eq!(body["library"]["version"], "9.9.9", "{body}");
    assert_eq!(body["library"]["generation"], 2, "{body}");
    assert_eq!(
        body["stale_instances"].as_array().unwrap().len(),
        2,
        "{body}"
    );
    let lib = eventually(
        "example instances on generation 2",
        Duration::from_secs(10),
        || {
            let l = plugins(skein);
            let Some(lib) = library(&l, "example") else {
                return Err(l.to_string());
            };
            let old_left = l["libraries"]
                .as_array()
                .unwrap()
                .iter()
                .any(|x| x["name"] == "example" && x["status"] == "superseded");
            let inst = lib["instances"].as_array().cloned().unwrap_or_default();
            if !old_left
                && inst.len() == 2
                && inst
                    .iter()
                    .all(|i| i["generation"] == 2 && i["status"] == "running")
            {
                Ok(lib)
            } else {
                Err(l.to_string())
            }
        },
    );
    let reload_took = t0.elapsed();
    assert_eq!(lib["version"], "9.9.9");
    for v in ["uav-1", "uav-3"] {
        let (status, body) = skein.post(
            &format!("/api/v1/vehicles/{v}/payloads/example"),
            json!({"command": "ping"}),
        );
        assert_eq!(status, 200, "{body}");
        assert_eq!(body["version"], "9.9.9", "{v}: {body}");
        let rec = skein
            .supervised(&format!("coordinator/{v}/payload/example"))
            .unwrap();
        assert_eq!(rec["restarts"], 0, "a reload is not a failure: {rec}");
    }
    let vs = skein.vehicles();
    assert!(
        vs.iter().all(|v| v["state"] == "Hovering"),
        "{}",
        summary(&vs)
    );
    let worst_reload = skein.assert_no_failsafe_and_no_gap(stats);

    (worst_reload, reload_took)
}

/// A poor link on uav-2's radio drops its MAVLink traffic in the simulator: the radio's
/// payload, the simulator's vehicle, the datagram rates before and after.
fn radio_drops_the_link(skein: &Skein, stats: &str, ports: &[String]) -> (Value, Value, f64, f64) {
    // (c) Radio: a poor link commanded on uav-2 really drops its MAVLink traffic.
    let before_rate = datagram_rate(skein, &ports[1], 200);
    let (status, body) = skein.post(
        "/api/v1/vehicles/uav-2/payloads/radio",
        json!({"command": "override", "loss_fraction": 0.6, "latency_ms": 50.0}),
    );
    assert_eq!(status, 200, "{body}");
    let radio = eventually(
        "radio state shows the loss",
        Duration::from_secs(10),
        || {
            let p = payload(skein, "uav-2", "radio");
            let loss = p["state"]["loss_percent"].as_f64().unwrap_or(0.0);
            if loss > 50.0 && p["state"]["applied_to_simulator"] == true {
                Ok(p)
            } else {
                Err(p.to_string())
            }
        },
    );
    let sim_v = eventually(
        "the simulator drops uav-2's datagrams",
        Duration::from_secs(10),
        || {
            let s = sim_stats(stats, "stats");
            let v = s["vehicles"]
                .as_array()
                .unwrap()
                .iter()
                .find(|v| v["sysid"] == 2)
                .cloned()
                .unwrap();
            if v["link_loss_fraction"].as_f64() > Some(0.5)
                && v["datagrams_dropped_link"].as_u64() > Some(10)
            {
                Ok(v)
            } else {
                Err(v.to_string())
            }
        },
    );
    let after_rate = datagram_rate(skein, &ports[1], 100);
    assert!(
        after_rate < 0.7 * before_rate,
        "uav-2's telemetry rate fell from {before_rate:.0}/s to {after_rate:.0}/s only"
    );
    let (status, body) = skein.post(
        "/api/v1/vehicles/uav-2/payloads/radio",
        json!({"command": "clear_override"}),
    );
    assert_eq!(status, 200, "{body}");

    (radio, sim_v, before_rate, after_rate)
}
