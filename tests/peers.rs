//! Independent peers against skein: pymavlink flies a `skein sim` vehicle (signed and
//! unsigned), and acts as QGroundControl on `skein up`'s ground-station forward. The Python
//! scripts live in `tests/peers/`; their interpreter is the test venv (see
//! `support::python`).

mod support;

use std::time::Duration;
use support::{Process, free_udp_range, run_peer};

/// Starts `skein sim --vehicles n` with the PX4 SITL layout on free ports; returns the
/// process and the first target port (where vehicle 0 sends, where a client listens).
fn sim(n: u16) -> (Process, u16) {
    let (p, targets, _) = sim_with(n, &[]);
    (p, targets)
}

/// [`sim`] with `extra` arguments and its stats socket open; also returns the stats
/// address.
fn sim_with(n: u16, extra: &[&str]) -> (Process, u16, String) {
    let targets = free_udp_range(n);
    let listens = free_udp_range(n);
    let (n, targets_s, listens_s) = (n.to_string(), targets.to_string(), listens.to_string());
    let mut args = vec![
        "sim",
        "--vehicles",
        &n,
        "--target-base-port",
        &targets_s,
        "--listen-base-port",
        &listens_s,
        "--stats",
        "127.0.0.1:0",
    ];
    args.extend_from_slice(extra);
    let mut p = Process::start(&args);
    let stats = p.wait_line("stats ", Duration::from_secs(30));
    let stats = stats.trim_start_matches("stats ").trim().to_string();
    p.wait_line("ready", Duration::from_secs(30));
    (p, targets, stats)
}

fn assert_peer(script: &str, args: &[&str], timeout: Duration) {
    let (code, out, err) = run_peer(script, args, timeout);
    assert_eq!(
        code,
        Some(0),
        "{script} failed (exit {code:?})\n--- stdout\n{out}\n--- stderr\n{err}"
    );
}

#[test]
fn pymavlink_decodes_everything_and_flies_offboard() {
    let (_sim, port) = sim(1);
    assert_peer(
        "sim_pymavlink.py",
        &["--port", &port.to_string()],
        Duration::from_secs(180),
    );
}

/// A key file for one test, written by `skein key create` itself.
fn signing_key_file(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("skein-key-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("sim.key");
    let mut p = Process::start(&["key", "create", "--out", path.to_str().unwrap()]);
    p.wait_line("signing_key_file = ", Duration::from_secs(30));
    assert_eq!(p.wait_exit(Duration::from_secs(10)), Some(0));
    use std::os::unix::fs::PermissionsExt;
    let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o600, "key file mode {mode:o}");
    path
}

/// The signed simulator ignores pymavlink without the key (the vehicle stays disarmed,
/// the simulator's unsigned-drop counter rises) and flies with it (arm, take off).
#[test]
fn pymavlink_flies_the_signed_simulator_only_with_the_key() {
    let key = signing_key_file("pymavlink");
    let (_sim, port, stats) = sim_with(1, &["--signing-key-file", key.to_str().unwrap()]);
    assert_peer(
        "sim_signing_pymavlink.py",
        &[
            "--port",
            &port.to_string(),
            "--key-file",
            key.to_str().unwrap(),
            "--stats",
            &stats,
        ],
        Duration::from_secs(120),
    );
}

/// pymavlink as QGroundControl on `skein up --sim 3 --gcs-forward`: three heartbeats with
/// three sysids; a DO_SET_MODE to sysid 2 changes that vehicle only; a setpoint from it
/// is dropped and counted.
#[test]
fn pymavlink_as_qgroundcontrol_sees_every_vehicle_and_commands_one() {
    qgroundcontrol_on_the_forward(&[]);
}

