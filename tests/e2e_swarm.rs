//! End to end, from the outside: `skein up --sim 3` as a process on free ports, driven
//! through the HTTP API only (and its UDP link ports for the malformed-input check).

mod support;

use serde_json::{Value, json};
use std::time::Duration;
use support::{
    EventLog, Process, Skein, eventually, free_udp_range, run_peer, sim_stats, steady_for, summary,
};

fn alt(v: &Value) -> f64 {
    v["position"]["relative_alt_m"].as_f64().unwrap_or(f64::NAN)
}

fn ned(v: &Value) -> (f64, f64, f64) {
    let p = &v["position"];
    (
        p["north_m"].as_f64().unwrap(),
        p["east_m"].as_f64().unwrap(),
        p["down_m"].as_f64().unwrap(),
    )
}

/// `id` lands, then holds half-way: PX4 leaves LAND for OFFBOARD and the vehicle hovers
/// (and rejoins its formation), never taken for a failsafe while the mode changes.
fn a_landing_is_broken_off_by_a_hold(skein: &Skein, id: &str) {
    let path = format!("/api/v1/vehicles/{id}/commands");
    let (status, body) = skein.post(&path, json!({"command": "land"}));
    assert_eq!(status, 202, "{body}");
    let one = || {
        skein
            .vehicles()
            .into_iter()
            .find(|v| v["id"] == id)
            .expect("the vehicle")
    };
    let from_m = eventually("landing", Duration::from_secs(10), || {
        let v = one();
        if v["state"] == "Landing" {
            Ok(alt(&v))
        } else {
            Err(v.to_string())
        }
    });
    eventually("on its way down", Duration::from_secs(20), || {
        let v = one();
        if alt(&v) < from_m - 1.0 {
            Ok(())
        } else {
            Err(v.to_string())
        }
    });
    let (status, body) = skein.post(&path, json!({"command": "hold"}));
    assert_eq!(status, 202, "{body}");
    steady_for(
        "hovering after the hold",
        Duration::from_secs(2),
        Duration::from_secs(20),
        || {
            let v = one();
            assert_ne!(v["state"], "Failsafe", "{v}");
            // (Back in its slot: the formation flown before takes in a hovering vehicle.)
            if (v["state"] == "Hovering" || v["state"] == "InFormation") && alt(&v) > 2.0 {
                Ok(())
            } else {
                Err(v.to_string())
            }
        },
    );
}

#[test]
fn three_vehicles_take_off_fly_a_line_and_land() {
    // Logs come home by themselves after landing, all three under one cap.
    let dir = tempfile::tempdir().unwrap();
    let config = support::payloads::write_config(
        dir.path(),
        &format!("[logs]\nfetch_after_landing = true\nmax_bytes_s = {LOG_CAP_BYTES_S}\n"),
    );
    let skein = Skein::up_sim(3, &["--config", &config]);
    let vs = skein.wait_all(
        "3 connected vehicles with positions and homes",
        3,
        Duration::from_secs(30),
        |v| {
            v["state"] == "Landed"
                && v["position"].is_object()
                && v["home"].is_object()
                && v["link"]["connected"] == true
        },
    );
    let ids: Vec<&str> = vs.iter().map(|v| v["id"].as_str().unwrap()).collect();
    assert_eq!(ids, ["uav-1", "uav-2", "uav-3"]);

    // Arm, then take off to 10 m.
    let (status, body) = skein.post("/api/v1/swarm/commands", json!({"command": "arm"}));
    assert_eq!(status, 202, "{body}");
    assert_eq!(body["accepted"].as_array().unwrap().len(), 3, "{body}");
    skein.wait_all("all armed", 3, Duration::from_secs(20), |v| {
        v["armed"] == true && v["state"] == "Armed"
    });
    let (status, body) = skein.post(
        "/api/v1/swarm/commands",
        json!({"command": "takeoff", "altitude_m": 10.0}),
    );
    assert_eq!(status, 202, "{body}");
    assert!(body["command_id"].as_u64().unwrap() > 0);
    skein.wait_all(
        "all hovering at 10 ± 1 m",
        3,
        Duration::from_secs(60),
        |v| v["state"] == "Hovering" && (alt(v) - 10.0).abs() < 1.0,
    );

    // A command the state forbids is refused with the state named.
    let (status, body) = skein.post(
        "/api/v1/vehicles/uav-1/commands",
        json!({"command": "takeoff", "altitude_m": 10.0}),
    );
    assert_eq!(status, 409, "{body}");
    assert!(
        body["error"].as_str().unwrap().contains("Hovering"),
        "{body}"
    );

    let vs = line_abreast_led_by_uav_2(&skein);
    a_landing_is_broken_off_by_a_hold(&skein, "uav-1");

    // Land: everyone down and disarmed.
    let (status, body) = skein.post("/api/v1/swarm/commands", json!({"command": "land"}));
    assert_eq!(status, 202, "{body}");
    skein.wait_all("all landed and disarmed", 3, Duration::from_secs(90), |v| {
        v["state"] == "Landed" && v["armed"] == false
    });
    let flown: Vec<(String, (f64, f64))> = vs
        .iter()
        .map(|v| {
            let (n, e, _) = ned(v);
            let home = &v["home"];
            let id = v["id"].as_str().unwrap().to_string();
            (
                id,
                (
                    n - home["north_m"].as_f64().unwrap(),
                    e - home["east_m"].as_f64().unwrap(),
                ),
            )
        })
        .collect();
    the_flight_logs_come_home(&skein, &flown);

    // PX4 stays in LAND after touchdown and refuses to arm there: a second takeoff must
    // still work.
    let (status, body) = skein.post(
        "/api/v1/vehicles/uav-1/commands",
        json!({"command": "takeoff", "altitude_m": 4.0}),
    );
    assert_eq!(status, 202, "{body}");
    eventually("uav-1 airborne again", Duration::from_secs(60), || {
        let (_, v) = skein.get("/api/v1/vehicles/uav-1");
        if v["state"] == "Hovering" && (alt(&v) - 4.0).abs() < 1.0 {
            Ok(())
        } else {
            Err(v.to_string())
        }
    });
}

