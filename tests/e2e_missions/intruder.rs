//! The intruder reaction end to end: `skein up --sim 4` with the counter-UAS plugins and
//! an intruder passing 60 m east; a mission holds all four on stations (the observation
//! UAVs uav-2 and uav-4 with their cameras turned east). The intruder's confirmed track
//! inside the plan's zone draws both observers (their gimbals on it, the swarm's
//! observation flying them) while uav-1 and uav-3 keep their stations; when the intruder
//! leaves the world and its track is lost, the observers go back to their stations, and
//! the mission lands everyone.

use super::{control, mission, wait_mission};
use crate::support::counter_uas::{OBSERVERS, build_plugins, up_with_intruder_pass};
use crate::support::{Skein, eventually};
use serde_json::{Value, json};
use std::time::Duration;

/// Each vehicle's landed position, `[north_m, east_m]`, in id order.
fn spawn_points(skein: &Skein) -> Vec<[f64; 2]> {
    let mut vs = skein.vehicles();
    vs.sort_by_key(|v| v["id"].as_str().unwrap_or_default().to_string());
    vs.iter()
        .map(|v| {
            let p = &v["position"];
            [
                p["north_m"].as_f64().unwrap(),
                p["east_m"].as_f64().unwrap(),
            ]
        })
        .collect()
}

fn plan(points: &[[f64; 2]]) -> Value {
    json!({
        "name": "watch the east",
        "reactions": {"intruder": {
            "zone": [[-120, 30], [-120, 120], [120, 120], [120, 30]],
            "observers": 2
        }},
        "steps": [
            {"kind": "takeoff", "altitude_m": 10, "interval_s": 1},
            {"kind": "station", "points": points, "altitude_m": 10, "duration_s": 600},
            {"kind": "land", "interval_s": 1}
        ]
    })
}

/// Vehicles farther than 1.5 m (horizontally) from their points, in words; empty when all
/// are there.
fn off_station(skein: &Skein, ids: &[&str], points: &[[f64; 2]]) -> Vec<String> {
    let vs = skein.vehicles();
    ids.iter()
        .filter_map(|id| {
            let i = id.trim_start_matches("uav-").parse::<usize>().unwrap() - 1;
            let v = vs.iter().find(|v| v["id"] == *id)?;
            let p = &v["position"];
            let d =
                (p["north_m"].as_f64()? - points[i][0]).hypot(p["east_m"].as_f64()? - points[i][1]);
            (d > 1.5).then(|| format!("{id} {d:.1} m off ({})", v["state"]))
        })
        .collect()
}

fn reactions(skein: &Skein, id: &str) -> Vec<Value> {
    mission(skein, id)["reactions"]
        .as_array()
        .cloned()
        .unwrap_or_default()
}

#[test]
fn an_intruder_in_the_zone_draws_the_observers_who_then_return_to_their_stations() {
    let dir = build_plugins("mission-intruder-plugins");
    let skein = up_with_intruder_pass(&dir, 5.0);
    // Out of the world until the cameras are ready (on station, turned east).
    skein.intruders_leave();
    skein.wait_all(
        "4 landed vehicles with homes",
        4,
        Duration::from_secs(30),
        |v| v["state"] == "Landed" && v["home"].is_object(),
    );
    let points = spawn_points(&skein);
    let (status, created) = skein.post("/api/v1/missions", plan(&points));
    assert_eq!(status, 201, "{created}");
    let id = created["id"].as_str().unwrap().to_string();
    let (status, started) = control(&skein, &id, "start");
    assert_eq!(status, 200, "{started}");
    wait_mission(
        &skein,
        &id,
        "everyone on station",
        Duration::from_secs(90),
        |m| {
            m["step"] == 1
                && m["steps"][1]["progress"]["detail"]
                    .as_str()
                    .is_some_and(|d| d.contains("of 600 s"))
        },
    );
    skein.point_gimbals(&OBSERVERS, 90.0, 3.0);
    skein.restart_intruders();

    let sent = eventually(
        "observers sent to the intruder's track",
        Duration::from_secs(150),
        || {
            let rs = reactions(&skein, &id);
            rs.iter()
                .find(|r| r["kind"] == "intruder")
                .cloned()
                .ok_or_else(|| format!("{rs:?}"))
        },
    );
    let mut sent_to: Vec<&str> = sent["vehicles"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    sent_to.sort_unstable();
    assert_eq!(sent_to, OBSERVERS, "{sent}");
    let detail = sent["detail"].as_str().unwrap();
    let track = detail.split_whitespace().next().unwrap().to_string();
    assert!(track.starts_with("track-"), "{detail}");
    eventually(
        "the track observed by both observers",
        Duration::from_secs(10),
        || {
            let (_, tracks) = skein.get("/api/v1/tracks");
            let t = tracks["tracks"]
                .as_array()
                .and_then(|ts| ts.iter().find(|t| t["id"] == track.as_str()).cloned());
            match t {
                Some(t) if t["observed_by"] == json!(OBSERVERS) => Ok(()),
                other => Err(format!("{other:?}")),
            }
        },
    );
    // The rest of the step carries on: uav-1 and uav-3 keep their stations.
    let others = ["uav-1", "uav-3"];
    assert!(
        off_station(&skein, &others, &points).is_empty(),
        "{:?}",
        off_station(&skein, &others, &points)
    );
    assert_eq!(mission(&skein, &id)["step"], 1);

    skein.intruders_leave();
    eventually(
        "the observers back to the step",
        Duration::from_secs(60),
        || {
            let rs = reactions(&skein, &id);
            rs.iter()
                .any(|r| {
                    r["detail"]
                        .as_str()
                        .unwrap_or("")
                        .contains("back to the step")
                })
                .then_some(())
                .ok_or_else(|| format!("{rs:?}"))
        },
    );
    let everyone = ["uav-1", "uav-2", "uav-3", "uav-4"];
    eventually("everyone on station again", Duration::from_secs(60), || {
        let off = off_station(&skein, &everyone, &points);
        off.is_empty().then_some(()).ok_or(off.join(", "))
    });
    let (_, tracks) = skein.get("/api/v1/tracks");
    assert!(
        tracks["tracks"]
            .as_array()
            .unwrap()
            .iter()
            .all(|t| t["observed_by"].as_array().is_none_or(Vec::is_empty)),
        "nobody observes any more: {tracks}"
    );

    assert_eq!(control(&skein, &id, "skip").0, 200);
    wait_mission(
        &skein,
        &id,
        "the mission done",
        Duration::from_secs(90),
        |m| m["state"] == "done",
    );
    skein.wait_all("everyone down", 4, Duration::from_secs(60), |v| {
        v["state"] == "Landed"
    });
}
