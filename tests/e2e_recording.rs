//! Recording and replay end to end: `skein up --sim 2 --record FILE` flies (take-off, a
//! formation), records on demand through the API as well, and the files are read with
//! the reference Python `mcap` reader (every channel: schema, encoding, content); then
//! `skein replay` plays the file back into the read-only API and its stream.

mod support;

use serde_json::{Value, json};
use std::time::Duration;
use support::plugins::{build_into, scratch};
use support::{EventLog, Process, Skein, eventually, one_at_a_time, run_peer};

const CONFIG: &str = r#"
[models.observation]
payloads = [
    { slot = "gimbal", kind = "gimbal" },
    { slot = "camera", kind = "camera", config = { width_px = 160, height_px = 120, frame_rate_hz = 2.0 } },
]
"#;

fn read_mcap(path: &std::path::Path) -> Value {
    let (code, out, err) = run_peer(
        "read_mcap.py",
        &[path.to_str().unwrap()],
        Duration::from_secs(120),
    );
    assert_eq!(code, Some(0), "read_mcap.py failed:\n{out}\n{err}");
    serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("{e}: {out}"))
}

#[test]
fn a_flight_is_recorded_to_mcap_read_by_the_reference_reader_and_replayed() {
    let _serial = one_at_a_time();
    let plugins = scratch("recording-plugins");
    build_into(
        &["skein-plugin-gimbal", "skein-plugin-camera"],
        &[],
        &plugins,
    );
    let dir = scratch("recording");
    let cfg = support::payloads::write_config(
        &dir,
        &format!(
            "{CONFIG}\n[recording]\ndir = \"{}\"\n",
            dir.join("on-demand").display()
        ),
    );
    let whole = dir.join("whole-run.mcap");
    let skein = Skein::up_sim(
        2,
        &[
            "--plugin-dir",
            plugins.to_str().unwrap(),
            "--config",
            &cfg,
            "--record",
            whole.to_str().unwrap(),
        ],
    );
    let (status, body) = skein.get("/api/v1/recording");
    assert_eq!(status, 200, "{body}");
    assert_eq!(body["recording"]["path"], whole.to_str().unwrap(), "{body}");
    // Another recording while one runs, and a name that is not a file name: refused.
    let (status, body) = skein.post("/api/v1/recording/start", json!({"name": "x"}));
    assert_eq!(status, 409, "{body}");
    skein.take_off(2, 5.0);
    let (status, body) = skein.put(
        "/api/v1/formation",
        json!({"shape": "line", "spacing_m": 7.0, "leader": "virtual", "altitude_m": 8.0}),
    );
    assert_eq!(status, 200, "{body}");
    // A mission the coordinator holds is recorded with its state, each second.
    let (status, body) = skein.post(
        "/api/v1/missions",
        json!({"name": "recorded", "steps": [{"kind": "takeoff", "altitude_m": 8}, {"kind": "land"}]}),
    );
    assert_eq!(status, 201, "{body}");
    eventually("a camera frame", Duration::from_secs(60), || {
        let v = skein.get("/api/v1/vehicles/uav-2").1;
        let frames = v["payloads"]
            .as_array()
            .and_then(|p| p.iter().find(|p| p["slot"] == "camera"))
            .and_then(|p| p["frames"].as_u64())
            .unwrap_or(0);
        if frames >= 2 {
            Ok(())
        } else {
            Err(format!("{frames} frames"))
        }
    });
    // The whole-run recording stops; an on-demand one starts and stops.
    let (status, summary) = skein.post("/api/v1/recording/stop", json!({}));
    assert_eq!(status, 200, "{summary}");
    assert!(summary["messages"].as_u64().unwrap() > 50, "{summary}");
    let (status, body) = skein.post("/api/v1/recording/stop", json!({}));
    assert_eq!(status, 409, "{body}");
    let (status, body) = skein.post("/api/v1/recording/start", json!({"name": "../etc"}));
    assert_eq!(
        (status, body["field"].clone()),
        (400, json!("name")),
        "{body}"
    );
    let hover = skein.record_for("hover", 1.5, Duration::from_secs(30));
    let on_demand = dir.join("on-demand/hover.mcap");
    assert_eq!(hover["path"], on_demand.to_str().unwrap(), "{hover}");
    drop(skein);

    // The reference reader: every channel, schemas and content.
    let r = read_mcap(&whole);
    let ch = &r["channels"];
    assert_eq!(r["message_count"], summary["messages"], "{r}");
    for (topic, schema) in [
        ("/skein/uav-1/state", "skein.VehicleState"),
        ("/skein/uav-2/state", "skein.VehicleState"),
        ("/skein/uav-1/fix", "foxglove.LocationFix"),
        ("/skein/uav-1/sent", "skein.SentMessage"),
        ("/skein/events", "skein.SwarmEvent"),
        ("/skein/commands", "skein.Command"),
        ("/skein/formation", "skein.Formation"),
        ("/skein/missions", "skein.Missions"),
        ("/skein/uav-2/camera/image", "foxglove.CompressedImage"),
    ] {
        let c = &ch[topic];
        assert_eq!(c["schema"], schema, "{topic}: {c}");
        assert_eq!(c["schema_encoding"], "jsonschema", "{topic}: {c}");
        assert_eq!(c["message_encoding"], "json", "{topic}: {c}");
        assert!(c["count"].as_u64().unwrap_or(0) > 0, "{topic}: {c}");
        assert_eq!(c["json_errors"], 0, "{topic}: {c}");
    }
    let sent = &ch["/skein/uav-1/sent"]["facts"];
    assert!(
        sent["messages"]
            .as_array()
            .unwrap()
            .contains(&json!("SET_POSITION_TARGET_LOCAL_NED")),
        "{sent}"
    );
    assert!(
        sent["commands"]
            .as_array()
            .unwrap()
            .contains(&json!("MAV_CMD_COMPONENT_ARM_DISARM")),
        "{sent}"
    );
    assert!(!sent["type_masks"].as_array().unwrap().is_empty(), "{sent}");
    let events = &ch["/skein/events"]["facts"]["types"];
    for t in ["state_changed", "command_result", "formation_changed"] {
        assert!(
            events.as_array().unwrap().contains(&json!(t)),
            "{t}: {events}"
        );
    }
    assert!(
        ch["/skein/commands"]["facts"]["commands"]
            .as_array()
            .unwrap()
            .contains(&json!("takeoff"))
    );
    let missions = &ch["/skein/missions"]["facts"];
    assert_eq!(
        (missions["names"].clone(), missions["states"].clone()),
        (json!(["recorded"]), json!(["ready"])),
        "{missions}"
    );
    let image = &ch["/skein/uav-2/camera/image"]["facts"];
    assert_eq!(
        (
            image["jpeg"].clone(),
            image["format"].clone(),
            image["stamped"].clone()
        ),
        (json!(true), json!("jpeg"), json!(true)),
        "{image}"
    );
    let fix = &ch["/skein/uav-1/fix"]["facts"];
    assert!(
        (fix["lat_deg"].as_f64().unwrap() - 47.397).abs() < 0.01,
        "{fix}"
    );
    assert_eq!(ch["/skein/uav-1/state"]["facts"]["armed_seen"], true);
    let hovering = read_mcap(&on_demand);
    assert!(
        hovering["channels"]["/skein/uav-1/state"]["count"]
            .as_u64()
            .unwrap()
            >= 10,
        "{hovering}"
    );

    // Replay: the read-only API answers from the recording, the stream carries its events.
    let mut replay = Process::start(&[
        "replay",
        whole.to_str().unwrap(),
        "--speed",
        "4",
        "--http",
        "127.0.0.1:0",
    ]);
    let line = replay.wait_line("replaying", Duration::from_secs(30));
    let base = line
        .split_whitespace()
        .find(|w| w.starts_with("http://"))
        .expect("url")
        .trim_end_matches('/')
        .to_string();
    let agent: ureq::Agent = ureq::Agent::config_builder()
        .http_status_as_error(false)
        .build()
        .into();
    let get = |path: &str| -> (u16, Value) {
        let mut r = agent.get(format!("{base}{path}")).call().expect("GET");
        let status = r.status().as_u16();
        (status, r.body_mut().read_json().unwrap_or(Value::Null))
    };
    let log = EventLog::connect(&base);
    eventually("both vehicles replayed", Duration::from_secs(60), || {
        let (_, v) = get("/api/v1/vehicles");
        match v.as_array() {
            Some(list) if list.len() == 2 => Ok(()),
            _ => Err(format!("{v}")),
        }
    });
    eventually(
        "replayed events on the stream",
        Duration::from_secs(60),
        || {
            if log.of_type("state_changed").is_empty() {
                Err("none yet".into())
            } else {
                Ok(())
            }
        },
    );
    eventually(
        "the replay reaches its end",
        Duration::from_secs(120),
        || {
            let (_, info) = get("/api/v1/replay");
            if info["finished"] == true {
                Ok(())
            } else {
                Err(format!("{info}"))
            }
        },
    );
    let (_, uav1) = get("/api/v1/vehicles/uav-1");
    assert_eq!(uav1["armed"], true, "{uav1}");
    let (status, formation) = get("/api/v1/formation");
    assert_eq!(
        (status, formation["shape"].clone()),
        (200, json!("line")),
        "{formation}"
    );
    let frame = agent
        .get(format!(
            "{base}/api/v1/vehicles/uav-2/payloads/camera/frame"
        ))
        .call()
        .expect("frame");
    assert_eq!(frame.status().as_u16(), 200);
    let mut r = agent
        .post(format!("{base}/api/v1/swarm/commands"))
        .send_json(json!({"command": "land"}))
        .expect("POST");
    assert_eq!(r.status().as_u16(), 409);
    let body: Value = r.body_mut().read_json().unwrap();
    assert!(
        body["error"].as_str().unwrap().contains("read-only"),
        "{body}"
    );
    drop(replay);
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&plugins);
}