/// Line abreast, 7 m spacing, led by uav-2, checked independently of skein's own metric;
/// returns the vehicles as they held it.
fn line_abreast_led_by_uav_2(skein: &Skein) -> Vec<Value> {
    let (status, body) = skein.put(
        "/api/v1/formation",
        json!({"shape": "line", "spacing_m": 7.0, "leader": "uav-2"}),
    );
    assert_eq!(status, 200, "{body}");
    let formed = eventually(
        "all within 1 m of their slots",
        Duration::from_secs(60),
        || {
            let vs = skein.vehicles();
            let (_, f) = skein.get("/api/v1/formation");
            let members = f["members"].as_array().cloned().unwrap_or_default();
            let in_formation = vs.iter().all(|v| v["state"] == "InFormation");
            let close = members.len() == 3
                && members
                    .iter()
                    .all(|m| m["error_m"].as_f64().unwrap_or(99.0) < 1.0);
            if in_formation && close {
                Ok((vs, f))
            } else {
                Err(format!("{} | formation {f}", summary(&vs)))
            }
        },
    );
    let (vs, f) = formed;
    assert_eq!(f["leader_id"], "uav-2");
    assert_eq!(f["shape"], "line");
    // Independently of skein's own metric: a line across north (heading 0), 7 m apart,
    // at one altitude, the leader in the middle.
    let mut pos: Vec<(String, (f64, f64, f64))> = vs
        .iter()
        .map(|v| (v["id"].as_str().unwrap().to_string(), ned(v)))
        .collect();
    pos.sort_by(|a, b| a.1.1.total_cmp(&b.1.1));
    let norths: Vec<f64> = pos.iter().map(|p| p.1.0).collect();
    let downs: Vec<f64> = pos.iter().map(|p| p.1.2).collect();
    let spread = |xs: &[f64]| {
        xs.iter().cloned().fold(f64::MIN, f64::max) - xs.iter().cloned().fold(f64::MAX, f64::min)
    };
    assert!(spread(&norths) < 1.5, "not abreast: {pos:?}");
    assert!(spread(&downs) < 1.5, "not level: {pos:?}");
    for w in pos.windows(2) {
        let gap = w[1].1.1 - w[0].1.1;
        assert!((gap - 7.0).abs() < 1.5, "spacing {gap} m: {pos:?}");
    }
    assert_eq!(pos[1].0, "uav-2", "leader in the middle: {pos:?}");
    assert!(f["min_separation_m"].as_f64().unwrap() > 3.0, "{f}");

    vs
}

/// Vehicle `vehicle`'s download as `GET /api/v1/logs` shows it.
fn download_of(skein: &Skein, vehicle: &str) -> Option<Value> {
    let (_, all) = skein.get("/api/v1/logs");
    all.as_array()?
        .iter()
        .find(|d| d["vehicle"] == vehicle)
        .cloned()
}

/// `[logs] max_bytes_s` of the flight: the three downloads share it (about 130 kB each,
/// which the simulator alone sends at 72 kB/s each).
const LOG_CAP_BYTES_S: f64 = 90_000.0;

/// Every byte of every download so far.
fn log_bytes(skein: &Skein) -> u64 {
    let (_, all) = skein.get("/api/v1/logs");
    all.as_array()
        .map(|l| l.iter().filter_map(|d| d["received_bytes"].as_u64()).sum())
        .unwrap_or(0)
}