/// The same with signed links (`--sim-signing-key-file`): the unsigned commands of the
/// ground station reach the vehicle only because skein's link signs them.
#[test]
fn pymavlink_as_qgroundcontrol_commands_a_signing_vehicle_through_skein() {
    let key = signing_key_file("gcs");
    let skein = qgroundcontrol_on_the_forward(&["--sim-signing-key-file", key.to_str().unwrap()]);
    let (_, links) = skein.get("/api/v1/links");
    let signing: Vec<&serde_json::Value> = links
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|l| l.get("signing"))
        .collect();
    assert_eq!(signing.len(), 3, "{links}");
    let (_, _, metrics) = skein.get_bytes("/metrics");
    assert!(
        String::from_utf8_lossy(&metrics).contains("mavlink_signing_dropped_frames{"),
        "no per-endpoint signing drop metric"
    );
    for s in signing {
        assert!(s["signed_ok"].as_u64() > Some(10), "{s}");
        assert_eq!(s["unsigned"], 0, "{s}");
        assert_eq!(s["bad_signature"], 0, "{s}");
    }
}

/// Runs `gcs_forward_pymavlink.py` against `skein up --sim 3 --gcs-forward … <extra>`
/// and checks the forwarder's counters; returns the running skein.
fn qgroundcontrol_on_the_forward(extra: &[&str]) -> support::Skein {
    let gcs_port = free_udp_range(1);
    let forward = format!("udpout:127.0.0.1:{gcs_port}");
    let mut args = vec!["--gcs-forward", forward.as_str()];
    args.extend_from_slice(extra);
    let skein = support::Skein::up_sim(3, &args);
    assert_peer(
        "gcs_forward_pymavlink.py",
        &[
            "--port",
            &gcs_port.to_string(),
            "--api",
            &skein.base,
            "--vehicles",
            "3",
        ],
        Duration::from_secs(120),
    );
    let (status, links) = skein.get("/api/v1/links");
    assert_eq!(status, 200, "{links}");
    let gcs = links
        .as_array()
        .unwrap()
        .iter()
        .find(|l| l["connection"] == forward.as_str())
        .unwrap_or_else(|| panic!("no forwarder entry in {links}"));
    let c = &gcs["gcs_forward"];
    assert!(c["setpoints_dropped"].as_u64() >= Some(1), "{gcs}");
    assert!(c["to_gcs"].as_u64() > Some(100), "{gcs}");
    assert!(c["from_gcs"].as_u64() >= Some(1), "{gcs}");
    let (_, _, metrics) = skein.get_bytes("/metrics");
    let metrics = String::from_utf8_lossy(&metrics);
    assert!(
        metrics.contains("gcs_forward_frames") && metrics.contains("setpoints_dropped"),
        "{metrics}"
    );
    skein
}

#[test]
fn mavsdk_flies_a_simulated_vehicle_offboard() {
    let (_sim, port) = sim(1);
    assert_peer(
        "sim_mavsdk.py",
        &["--port", &port.to_string()],
        Duration::from_secs(180),
    );
}

/// MAVSDK's documented offboard start (arm, ONE setpoint, `offboard.start()`, fly) works
/// because the simulator, like PX4 v1.16, accepts OFFBOARD on one fresh setpoint.
#[test]
fn mavsdk_documented_offboard_start() {
    let (_sim, port) = sim(1);
    assert_peer(
        "sim_mavsdk.py",
        &["--port", &port.to_string(), "--documented-start"],
        Duration::from_secs(180),
    );
}

#[test]
fn the_dashboard_flies_three_vehicles_in_chromium() {
    let skein = support::Skein::up_sim(3, &[]);
    let url = format!("{}/", skein.base);
    let stats = skein.sim_stats_addr();
    let shot = std::env::temp_dir().join(format!("skein-dashboard-{}.png", std::process::id()));
    assert_peer(
        "dashboard_selenium.py",
        &[
            "--url",
            &url,
            "--sim-stats",
            &stats,
            "--screenshot",
            shot.to_str().unwrap(),
        ],
        Duration::from_secs(240),
    );
}

