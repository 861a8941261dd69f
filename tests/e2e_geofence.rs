//! Flying at a real place (`skein up --sim 3 --map-tiles field.mbtiles`), one skein for
//! the whole path an operator takes:
//!
//! 1. the map: an MBTiles file written here (tiles whose colour says which tile they are,
//!    rows in TMS order, a hole 300 m north) is served over HTTP (content type, cache
//!    header, 404 outside the set) and, in Chromium, the tile under each vehicle's marker
//!    is the one holding its latitude / longitude, the hole shows the grid;
//! 2. while the swarm takes off, the operator draws a polygon on the plan and applies it:
//!    every vehicle's autopilot holds it, read back by pymavlink through the
//!    ground-station forward as an independent peer;
//! 3. bad fences, each answered with its reason and nothing applied: a self-intersecting
//!    polygon, two vertices, a fence leaving a vehicle in the air outside, a fence too
//!    large for PX4 (`MAV_MISSION_NO_SPACE`), an autopilot that refuses the upload
//!    (`MAV_MISSION_ERROR`, the simulator's test fault);
//! 4. a go-to outside is clamped, a leader go-to outside refused; with another vehicle's
//!    setpoints let through the fence (test fault `bypass_geofence`), a go-to across it
//!    is stopped by the simulated PX4's own `GF_ACTION` (hold), and the dashboard shows
//!    the breach.
//!
//! And a file that is not an MBTiles stops skein at start, naming it.

mod support;

use serde_json::{Value, json};
use std::time::Duration;
use support::map_tiles::write_mbtiles;
use support::{Process, Skein, eventually, free_udp_range, run_peer, sim_stats};

/// The simulator's home (`skein sim --home` default), the swarm origin of `--sim`.
const HOME: (f64, f64) = (47.397_742, 8.545_594);
/// The hole in the tile set: 300 m north of home.
const HOLE_NORTH_M: f64 = 300.0;