/// After the flight: the newest log of every vehicle fetched by itself on landing, all at
/// once under one cap (uav-1's link cut for 3 s in the middle of its download), each read
/// by pyulog: PX4's topics, the climb to the 10 m hover, and the place each vehicle held
/// in the line (`flown`: north/east from its home, which is its local frame's origin).
fn the_flight_logs_come_home(skein: &Skein, flown: &[(String, (f64, f64))]) {
    let stats = skein.sim_stats_addr();
    eventually(
        "three downloads after landing",
        Duration::from_secs(30),
        || {
            let (_, all) = skein.get("/api/v1/logs");
            (all.as_array().map(Vec::len) == Some(3))
                .then_some(())
                .ok_or(all.to_string())
        },
    );
    let (t0, b0) = (std::time::Instant::now(), log_bytes(skein));
    // Cut uav-1's link once its first bytes arrived (its 130 kB take the simulator about
    // 1.8 s: the cut lands in the middle).
    let started = eventually(
        "uav-1's download under way",
        Duration::from_secs(30),
        || match download_of(skein, "uav-1") {
            Some(d) if d["received_bytes"].as_u64() > Some(0) => Ok(d),
            d => Err(format!("{d:?}")),
        },
    );
    assert_eq!(sim_stats(&stats, "link 1 1 0")["ok"], true);
    // For the 3 s of the outage, uav-1's download stands still, unfinished.
    steady_for(
        "uav-1's download cut off in the middle",
        Duration::from_secs(3),
        Duration::from_secs(10),
        || match download_of(skein, "uav-1") {
            Some(d)
                if d["state"] == "downloading"
                    && d["received_bytes"].as_u64() < d["size_bytes"].as_u64() =>
            {
                Ok(())
            }
            d => Err(format!("first bytes: {started}; now: {d:?}")),
        },
    );
    assert_eq!(sim_stats(&stats, "link 1 0 0")["ok"], true);
    let done = eventually("every log downloaded", Duration::from_secs(120), || {
        let (_, all) = skein.get("/api/v1/logs");
        let list = all.as_array().cloned().unwrap_or_default();
        if list.len() == 3 && list.iter().all(|d| d["state"] == "complete") {
            Ok(list)
        } else {
            Err(all.to_string())
        }
    });
    // Under the cap (a tenth over, for the polls' own timing, and a window in flight).
    let rate = (log_bytes(skein) - b0) as f64 / t0.elapsed().as_secs_f64();
    assert!(
        rate < 1.1 * LOG_CAP_BYTES_S + 3000.0,
        "{rate:.0} B/s over the cap"
    );
    eprintln!("three logs at {rate:.0} B/s together (cap {LOG_CAP_BYTES_S})");
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    for d in &done {
        let (vehicle, log_id) = (
            d["vehicle"].as_str().unwrap(),
            d["log_id"].as_u64().unwrap(),
        );
        let (status, ctype, bytes) =
            skein.get_bytes(&format!("/api/v1/vehicles/{vehicle}/logs/{log_id}/file"));
        assert_eq!((status, ctype.as_str()), (200, "application/octet-stream"));
        assert_eq!(bytes.len() as u64, d["size_bytes"].as_u64().unwrap(), "{d}");
        let path = dir.path().join(format!("{vehicle}.ulg"));
        std::fs::write(&path, bytes).unwrap();
        files.push((vehicle.to_string(), path.display().to_string()));
    }
    let args: Vec<&str> = files.iter().map(|(_, p)| p.as_str()).collect();
    let (code, out, err) = run_peer("read_ulog.py", &args, Duration::from_secs(60));
    assert_eq!(code, Some(0), "read_ulog.py\n{out}\n{err}");
    let read: Value = serde_json::from_str(out.trim()).unwrap();
    for (vehicle, path) in &files {
        let lp = &read[path]["vehicle_local_position"];
        // Up to the 10 m hover at least (formation changes step members up and down).
        let height = lp["max_height_m"].as_f64().unwrap();
        assert!((9.0..20.0).contains(&height), "{vehicle}: {lp}");
        let (_, (north, east)) = flown.iter().find(|(id, _)| id == vehicle).unwrap();
        let within = |range: &Value, x: f64| {
            range[0].as_f64().unwrap() - 1.0 <= x && x <= range[1].as_f64().unwrap() + 1.0
        };
        assert!(
            within(&lp["north_m"], *north) && within(&lp["east_m"], *east),
            "{vehicle} held ({north:.1}, {east:.1}) m from home; its log: {lp}"
        );
    }
}