/// The dashboard's Mission tab in Chromium (`mission_selenium.py`): a survey drawn on the
/// plan, refused where the refusal names (a corner past the fence, lanes too close), fixed
/// and stored; rehearsed (its figures and picture shown, nothing moved); flown with a
/// pause, its lanes counted; flown again to skip the survey, and
/// again to abort it. Screenshots: `target/screenshots/mission{,-plan}.png`.
#[test]
fn the_dashboard_plans_and_flies_a_mission_in_chromium() {
    let skein = support::Skein::up_sim(3, &[]);
    // A fence whose north edge is 22 m north of the swarm: the first draft reaches past it.
    let (status, body) = skein.put(
        "/api/v1/geofence",
        serde_json::json!({"radius_m": 500, "max_altitude_m": 120, "min_altitude_m": 0,
            "polygon": [[-15, -15], [-15, 35], [22, 35], [22, -15]], "breach_action": "hold"}),
    );
    assert_eq!(status, 200, "{body}");
    let url = format!("{}/", skein.base);
    let shots = support::workspace().join("target").join("screenshots");
    let _ = std::fs::create_dir_all(&shots);
    let (shot, plan_shot) = (shots.join("mission.png"), shots.join("mission-plan.png"));
    let (code, out, err) = run_peer(
        "mission_selenium.py",
        &[
            "--url",
            &url,
            "--fence-north",
            "22",
            "--screenshot",
            shot.to_str().unwrap(),
            "--plan-screenshot",
            plan_shot.to_str().unwrap(),
        ],
        Duration::from_secs(600),
    );
    // The summary (timings, the refusals, the lanes seen) is worth reading on success too.
    println!("{out}");
    assert_eq!(
        code,
        Some(0),
        "mission_selenium.py failed (exit {code:?})\n--- stdout\n{out}\n--- stderr\n{err}"
    );
}

/// Vehicle models of the ground station test: the observation model with a small camera
/// (so that frames are cheap), a gimbal and a radio; the generic one with the example
/// plugin in its own process (a kind the dashboard has no widget for).
const GROUND_STATION_CONFIG: &str = r#"
[models.observation]
payloads = [
    { slot = "gimbal", kind = "gimbal" },
    { slot = "camera", kind = "camera", config = { width_px = 320, height_px = 240, frame_rate_hz = 5.0 } },
    { slot = "radio", kind = "radio" },
]

[models.generic]
payloads = [{ slot = "example", kind = "example", isolation = "process" }]
"#;

#[test]
fn the_ground_station_drives_payloads_supervision_and_plugins_in_chromium() {
    let dir = support::plugins::scratch("ground-station");
    support::plugins::build_into(
        &[
            "skein-plugin-gimbal",
            "skein-plugin-camera",
            "skein-plugin-radio",
            "skein-plugin-example",
        ],
        &[],
        &dir,
    );
    let cfg = dir.join("skein.toml");
    std::fs::write(&cfg, GROUND_STATION_CONFIG).unwrap();
    let skein = support::Skein::up(&[
        "--sim",
        "4",
        "--sim-base-port",
        "0",
        "--enable-fault-injection",
        "--plugin-dir",
        dir.to_str().unwrap(),
        "--config",
        cfg.to_str().unwrap(),
    ]);
    // The geofence the plan view draws (the default fence: 500 m around the origin).
    let (status, fence) = skein.get("/api/v1/geofence");
    assert_eq!(status, 200, "{fence}");
    assert_eq!(fence["radius_m"], 500.0, "{fence}");
    let url = format!("{}/", skein.base);
    let shots = support::workspace().join("target").join("screenshots");
    println!("ground station screenshots: {}", shots.display());
    let (code, out, err) = run_peer(
        "ground_station_selenium.py",
        &["--url", &url, "--screenshots", shots.to_str().unwrap()],
        Duration::from_secs(240),
    );
    // The summary (timings, what was seen) is worth reading on success too.
    println!("{out}");
    assert_eq!(
        code,
        Some(0),
        "ground_station_selenium.py failed (exit {code:?})\n--- stdout\n{out}\n--- stderr\n{err}"
    );
}