fn scratch(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("skein-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn a_corrupt_mbtiles_file_is_refused_at_start() {
    let dir = scratch("corrupt-map");
    let junk = dir.join("field.mbtiles");
    std::fs::write(
        &junk,
        b"this is not a SQLite database, whatever its name says".repeat(80),
    )
    .unwrap();
    let mut p = Process::start(&[
        "up",
        "--sim",
        "1",
        "--sim-base-port",
        "0",
        "--http",
        "127.0.0.1:0",
        "--map-tiles",
        junk.to_str().unwrap(),
    ]);
    let code = p.wait_exit(Duration::from_secs(30));
    let err = p.stderr_text();
    assert!(matches!(code, Some(c) if c != 0), "exit {code:?}: {err}");
    assert!(
        err.contains("field.mbtiles") && err.contains("not an MBTiles file"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `PUT /api/v1/geofence` with `body`: (status, answer).
fn put_fence(skein: &Skein, body: Value) -> (u16, Value) {
    skein.put("/api/v1/geofence", body)
}

/// A square polygon fence of half-width `half_m` about (n, e).
fn square(n: f64, e: f64, half_m: f64) -> Value {
    json!({"radius_m": 500, "max_altitude_m": 60, "polygon": [
        [n - half_m, e - half_m], [n + half_m, e - half_m],
        [n + half_m, e + half_m], [n - half_m, e + half_m]]})
}

fn fence_states(skein: &Skein) -> Vec<(String, String, u64)> {
    skein
        .vehicles()
        .iter()
        .map(|v| {
            (
                v["id"].as_str().unwrap_or("?").to_string(),
                v["fence"]["state"].as_str().unwrap_or("?").to_string(),
                v["fence"]["version"].as_u64().unwrap_or(0),
            )
        })
        .collect()
}

/// The bad fences: each refused with its reason, the fence in force (`fence`, version 2,
/// 4 fence items on every autopilot) unchanged.
fn bad_fences_change_nothing(skein: &Skein, stats: &str, fence: &Value) {
    let (s, e) = put_fence(
        skein,
        json!({"radius_m": 500, "max_altitude_m": 60,
               "polygon": [[0, 0], [50, 50], [50, 0], [0, 50]]}),
    );
    assert_eq!((s, e["field"].as_str()), (400, Some("polygon")), "{e}");
    assert!(
        e["error"].as_str().unwrap().contains("self-intersecting"),
        "{e}"
    );
    let (s, e) = put_fence(
        skein,
        json!({"radius_m": 500, "max_altitude_m": 60, "polygon": [[0, 0], [50, 50]]}),
    );
    assert_eq!((s, e["field"].as_str()), (400, Some("polygon")), "{e}");
    assert!(e["error"].as_str().unwrap().contains("at least 3"), "{e}");
    // A fence 100 m north of the hovering swarm.
    let (s, e) = put_fence(skein, square(120.0, 0.0, 20.0));
    assert_eq!(s, 409, "{e}");
    assert!(
        e["error"].as_str().unwrap().contains("uav-1 is in the air"),
        "{e}"
    );
    // 70 vertices: more than PX4 stores; every autopilot refuses.
    let many: Vec<[f64; 2]> = (0..70)
        .map(|i| {
            let a = f64::from(i) * std::f64::consts::TAU / 70.0;
            [5.0 + 25.0 * a.cos(), 25.0 * a.sin()]
        })
        .collect();
    let (s, e) = put_fence(
        skein,
        json!({"radius_m": 500, "max_altitude_m": 60, "polygon": many}),
    );
    let why = e["error"].as_str().unwrap_or_default().to_string();
    assert_eq!(s, 409, "{e}");
    for id in ["uav-1", "uav-2", "uav-3"] {
        assert!(why.contains(&format!("{id}: failed")), "{why}");
    }
    assert!(why.contains("MAV_MISSION_NO_SPACE"), "{why}");
    // One autopilot that refuses any upload: the others took the fence and give it back.
    assert_eq!(sim_stats(stats, "mission_fault 2 error")["ok"], true);
    let (s, e) = put_fence(skein, square(5.0, 0.0, 25.0));
    let why = e["error"].as_str().unwrap_or_default().to_string();
    assert_eq!(s, 409, "{e}");
    assert!(
        why.contains("uav-2: failed") && why.contains("MAV_MISSION_ERROR"),
        "{why}"
    );
    assert!(!why.contains("uav-1: failed"), "{why}");
    assert_eq!(sim_stats(stats, "mission_fault 2 off")["ok"], true);
    assert_eq!(&skein.get("/api/v1/geofence").1, fence, "nothing applied");
    // Every simulated autopilot holds the fence in force (its 4 vertices) again.
    let s = sim_stats(stats, "stats");
    for v in s["vehicles"].as_array().unwrap() {
        assert_eq!(v["fence_items"].as_u64(), Some(4), "{v}");
    }
}

/// Waits until `id` has stopped (ground speed under 0.2 m/s) at least `min_north_m` north.
fn stopped_north_of(skein: &Skein, id: &str, min_north_m: f64) -> Value {
    eventually(
        &format!("{id} stopped at the fence"),
        Duration::from_secs(60),
        || {
            let (_, v) = skein.get(&format!("/api/v1/vehicles/{id}"));
            let n = v["position"]["north_m"].as_f64().unwrap_or(0.0);
            let speed = v["velocity"]["north_m_s"]
                .as_f64()
                .unwrap_or(9.0)
                .hypot(v["velocity"]["east_m_s"].as_f64().unwrap_or(9.0));
            if n > min_north_m && speed < 0.2 {
                Ok(v)
            } else {
                Err(format!("{v}"))
            }
        },
    )
}

#[test]
fn the_field_map_the_fence_drawn_on_it_and_every_px4_holding_it() {
    let dir = scratch("field-map");
    let tiles = dir.join("field.mbtiles");
    let hole = (HOME.0 + HOLE_NORTH_M / 111_195.0, HOME.1);
    // Wide at the shallow levels the zoomed-out plan draws, close about the swarm at the
    // deep ones it draws (overzoomed) around the vehicles.
    let zooms = [(15, 1500.0), (16, 1500.0), (17, 300.0), (18, 150.0)];
    let n = write_mbtiles(&tiles, HOME, &zooms, Some(hole));
    assert!(n > 50, "{n} tiles");
    let gcs_port = free_udp_range(1);
    let forward = format!("udpout:127.0.0.1:{gcs_port}");
    let skein = Skein::up_sim(
        3,
        &[
            "--enable-fault-injection",
            "--map-tiles",
            tiles.to_str().unwrap(),
            "--gcs-forward",
            &forward,
        ],
    );
    let stats = skein.sim_stats_addr();

    // 1. The tiles over HTTP.
    let (s, map) = skein.get("/api/v1/map");
    assert_eq!(s, 200, "{map}");
    assert_eq!(map["source"], "mbtiles");
    assert_eq!(
        (map["min_zoom"].as_u64(), map["max_zoom"].as_u64()),
        (Some(15), Some(18))
    );
    assert_eq!(map["attribution"], "test tiles: colour = tile");
    let (x, y) = support::map_tiles::tile_of(HOME.0, HOME.1, 18);
    let (s, ctype, body) = skein.get_bytes(&format!("/api/v1/map/tiles/18/{x}/{y}"));
    assert_eq!((s, ctype.as_str()), (200, "image/jpeg"));
    assert!(body.starts_with(&[0xFF, 0xD8, 0xFF]));
    let (hx, hy) = support::map_tiles::tile_of(hole.0, hole.1, 18);
    assert_eq!(skein.get(&format!("/api/v1/map/tiles/18/{hx}/{hy}")).0, 404);
    assert_eq!(skein.get(&format!("/api/v1/map/tiles/19/{x}/{y}")).0, 404);
    let (s, e) = skein.get("/api/v1/map/tiles/18/x/1");
    assert_eq!((s, e["field"].as_str()), (400, Some("x")), "{e}");

    // 2. The browser checks the map, then the operator draws the fence, while the swarm
    // takes off; it then waits for the breach of step 4 to show.
    let url = format!("{}/", skein.base);
    let shot = support::workspace()
        .join("target")
        .join("screenshots")
        .join("map-geofence.png");
    let _ = std::fs::create_dir_all(shot.parent().unwrap());
    let browser = std::thread::spawn({
        let api = skein.base.clone();
        let shot = shot.clone();
        move || {
            run_peer(
                "geofence_selenium.py",
                &[
                    "--url",
                    &url,
                    "--api",
                    &api,
                    "--screenshot",
                    shot.to_str().unwrap(),
                    "--hole-north",
                    &HOLE_NORTH_M.to_string(),
                    "--breach",
                    "uav-3",
                ],
                Duration::from_secs(240),
            )
        }
    });
    skein.take_off(3, 10.0);
    let fence = eventually(
        "the operator's fence in force on every vehicle",
        Duration::from_secs(150),
        || {
            let (_, fence) = skein.get("/api/v1/geofence");
            let f = fence_states(&skein);
            let drawn = fence["polygon"].as_array().is_some_and(|p| p.len() == 4);
            if drawn && f.iter().all(|(_, s, v)| s == "synced" && *v == 2) {
                Ok(Some(fence))
            } else if browser.is_finished() {
                Ok(None)
            } else {
                Err(format!("{fence} {f:?}"))
            }
        },
    );
    let Some(fence) = fence else {
        let (code, out, err) = browser.join().expect("browser thread");
        panic!("the browser ended before the fence was applied (exit {code:?})\n{out}\n{err}");
    };
    let poly: Vec<[f64; 2]> = serde_json::from_value(fence["polygon"].clone()).unwrap();
    let north_edge = poly.iter().map(|v| v[0]).fold(f64::NEG_INFINITY, f64::max);
    let west = poly.iter().map(|v| v[1]).fold(f64::INFINITY, f64::min);
    let east = poly.iter().map(|v| v[1]).fold(f64::NEG_INFINITY, f64::max);

    // pymavlink, through the ground-station forward, reads every autopilot's fence.
    let (code, out, err) = run_peer(
        "fence_pymavlink.py",
        &["--port", &gcs_port.to_string(), "--vehicles", "3"],
        Duration::from_secs(60),
    );
    assert_eq!(code, Some(0), "fence_pymavlink.py\n{out}\n{err}");
    let held: Value = serde_json::from_str(out.lines().last().unwrap_or("{}")).unwrap();
    let origin = skein.get("/api/v1/health").1["swarm_origin"].clone();
    let (lat0, lon0) = (
        origin["lat_deg"].as_f64().unwrap(),
        origin["lon_deg"].as_f64().unwrap(),
    );
    let m_per_deg_lon = 111_412.0 * lat0.to_radians().cos();
    for sysid in ["1", "2", "3"] {
        let items = held[sysid]["fence"]
            .as_array()
            .unwrap_or_else(|| panic!("{held}"));
        assert_eq!(items.len(), 4, "{held}");
        for (item, [n, e]) in items.iter().zip(&poly) {
            assert_eq!(
                item["command"], "MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION",
                "{item}"
            );
            assert_eq!(item["param1"], 4.0, "{item}");
            // Where the vertex drawn is (a flat earth is exact enough over 50 m).
            let dn = (item["lat_deg"].as_f64().unwrap() - lat0) * 111_132.0 - n;
            let de = (item["lon_deg"].as_f64().unwrap() - lon0) * m_per_deg_lon - e;
            assert!(
                dn.hypot(de) < 0.3,
                "sysid {sysid}: {item} is {dn:.2} m N, {de:.2} m E off ({n}, {e})"
            );
        }
        assert_eq!(held[sysid]["rally"], json!([]), "{held}");
    }

    // 3. Bad fences, the swarm in the air.
    bad_fences_change_nothing(&skein, &stats, &fence);

    // 4. A go-to outside the fence is clamped (uav-1 stops inside its edge, in OFFBOARD,
    // its autopilot never breached) while skein's guard is bypassed on uav-3, whose
    // autopilot's own fence stops it with GF_ACTION (hold).
    let goto = |id: &str, n: f64, e: f64| {
        let (s, r) = skein.post(
            &format!("/api/v1/vehicles/{id}/commands"),
            json!({"command": "goto", "north_m": n, "east_m": e, "down_m": -10.0}),
        );
        assert_eq!(s, 202, "{r}");
    };
    let (s, r) = skein.post(
        "/api/v1/faults",
        json!({"target": "coordinator/uav-3", "kind": "bypass_geofence"}),
    );
    assert_eq!(s, 202, "{r}");
    goto("uav-1", north_edge + 30.0, west + 5.0);
    goto("uav-3", north_edge + 40.0, east - 5.0);
    let uav1 = stopped_north_of(&skein, "uav-1", north_edge - 8.0);
    let n1 = uav1["position"]["north_m"].as_f64().unwrap();
    assert!(
        n1 < north_edge,
        "uav-1 at {n1:.2} m north, the fence's edge at {north_edge}"
    );
    assert_eq!(uav1["px4_mode"], "OFFBOARD", "{uav1}");
    // The leader's go-to outside is refused, against the new fence.
    let (s, e) = skein.post(
        "/api/v1/formation/leader/goto",
        json!({"north_m": north_edge + 30.0, "east_m": 0.0}),
    );
    assert_eq!((s, e["field"].as_str()), (400, Some("north_m")), "{e}");
    eventually(
        "uav-3 held by its autopilot's fence",
        Duration::from_secs(60),
        || {
            let s = sim_stats(&stats, "stats");
            let v3 = s["vehicles"].as_array().unwrap()[2].clone();
            let (_, api) = skein.get("/api/v1/vehicles/uav-3");
            if v3["geofence_breaches"] == 1
                && api["px4_mode"] == "HOLD"
                && api["fence"]["breached"] == true
            {
                Ok(())
            } else {
                Err(format!("sim {v3} / api {api}"))
            }
        },
    );
    let s = sim_stats(&stats, "stats");
    for v in s["vehicles"].as_array().unwrap() {
        let want = u64::from(v["sysid"] == 3);
        assert_eq!(v["geofence_breaches"].as_u64(), Some(want), "{v}");
    }

    let (code, out, err) = browser.join().expect("browser thread");
    println!("{out}");
    assert_eq!(
        code,
        Some(0),
        "geofence_selenium.py failed (exit {code:?})\n{out}\n{err}"
    );
    println!("screenshot: {}", shot.display());
    let _ = std::fs::remove_dir_all(&dir);
}
