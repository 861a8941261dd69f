//! `skein mission rehearse` from the command line: the README's first mission, as TOML,
//! rehearsed on three simulated vehicles to the end, its picture written; a plan the
//! checks refuse exits 2 naming the field, as does an impossible latitude.

use crate::support::skein_bin;
use serde_json::Value;
use std::process::Command;

#[test]
fn the_first_mission_is_rehearsed_from_its_toml_file() {
    let dir = tempfile::tempdir().unwrap();
    let svg = dir.path().join("first.svg");
    let root = env!("CARGO_MANIFEST_DIR");
    let out = Command::new(skein_bin())
        .args(["mission", "rehearse", "--sim", "3", "--svg"])
        .arg(&svg)
        .arg(format!("{root}/../../deploy/config/mission-example.toml"))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{:?}: {stdout} {}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    let r: Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(r["state"], "done", "{r}");
    let kinds: Vec<&str> = r["steps"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["kind"].as_str().unwrap())
        .collect();
    assert_eq!(kinds, ["takeoff", "transit", "survey", "station", "land"]);
    assert!(r["min_separation_m"].as_f64().unwrap() > 3.0, "{r}");
    assert_eq!(r["energy_left"].as_object().unwrap().len(), 3, "{r}");
    assert!(r["speed_factor"].as_f64().unwrap() > 1.0, "{r}");
    let picture = std::fs::read_to_string(&svg).unwrap();
    assert!(picture.starts_with("<svg") && picture.contains("uav-3"));

    // Lanes 2 m apart: refused by the checks before anything flies. A point as
    // latitude/longitude is put into the swarm frame first: an impossible latitude is
    // named.
    for (plan, field) in [
        (
            r#"{"name": "tight", "steps": [{"kind": "takeoff", "altitude_m": 10},
                {"kind": "survey", "polygon": [[20, -10], [20, 40], [60, 40]],
                 "altitude_m": 15, "lane_spacing_m": 2}]}"#,
            "steps[1].lane_spacing_m",
        ),
        (
            r#"{"name": "geo", "steps": [{"kind": "station",
                "points": [{"lat_deg": 95, "lon_deg": 8.5}], "altitude_m": 8,
                "duration_s": 1}]}"#,
            "steps[0].points[0].lat_deg",
        ),
    ] {
        let bad = dir.path().join("bad.json");
        std::fs::write(&bad, plan).unwrap();
        let out = Command::new(skein_bin())
            .args(["mission", "rehearse"])
            .arg(&bad)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        assert!(stderr.contains(field), "{field}: {stderr}");
    }
}