#[test]
fn bad_input_is_refused_with_the_field_and_malformed_mavlink_is_counted() {
    let skein = Skein::sim(1);
    skein.wait_all("vehicle connected", 1, Duration::from_secs(30), |v| {
        v["link"]["connected"] == true
    });

    let (status, body) = skein.put(
        "/api/v1/formation",
        json!({"shape": "hexagon", "spacing_m": 5}),
    );
    assert_eq!(status, 400, "{body}");
    assert_eq!(body["field"], "shape");
    assert!(
        body["error"].as_str().unwrap().contains("hexagon"),
        "{body}"
    );

    let (status, body) = skein.put("/api/v1/formation", json!({"shape": "line"}));
    assert_eq!(status, 400, "{body}");
    assert_eq!(body["field"], "spacing_m");

    let (status, body) = skein.put(
        "/api/v1/formation",
        json!({"shape": "line", "spacing_m": 5, "leader": "uav-99"}),
    );
    assert_eq!(status, 400, "{body}");
    assert_eq!(body["field"], "leader");

    let (status, body) = skein.post("/api/v1/swarm/commands", json!({"altitude_m": 10}));
    assert_eq!(status, 400, "{body}");
    assert_eq!(body["field"], "command");

    let (status, body) = skein.post(
        "/api/v1/swarm/commands",
        json!({"command": "takeoff", "altitude_m": "high"}),
    );
    assert_eq!(status, 400, "{body}");
    assert_eq!(body["field"], "altitude_m");

    let (status, body) = skein.raw("POST", "/api/v1/swarm/commands", "{not json");
    assert_eq!(status, 400, "{body}");
    assert!(body["error"].as_str().unwrap().contains("invalid JSON"));

    let (status, body) = skein.get("/api/v1/vehicles/uav-42");
    assert_eq!(status, 404, "{body}");
    assert!(body["error"].as_str().unwrap().contains("uav-42"));
    let (status, _) = skein.get("/api/v1/nonsense");
    assert_eq!(status, 404);

    // A malformed datagram to the vehicle's link port: counted, dropped, link unharmed.
    let (_, links) = skein.get("/api/v1/links");
    let addr = links[0]["local_addr"].as_str().unwrap().to_string();
    let before = links[0]["decode"]["rejected_datagrams"].as_u64().unwrap();
    let sock = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    sock.send_to(b"\xfd\x09\x00\x00 definitely not a MAVLink frame", &addr)
        .unwrap();
    eventually(
        "the malformed datagram counted",
        Duration::from_secs(10),
        || {
            let (_, links) = skein.get("/api/v1/links");
            let n = links[0]["decode"]["rejected_datagrams"].as_u64().unwrap();
            if n > before {
                Ok(())
            } else {
                Err(links.to_string())
            }
        },
    );
    let (_, v) = skein.get("/api/v1/vehicles/uav-1");
    assert_eq!(v["link"]["connected"], true, "{v}");
}