/// The counter-UAS views in Chromium: a V of three intruders passes east of four vehicles
/// whose observation UAVs (uav-2, uav-4) look east; the dashboard lists and draws a
/// confirmed track and the hostile swarm they form (its hull and forecast cone), observes
/// a track on a click, and shows the detector's boxes over uav-2's video.
#[test]
fn the_dashboard_shows_tracks_and_observes_one_in_chromium() {
    let _serial = support::one_at_a_time();
    let dir = support::counter_uas::build_plugins("tracks-dashboard");
    // About 20 s of every 45 s pass in the cameras' view at 4 m/s.
    let skein = support::counter_uas::up_with_formation_pass(&dir, 4.0, 3);
    skein.take_off(4, 10.0);
    skein.point_gimbals(&support::counter_uas::OBSERVERS, 90.0, 3.0);
    // The intruder's pass (back and forth, about 20 s of every 45 s in view): the browser
    // starts once the tracker has a confirmed track, so the page has one to show.
    support::eventually("a confirmed track", Duration::from_secs(150), || {
        let (_, tracks) = skein.get("/api/v1/tracks");
        let confirmed = tracks["tracks"]
            .as_array()
            .is_some_and(|t| t.iter().any(|t| t["status"] == "confirmed"));
        if confirmed {
            return Ok(());
        }
        let (_, uav2) = skein.get("/api/v1/vehicles/uav-2");
        let detector = uav2["payloads"]
            .as_array()
            .and_then(|p| p.iter().find(|p| p["kind"] == "detector").cloned());
        let (_, truth) = skein.get("/api/v1/sim/truth");
        Err(format!(
            "tracks {tracks}; intruder {}; uav-2 detector {}",
            truth["intruders"][0],
            detector.unwrap_or_default()
        ))
    });
    let url = format!("{}/", skein.base);
    let shot = support::workspace()
        .join("target")
        .join("screenshots")
        .join("tracks.png");
    let _ = std::fs::create_dir_all(shot.parent().unwrap());
    // What the API says while the browser looks (in the failure's message, after the
    // browser's own report: one line per look, each track's id, status, swarm and
    // observers).
    let watching = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(true));
    let watcher = {
        let (base, watching) = (skein.base.clone(), watching.clone());
        let started = std::time::Instant::now();
        std::thread::spawn(move || {
            let mut seen = Vec::new();
            while watching.load(std::sync::atomic::Ordering::Relaxed) {
                let tracks: serde_json::Value = ureq::get(format!("{base}/api/v1/tracks"))
                    .call()
                    .ok()
                    .and_then(|mut r| r.body_mut().read_json().ok())
                    .unwrap_or_default();
                seen.push(format!(
                    "{:5.1} s: {}",
                    started.elapsed().as_secs_f64(),
                    tracks_line(&tracks)
                ));
                std::thread::sleep(Duration::from_secs(3));
            }
            seen
        })
    };
    let (code, out, err) = run_peer(
        "tracks_selenium.py",
        &["--url", &url, "--screenshot", shot.to_str().unwrap()],
        Duration::from_secs(240),
    );
    watching.store(false, std::sync::atomic::Ordering::Relaxed);
    let api_log = watcher.join().unwrap().join("\n");
    println!("{out}");
    assert_eq!(
        code,
        Some(0),
        "tracks_selenium.py failed (exit {code:?})\n--- stdout\n{out}\n--- stderr\n{err}\n\
         --- GET /api/v1/tracks every 3 s meanwhile\n{api_log}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// One look at `GET /api/v1/tracks`, short: each track's `id status swarm [observers]`.
fn tracks_line(tracks: &serde_json::Value) -> String {
    let Some(list) = tracks["tracks"].as_array() else {
        return format!("no track list: {tracks}");
    };
    let each: Vec<String> = list
        .iter()
        .map(|t| {
            format!(
                "{} {} {} {}",
                t["id"].as_str().unwrap_or("?"),
                t["status"].as_str().unwrap_or("?"),
                t["swarm"].as_str().unwrap_or("-"),
                t["observed_by"]
            )
        })
        .collect();
    each.join("; ")
}