#[test]
fn real_vehicles_from_a_config_file_with_a_separate_simulator_process() {
    // `skein sim` as its own process, PX4 SITL port layout on free ports.
    let targets = free_udp_range(2);
    let listens = free_udp_range(2);
    let mut sim = Process::start(&[
        "sim",
        "--vehicles",
        "2",
        "--target-base-port",
        &targets.to_string(),
        "--listen-base-port",
        &listens.to_string(),
    ]);
    // The simulator announces its vehicles before we connect.
    sim.wait_line("ready", Duration::from_secs(30));
    let dir = std::env::temp_dir().join(format!("skein-e2e-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cfg = dir.join("swarm.toml");
    std::fs::write(
        &cfg,
        format!(
            "[swarm]\nmin_separation_m = 2.5\n\n[[vehicles]]\nconnection = \"udpin:127.0.0.1:{}\"\nid = \"alpha\"\n\n[[vehicles]]\nconnection = \"udpin:127.0.0.1:{}\"\nid = \"bravo\"\n",
            targets,
            targets + 1
        ),
    )
    .unwrap();
    let skein = Skein::up(&["--config", cfg.to_str().unwrap()]);
    let vs = skein.wait_all(
        "alpha and bravo connected",
        2,
        Duration::from_secs(30),
        |v| v["link"]["connected"] == true && v["position"].is_object(),
    );
    assert_eq!(vs[0]["id"], "alpha");
    assert_eq!(vs[1]["id"], "bravo");
    assert_eq!(vs[1]["sysid"], 2);
}

#[test]
fn a_bad_config_file_is_refused_naming_key_and_line() {
    let dir = std::env::temp_dir().join(format!("skein-e2e-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cfg = dir.join("bad.toml");
    std::fs::write(
        &cfg,
        "[[vehicles]]\nconnection = \"udpin:0.0.0.0:14540\"\nmodle = \"generic\"\n",
    )
    .unwrap();
    let mut p = Process::start(&[
        "up",
        "--config",
        cfg.to_str().unwrap(),
        "--http",
        "127.0.0.1:0",
    ]);
    let code = p.wait_exit(Duration::from_secs(30));
    assert_ne!(code, Some(0));
    // Give the stderr reader a moment to drain by polling for the message.
    let err = eventually("the error on stderr", Duration::from_secs(5), || {
        let e = p.stderr_text();
        if e.contains("modle") { Ok(e) } else { Err(e) }
    });
    assert!(err.contains("line 3"), "{err}");
    assert!(err.contains("bad.toml"), "{err}");
}

#[test]
fn px4_parameters_through_the_api() {
    let skein = Skein::sim(1);
    skein.wait_all("vehicle connected", 1, Duration::from_secs(30), |v| {
        v["link"]["connected"] == true
    });
    let (status, p) = skein.get("/api/v1/vehicles/uav-1/params/MIS_TAKEOFF_ALT");
    assert_eq!(status, 200, "{p}");
    assert_eq!(p["type"], "real32");
    assert!((p["value"].as_f64().unwrap() - 2.5).abs() < 1e-6, "{p}");
    // An integer parameter is written in its own type (PX4's bytewise encoding).
    let (status, p) = skein.put(
        "/api/v1/vehicles/uav-1/params/COM_OBL_RC_ACT",
        json!({"value": 5}),
    );
    assert_eq!(status, 200, "{p}");
    assert_eq!(
        (p["type"].as_str(), p["value"].as_i64()),
        (Some("int32"), Some(5))
    );
    let (_, p) = skein.get("/api/v1/vehicles/uav-1/params/COM_OBL_RC_ACT");
    assert_eq!(p["value"], 5);
    let (status, body) = skein.put(
        "/api/v1/vehicles/uav-1/params/COM_OBL_RC_ACT",
        json!({"value": "five"}),
    );
    assert_eq!(
        (status, body["field"].as_str()),
        (400, Some("value")),
        "{body}"
    );
    let (status, body) = skein.get("/api/v1/vehicles/uav-1/params/THIS_NAME_IS_TOO_LONG");
    assert_eq!(
        (status, body["field"].as_str()),
        (400, Some("name")),
        "{body}"
    );
    let (status, _) = skein.get("/api/v1/vehicles/uav-9/params/MIS_TAKEOFF_ALT");
    assert_eq!(status, 404);
    refused_arming_carries_px4s_reasons(&skein);
    // Emergency disarm needs an explicit confirmation.
    let (status, body) = skein.post(
        "/api/v1/vehicles/uav-1/commands",
        json!({"command": "force_disarm"}),
    );
    assert_eq!(
        (status, body["field"].as_str()),
        (400, Some("confirm")),
        "{body}"
    );
}

/// With `COM_ARM_ODID` = 2 PX4 refuses to arm without a Remote ID transmitter: the
/// command's outcome names PX4's check (its events' report) and carries what PX4 said
/// (a `STATUSTEXT` and the commander's verdict, an event, longer than one message), the
/// texts are on the stream, the pre-flight view names the check; with 0 it arms.
fn refused_arming_carries_px4s_reasons(skein: &Skein) {
    skein.wait_all(
        "uav-1 landed with a home",
        1,
        Duration::from_secs(30),
        |v| v["state"] == "Landed" && v["home"].is_object(),
    );
    let events = EventLog::connect(&skein.base);
    put_odid(skein, 2);
    // PX4's arming checks fail (SYS_STATUS), and the fleet's pre-flight view says so.
    arming_check(skein, "fail");
    // PX4's own check, by name (its events' report, decoded with the metadata the
    // vehicle served over MAVLink FTP).
    let named = eventually("uav-1's check by name", Duration::from_secs(10), || {
        let c = arming_check(skein, "fail");
        let detail = c["detail"].as_str().unwrap_or_default();
        if detail.starts_with("fail: Open Drone ID system missing (error)") {
            Ok(c)
        } else {
            Err(c.to_string())
        }
    });
    assert_eq!(named["state"], "fail", "{named}");
    let refused = arm_outcome(skein, &events);
    assert_eq!(refused["ok"], false, "{refused}");
    let error = refused["error"].as_str().unwrap_or_default();
    assert!(
        error.contains("(Open Drone ID system missing; "),
        "PX4's check named first: {error}"
    );
    for said in [
        "Preflight Fail: Open Drone ID system missing",
        "Arming denied: Resolve system health failures first",
    ] {
        assert!(error.contains(said), "{error}");
        assert!(
            events
                .of_type("status_text")
                .iter()
                .any(|e| e["id"] == "uav-1" && e["text"] == said && e["severity"] == 2),
            "{said} not on the stream: {:?}",
            events.of_type("status_text")
        );
    }
    px4s_refusal_is_the_vehicles(skein);
    put_odid(skein, 0);
    arming_check(skein, "ok");
    let (_, v) = skein.get("/api/v1/vehicles/uav-1");
    assert_eq!(v["px4_arming_checks"], json!([]), "nothing fails now: {v}");
    let armed = arm_outcome(skein, &events);
    assert_eq!(armed["ok"], true, "{armed}");
}

/// Sets uav-1's `COM_ARM_ODID` (PX4: 2 refuses to arm without Remote ID, 0 ignores it).
fn put_odid(skein: &Skein, value: i64) {
    let (status, p) = skein.put(
        "/api/v1/vehicles/uav-1/params/COM_ARM_ODID",
        json!({ "value": value }),
    );
    assert_eq!(status, 200, "{p}");
}

/// Commands uav-1 to arm; the command's outcome (`command_result` on the stream).
fn arm_outcome(skein: &Skein, events: &EventLog) -> Value {
    let (status, body) = skein.post("/api/v1/vehicles/uav-1/commands", json!({"command": "arm"}));
    assert_eq!(status, 202, "{body}");
    let id = body["command_id"].as_u64().unwrap();
    eventually("the arm's outcome", Duration::from_secs(20), || {
        events
            .of_type("command_result")
            .into_iter()
            .find(|e| e["command_id"] == id)
            .ok_or_else(|| format!("{:?}", events.of_type("command_result")))
    })
}

/// uav-1's `px4_arming_checks` pre-flight check, once in `state`.
fn arming_check(skein: &Skein, state: &'static str) -> Value {
    eventually("uav-1's PX4 arming checks", Duration::from_secs(10), || {
        let (_, p) = skein.get("/api/v1/preflight");
        let c = p["vehicles"][0]["checks"]
            .as_array()
            .and_then(|cs| cs.iter().find(|c| c["check"] == "px4_arming_checks"))
            .cloned()
            .unwrap_or_default();
        if c["state"] == state {
            Ok(c)
        } else {
            Err(p.to_string())
        }
    })
}

/// What PX4 said when it refused is the vehicle's (its arming checks, its messages) and
/// the pre-flight check's detail; its GNSS fix is there too.
fn px4s_refusal_is_the_vehicles(skein: &Skein) {
    let c = arming_check(skein, "fail");
    assert!(
        c["detail"]
            .as_str()
            .unwrap_or_default()
            .contains("Open Drone ID system missing"),
        "{c}"
    );
    let (_, v) = skein.get("/api/v1/vehicles/uav-1");
    assert_eq!(
        v["px4_arming_checks"],
        json!([{
            "message": "Open Drone ID system missing",
            "description": "Open Drone ID system failed to report. Make sure it it setup and installed properly.",
            "severity": "error",
            "prevents_arming": true
        }]),
        "{v}"
    );
    // The snapshot takes up PX4's messages at its next refresh, after the stream has them
    // (once in CI, short of CPU, the first read still had none): polled.
    eventually(
        "PX4's refusal in the vehicle's messages",
        Duration::from_secs(10),
        || {
            let (_, v) = skein.get("/api/v1/vehicles/uav-1");
            let said = v["px4_messages"].as_array().is_some_and(|m| {
                m.iter().any(|m| {
                    m["text"] == "Arming denied: Resolve system health failures first"
                        && m["severity"] == 2
                })
            });
            if said {
                Ok(())
            } else {
                Err(v["px4_messages"].to_string())
            }
        },
    );
    assert!(
        v["gps"]["fix_type"].as_u64() >= Some(3) && v["gps"]["eph_m"].is_number(),
        "{}",
        v["gps"]
    );
}

/// Where the ground station's receiver is in the NMEA log: 60°10.27404' N,
/// 24°56.74068' E (60.171234, 24.945678), 25.0 m above mean sea level, geoid separation
/// 17.5 m; OPEN_DRONE_ID_SYSTEM's units are 1e-7 degrees.
const OPERATOR_GNSS_E7: (i64, i64) = (601_712_340, 249_456_780);

/// One epoch of a receiver with a 3D fix there: `GGA` and `RMC`.
fn operator_nmea() -> Vec<String> {
    use skein_gnss::nmea0183::sentence;
    vec![
        sentence("GPGGA,120000.00,6010.27404,N,02456.74068,E,1,09,0.9,25.0,M,17.5,M,,"),
        sentence("GPRMC,120000.00,A,6010.27404,N,02456.74068,E,0.0,0.0,010126,,,A"),
    ]
}

/// Remote ID: with `[remote_id]` every vehicle hears the operator's identity and
/// location (`OPEN_DRONE_ID_SYSTEM`, `OPEN_DRONE_ID_OPERATOR_ID`) at 1 Hz, as a fleet of
/// pymavlink autopilots with transmitters records them, and the API shows what each
/// transmitter says of itself (`OPEN_DRONE_ID_ARM_STATUS`). The operator's location is
/// the ground station's GNSS (Debian's gpsd fed by gpsfake, `operator_gnss`: LIVE_GNSS)
/// until gpsd is killed; then, within the live fix's age limit and one message, the
/// configured location (FIXED), and each vehicle's status says why.
#[test]
fn remote_id_reaches_every_vehicle_at_1_hz() {
    let mut gps = support::gpsd::FakeGps::start(&operator_nmea());
    let port = free_udp_range(3);
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("fleet.toml");
    let mut text = format!(
        "[remote_id]\noperator_id = \"FIN87astrdge12k8\"\ncategory_eu = \"open\"\nclass_eu = 1\n\
         operator_location = {{ lat_deg = 60.1699, lon_deg = 24.9384, alt_amsl_m = 25.0 }}\n\
         operator_gnss = \"gpsd://127.0.0.1:{}\"\n",
        gps.port
    );
    for i in 0..3 {
        text += &format!(
            "\n[[vehicles]]\nconnection = \"udpin:127.0.0.1:{}\"\nsysid = {}\n",
            port + i,
            i + 1
        );
    }
    std::fs::write(&cfg, text).unwrap();
    let skein = Skein::up(&["--config", cfg.to_str().unwrap()]);
    let fleet = std::thread::spawn(move || {
        let port = port.to_string();
        // On until every vehicle heard the FIXED location (type 2) after the receiver stopped.
        let args = [
            "--port",
            port.as_str(),
            "--vehicles",
            "3",
            "--seconds",
            "6",
            "--until-type",
            "2",
        ];
        run_peer("remote_id_pymavlink.py", &args, Duration::from_secs(90))
    });
    // A transmitter is ready once it has the operator's id, and the API says so.
    let v = eventually(
        "uav-1's transmitter good to arm",
        Duration::from_secs(30),
        || {
            let (_, v) = skein.get("/api/v1/vehicles/uav-1");
            if v["remote_id"]["transmitter"]["good_to_arm"] == true {
                Ok(v)
            } else {
                Err(v["remote_id"].to_string())
            }
        },
    );
    assert_eq!(v["remote_id"]["operator_sent"], true, "{}", v["remote_id"]);
    let stopped_unix_s = live_gnss_then_the_receiver_stops(&skein, &mut gps);
    let (code, out, err) = fleet.join().unwrap();
    assert_eq!(code, Some(0), "remote_id_pymavlink.py\n{out}\n{err}");
    let heard: Value = serde_json::from_str(out.trim()).unwrap();
    for sysid in ["1", "2", "3"] {
        for kind in ["system", "operator_id"] {
            let r = &heard[sysid][kind];
            let rate = r["rate_hz"].as_f64().unwrap();
            assert!(
                r["count"].as_u64().unwrap() >= 5 && (0.8..=1.25).contains(&rate),
                "vehicle {sysid} {kind}: {r}"
            );
        }
        live_then_fixed(sysid, &heard[sysid]["system"]["changes"], stopped_unix_s);
        let system = &heard[sysid]["system"]["last"];
        // FIXED location, EU classification, category open, class C1 (MAV_ODID enums).
        for (field, value) in [
            ("operator_latitude", 601_699_000),
            ("operator_longitude", 249_384_000),
            ("operator_location_type", 2),
            ("classification_type", 1),
            ("category_eu", 1),
            ("class_eu", 2),
        ] {
            assert_eq!(system[field], value, "vehicle {sysid} {field}: {system}");
        }
        let operator = &heard[sysid]["operator_id"]["last"];
        assert_eq!(operator["operator_id"], "FIN87astrdge12k8", "{operator}");
        assert_eq!(operator["operator_id_type"], 0, "{operator}");
    }
}

/// Waits until every vehicle's status says its operator location is the live GNSS
/// one, kills gpsd, and waits until every status says it fell back to the fixed
/// location and why; returns when gpsd was killed (Unix seconds).
fn live_gnss_then_the_receiver_stops(skein: &Skein, gps: &mut support::gpsd::FakeGps) -> f64 {
    let rid = |id: &str| skein.get(&format!("/api/v1/vehicles/{id}")).1["remote_id"].clone();
    for id in ["uav-1", "uav-2", "uav-3"] {
        let r = eventually(&format!("{id}: live GNSS"), Duration::from_secs(20), || {
            let r = rid(id);
            (r["operator_location_source"] == "live_gnss")
                .then_some(r.clone())
                .ok_or(r.to_string())
        });
        let g = &r["operator_gnss"];
        assert_eq!(g["source"], format!("gpsd://127.0.0.1:{}", gps.port), "{r}");
        assert_eq!(
            (&g["connected"], &g["no_fix"], &g["malformed"]),
            (&json!(true), &json!(false), &json!(0)),
            "{r}"
        );
        // gpsd's eph from the GGA's HDOP 0.9.
        assert!(g["eph_m"].as_f64().is_some_and(|e| e > 0.0), "{r}");
        assert!(r["operator_location_age_s"].as_f64().unwrap() < 3.0, "{r}");
        assert_eq!(r["operator_location_fallback"], Value::Null, "{r}");
    }
    let stopped = std::time::SystemTime::now();
    gps.stop();
    let limit_s = skein_link::remote_id::LIVE_FIX_MAX_AGE.as_secs_f64();
    for id in ["uav-1", "uav-2", "uav-3"] {
        let r = eventually(
            &format!("{id}: fixed after gpsd stopped"),
            Duration::from_secs(10),
            || {
                let r = rid(id);
                (r["operator_location_source"] == "fixed")
                    .then_some(r.clone())
                    .ok_or(r.to_string())
            },
        );
        let why = r["operator_location_fallback"].as_str().unwrap_or_default();
        let says = format!("no fix from gpsd://127.0.0.1:{} for", gps.port);
        assert!(
            why.starts_with(&says) && why.contains("(the limit is 3 s)"),
            "{r}"
        );
        assert_eq!(r["operator_location_age_s"], Value::Null, "{r}");
        assert!(
            r["operator_gnss"]["fix_age_s"].as_f64().unwrap() > limit_s,
            "{r}"
        );
    }
    let (_, p) = skein.get("/api/v1/preflight");
    let check = p["vehicles"][0]["checks"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["check"] == "remote_id")
        .cloned();
    let check = check.expect("a remote_id check");
    assert_eq!(check["state"], "warn", "{check}");
    assert!(
        check["detail"]
            .as_str()
            .unwrap()
            .contains("operator at the fixed location, not live GNSS: no fix from gpsd://"),
        "{check}"
    );
    stopped
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_secs_f64()
}

/// Vehicle `sysid` heard the live GNSS location (type 1), within 1e-6 degrees of the
/// NMEA log's, at its ellipsoid height (25.0 m above mean sea level + 17.5 m), then the
/// fixed location (type 2) within the live fix's age limit and one message period
/// (1 s, with 1 s for a loaded machine) of gpsd's end.
fn live_then_fixed(sysid: &str, changes: &Value, stopped_unix_s: f64) {
    let changes = changes.as_array().unwrap();
    let live = changes
        .iter()
        .position(|c| c["operator_location_type"] == 1);
    let live = live.unwrap_or_else(|| panic!("vehicle {sysid}: no LIVE_GNSS: {changes:?}"));
    let c = &changes[live];
    let (lat, lon) = OPERATOR_GNSS_E7;
    let e7 = |k: &str| c[k].as_i64().unwrap();
    assert!(
        (e7("operator_latitude") - lat).abs() <= 10,
        "vehicle {sysid}: {c}"
    );
    assert!(
        (e7("operator_longitude") - lon).abs() <= 10,
        "vehicle {sysid}: {c}"
    );
    assert_eq!(c["operator_altitude_geo"], 42.5, "vehicle {sysid}: {c}");
    let fixed = changes[live..]
        .iter()
        .find(|c| c["operator_location_type"] == 2);
    let fixed = fixed.unwrap_or_else(|| panic!("vehicle {sysid}: no FIXED after: {changes:?}"));
    let after_s = fixed["unix_s"].as_f64().unwrap() - stopped_unix_s;
    let limit_s = skein_link::remote_id::LIVE_FIX_MAX_AGE.as_secs_f64();
    println!("vehicle {sysid}: FIXED {after_s:.2} s after gpsd was killed");
    assert!(
        after_s > 0.0 && after_s <= limit_s + 2.0,
        "vehicle {sysid}: {after_s} s: {changes:?}"
    );
}

/// An agent runs on an aircraft's companion computer: its GNSS receiver is the
/// aircraft's, so it refuses `operator_gnss` (the operator's live location) at start.
#[test]
fn an_agent_refuses_the_operator_gnss() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("agent.toml");
    let text = format!(
        "[remote_id]\noperator_id = \"OP1\"\noperator_gnss = \"gpsd://127.0.0.1\"\n\n\
         [[vehicles]]\nconnection = \"udpin:127.0.0.1:{}\"\nsysid = 1\n",
        free_udp_range(1)
    );
    std::fs::write(&cfg, text).unwrap();
    let mut p = Process::start(&["agent", "--config", cfg.to_str().unwrap()]);
    assert_eq!(p.wait_exit(Duration::from_secs(30)), Some(1));
    let err = p.stderr_text();
    assert!(
        err.contains("remote_id.operator_gnss = \"gpsd://127.0.0.1:2947\"")
            && err.contains("the aircraft's, not the operator's"),
        "{err}"
    );
}

#[test]
fn the_plugin_host_child_is_a_subcommand_of_the_binary() {
    // `skein plugin-host` is what process isolation spawns; without its parent's socket
    // it says so and exits 3 (bad arguments: 2).
    let mut p = Process::start(&[
        "plugin-host",
        "--socket",
        "/nonexistent/skein.sock",
        "--library",
        "/nonexistent/libx.so",
    ]);
    assert_eq!(p.wait_exit(Duration::from_secs(30)), Some(3));
    assert!(
        p.stderr_text().contains("cannot connect"),
        "{}",
        p.stderr_text()
    );
    let mut p = Process::start(&["plugin-host", "--frobnicate"]);
    assert_eq!(p.wait_exit(Duration::from_secs(30)), Some(2));
    assert!(
        p.stderr_text().contains("--frobnicate"),
        "{}",
        p.stderr_text()
    );
}
