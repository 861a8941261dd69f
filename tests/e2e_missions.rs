//! Missions end to end, through the HTTP API only: `skein up --sim 4` stores a plan
//! (bad ones refused naming the step and field), flies it with three vehicles and a
//! reserve (take off in turn, transit in a formation, a survey split in lanes, a patrol,
//! stations, land in turn), paused and resumed mid-survey; uav-3, given a small battery,
//! runs low and the reserve takes its place; every lane flown, everyone down at the end;
//! a plan naming what the swarm lacks is refused at start with the names; a point given
//! as latitude/longitude is stored in the swarm frame; uav-3's measured consumption
//! refuses a plan the model's pack would fly. The intruder
//! reaction flies in [`intruder`]; `skein mission rehearse` runs in [`cli`].

/// `skein mission rehearse`'s test (its own file, as the next).
#[path = "e2e_missions/cli.rs"]
mod cli;
/// The intruder reaction's test (its own file: a test crate's root holds no folder of its
/// own).
#[path = "e2e_missions/intruder.rs"]
mod intruder;
mod support;

use serde_json::{Value, json};
use std::time::Duration;
use support::{Skein, eventually};

fn plan() -> Value {
    json!({
        "name": "e2e sortie",
        "groups": {"pair": {"vehicles": ["uav-1", "uav-3"]}},
        "reactions": {"low_battery": {"below_percent": 85, "reserves": ["uav-4"]}},
        "steps": [
            {"kind": "takeoff", "altitude_m": 8, "interval_s": 1},
            {"kind": "transit", "waypoints": [[15, 5]], "altitude_m": 10, "speed_m_s": 4,
             "formation": {"shape": "line", "spacing_m": 7}},
            {"kind": "survey", "polygon": [[20, -10], [20, 20], [40, 20], [40, -10]],
             "altitude_m": 10, "lane_spacing_m": 5},
            {"kind": "patrol", "group": "pair", "route": [[10, 0], [10, 20], [25, 20]],
             "altitude_m": 12, "duration_s": 3},
            {"kind": "station", "points": [[5, 0], [5, 8], [5, 16]], "altitude_m": 8,
             "duration_s": 2},
            {"kind": "land", "interval_s": 1}
        ]
    })
}

fn mission(skein: &Skein, id: &str) -> Value {
    let (status, m) = skein.get(&format!("/api/v1/missions/{id}"));
    assert_eq!(status, 200, "{m}");
    m
}

fn control(skein: &Skein, id: &str, action: &str) -> (u16, Value) {
    skein.post(&format!("/api/v1/missions/{id}/{action}"), json!({}))
}

/// Waits (`within`) for `pred` on mission `id`.
fn wait_mission(
    skein: &Skein,
    id: &str,
    what: &str,
    within: Duration,
    mut pred: impl FnMut(&Value) -> bool,
) -> Value {
    eventually(what, within, || {
        let m = mission(skein, id);
        if pred(&m) {
            Ok(m)
        } else {
            Err(json!({"state": m["state"], "step": m["step"], "steps": m["steps"], "error": m["error"]}).to_string())
        }
    })
}

#[test]
fn a_plan_with_every_step_kind_flies_to_the_end() {
    let skein = Skein::up_sim(4, &[]);
    skein.wait_all(
        "4 landed vehicles with homes",
        4,
        Duration::from_secs(30),
        |v| v["state"] == "Landed" && v["home"].is_object(),
    );
    refusals(&skein);
    geodetic_points(&skein);
    // uav-3's pack is 400 mAh, not 5000: it falls below 85 % about 18 s into its flight.
    let (status, p) = skein.put(
        "/api/v1/vehicles/uav-3/params/BAT1_CAPACITY",
        json!({"value": 400}),
    );
    assert_eq!(status, 200, "{p}");

    let (status, created) = skein.post("/api/v1/missions", plan());
    assert_eq!(status, 201, "{created}");
    let id = created["id"].as_str().unwrap().to_string();
    assert_eq!(created["state"], "ready");
    let kinds: Vec<&str> = created["steps"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["kind"].as_str().unwrap())
        .collect();
    assert_eq!(
        kinds,
        ["takeoff", "transit", "survey", "patrol", "station", "land"]
    );
    assert_eq!(control(&skein, &id, "resume").0, 409, "not started");
    let rehearsed = rehearse_first(&skein, &id);

    let (status, started) = control(&skein, &id, "start");
    assert_eq!(
        (status, &started["state"]),
        (200, &json!("running")),
        "{started}"
    );
    assert_eq!(
        started["steps"][0]["vehicles"],
        json!(["uav-1", "uav-2", "uav-3"]),
        "uav-4 waits"
    );
    assert_eq!(control(&skein, &id, "start").0, 409, "already flying");
    pause_mid_survey(&skein, &id);

    // Where everyone was, each mission second: a flight that parts from its rehearsal
    // says where and how.
    let mut track = String::new();
    let mut last_s = f64::NEG_INFINITY;
    let done = wait_mission(
        &skein,
        &id,
        "the mission done",
        Duration::from_secs(240),
        |m| {
            let t = m["elapsed_s"].as_f64().unwrap_or(0.0);
            if t - last_s >= 1.0 {
                last_s = t;
                track.push_str(&track_line(&skein, m));
            }
            m["state"] == "done"
        },
    );
    compare(&rehearsed, &done, &track);
    let survey = &done["steps"][2]["progress"];
    assert!(survey["lanes_total"].as_u64() >= Some(4), "{survey}");
    assert_eq!(
        survey["lanes_done"], survey["lanes_total"],
        "every lane flown: {survey}"
    );
    assert!(
        done["steps"]
            .as_array()
            .unwrap()
            .iter()
            .all(|s| s["state"] == "done"),
        "{done}"
    );
    // uav-3 ran low: the reserve uav-4 took its place for the rest of the mission.
    let reactions = done["reactions"].as_array().unwrap();
    assert!(
        reactions.iter().any(|r| r["detail"]
            .as_str()
            .unwrap()
            .contains("uav-4 took over from uav-3")),
        "{reactions:?}"
    );
    assert_eq!(
        done["steps"][5]["vehicles"],
        json!(["uav-1", "uav-2", "uav-4"]),
        "{done}"
    );
    skein.wait_all("everyone down", 4, Duration::from_secs(60), |v| {
        v["state"] == "Landed"
    });
    measured_consumption_refuses_uav_3(&skein);
    let (_, list) = skein.get("/api/v1/missions");
    assert!(
        list.as_array()
            .unwrap()
            .iter()
            .any(|m| m["id"] == id.as_str()),
        "{list}"
    );
}

/// The plan rehearsed in virtual time before it flies: it ends done, every step timed,
/// the survey covered, the separation kept; a bad scenario is refused naming its field.
fn rehearse_first(skein: &Skein, id: &str) -> Value {
    let (status, e) = skein.post(
        &format!("/api/v1/missions/{id}/rehearse"),
        json!({"intruders": {"count": 0}}),
    );
    assert_eq!(
        (status, e["field"].as_str()),
        (400, Some("intruders.count")),
        "{e}"
    );
    assert_eq!(
        skein.post("/api/v1/missions/m-999/rehearse", json!({})).0,
        404
    );
    let rehearsal = format!("/api/v1/missions/{id}/rehearsal");
    let (status, none) = skein.get(&rehearsal);
    assert_eq!(
        (status, none["state"].as_str()),
        (200, Some("none")),
        "{none}"
    );
    assert_eq!(skein.get("/api/v1/missions/m-999/rehearsal").0, 404);
    let (status, started) = skein.post(&format!("/api/v1/missions/{id}/rehearse"), json!({}));
    assert_eq!(status, 202, "{started}");
    assert_eq!(started["mission"], id, "{started}");
    // A debug build at nice 19 beside a CI's builds: minutes, never an open request.
    let ended = eventually("the rehearsal's end", Duration::from_secs(600), || {
        let (status, r) = skein.get(&rehearsal);
        match (status, r["state"].as_str()) {
            (200, Some("running")) => Err(format!("{} mission s flown", r["mission_s"])),
            (200, _) => Ok(r),
            _ => panic!("{status}: {r}"),
        }
    });
    assert_eq!(ended["state"], "done", "{}", ended["error"]);
    let r = ended["report"].clone();
    assert_eq!(
        ended["mission_s"], r["duration_s"],
        "progress ends at the mission's end"
    );
    let mut shown = r.clone();
    shown["picture_svg"] = json!("…");
    assert_eq!(r["state"], "done", "{shown}");
    assert!(
        r["steps"]
            .as_array()
            .unwrap()
            .iter()
            .all(|s| s["ended_s"].is_number()),
        "{shown}"
    );
    // This survey gives a lane spacing and no camera: each lane sees its own width and no
    // more, so any drift off a lane leaves a sliver unseen (0.77 in a deterministic
    // rehearsal); a camera's overlap is what buys full coverage (tests/rehearse.rs).
    assert!(r["coverage"].as_f64().unwrap() > 0.7, "{shown}");
    assert!(r["min_separation_m"].as_f64().unwrap() > 3.0, "{shown}");
    assert!(r["min_fence_margin_m"].as_f64().unwrap() > 0.0, "{shown}");
    assert_eq!(r["energy_left"].as_object().unwrap().len(), 4, "{shown}");
    assert!(
        r["picture_svg"].as_str().unwrap().starts_with("<svg"),
        "{shown}"
    );
    println!(
        "rehearsed: {} s of mission in {} s ({}x), coverage {}",
        r["duration_s"], r["wall_s"], r["speed_factor"], r["coverage"]
    );
    // uav-3's 400 mAh pack (its BAT1_CAPACITY) runs low in the rehearsal too.
    assert!(
        r["reactions"]
            .as_array()
            .unwrap()
            .iter()
            .any(|x| x["detail"]
                .as_str()
                .is_some_and(|d| d.contains("uav-4 took over from uav-3"))),
        "{shown}"
    );
    // Nothing flew: the mission is still ready.
    assert_eq!(mission(skein, id)["state"], "ready");
    shown
}

/// One line of the flight's track: mission second, step, each vehicle's state and
/// position (north, east, altitude).
fn track_line(skein: &Skein, m: &Value) -> String {
    let (_, vehicles) = skein.get("/api/v1/vehicles");
    let mut line = format!(
        "{:.0} s step {}:",
        m["elapsed_s"].as_f64().unwrap_or(0.0),
        m["step"]
    );
    for v in vehicles.as_array().into_iter().flatten() {
        let p = &v["position"];
        let at = |k: &str| p[k].as_f64().unwrap_or(f64::NAN);
        line.push_str(&format!(
            " {} {} ({:.1}, {:.1}, {:.1})",
            v["id"].as_str().unwrap_or("?"),
            v["state"].as_str().unwrap_or("?"),
            at("north_m"),
            at("east_m"),
            -at("down_m")
        ));
    }
    line.push('\n');
    line
}

/// The rehearsal's figures beside the flight's: each step ended at about the same mission
/// time (the flight's clock stops while it is paused, as the rehearsal never is). `track`
/// is the flight's, shown when they part.
fn compare(rehearsed: &Value, flown: &Value, track: &str) {
    let ends = |m: &Value| -> Vec<f64> {
        m["steps"]
            .as_array()
            .unwrap()
            .iter()
            .map(|s| s["ended_s"].as_f64().unwrap_or(f64::NAN))
            .collect()
    };
    let (r, f) = (ends(rehearsed), ends(flown));
    println!("step ends, rehearsed {r:?}, flown {f:?}");
    let (r_end, f_end) = (r[r.len() - 1], f[f.len() - 1]);
    assert!(
        (r_end - f_end).abs() <= 0.1 * f_end,
        "rehearsed {r_end:.1} s, flown {f_end:.1} s: {rehearsed} {flown}\nthe flight:\n{track}"
    );
}

/// Mid-survey: pause (its vehicles hold, the clock stops), then resume.
fn pause_mid_survey(skein: &Skein, id: &str) {
    let m = wait_mission(
        skein,
        id,
        "the survey under way",
        Duration::from_secs(120),
        |m| m["step"] == 2 && m["steps"][2]["progress"]["lanes_done"].as_u64() >= Some(1),
    );
    assert_eq!(m["steps"][1]["state"], "done", "{m}");
    let (status, paused) = control(skein, id, "pause");
    assert_eq!(
        (status, &paused["state"]),
        (200, &json!("paused")),
        "{paused}"
    );
    let held = paused["elapsed_s"].as_f64().unwrap();
    eventually(
        "the survey's vehicles hold",
        Duration::from_secs(15),
        || {
            let vs = skein.vehicles();
            let holding = vs.iter().filter(|v| v["state"] == "Hovering").count();
            (holding >= 3).then_some(()).ok_or(support::summary(&vs))
        },
    );
    let aged = mission(skein, id)["elapsed_s"].as_f64().unwrap() - held;
    assert!(aged < 1.0, "a paused mission does not age: {aged} s");
    let (status, resumed) = control(skein, id, "resume");
    assert_eq!(
        (status, &resumed["state"]),
        (200, &json!("running")),
        "{resumed}"
    );
}

/// A plan's point given as `{"lat_deg", "lon_deg"}`: stored as `[north_m, east_m]` in the
/// swarm frame (0.0001° of latitude north of the swarm origin: 11.1 m north); an
/// impossible latitude refused naming it.
fn geodetic_points(skein: &Skein) {
    let (_, health) = skein.get("/api/v1/health");
    let origin = &health["swarm_origin"];
    let (lat, lon) = (origin["lat_deg"].as_f64(), origin["lon_deg"].as_f64());
    let (Some(lat), Some(lon)) = (lat, lon) else {
        panic!("no swarm origin: {health}")
    };
    let (status, m) = skein.post(
        "/api/v1/missions",
        json!({"name": "by latitude", "steps": [{"kind": "station",
            "points": [{"lat_deg": lat + 0.0001, "lon_deg": lon}],
            "altitude_m": 8, "duration_s": 1}]}),
    );
    assert_eq!(status, 201, "{m}");
    let point = &m["plan"]["steps"][0]["points"][0];
    let (north_m, east_m) = (point[0].as_f64().unwrap(), point[1].as_f64().unwrap());
    assert!(
        (north_m - 11.12).abs() < 0.05 && east_m.abs() < 0.01,
        "{point}"
    );
    let (status, e) = skein.post(
        "/api/v1/missions",
        json!({"name": "x", "steps": [{"kind": "station",
            "points": [{"lat_deg": 95.0, "lon_deg": lon}], "altitude_m": 8, "duration_s": 1}]}),
    );
    assert_eq!(
        (status, e["field"].as_str()),
        (400, Some("steps[0].points[0].lat_deg")),
        "{e}"
    );
}

/// uav-3 flew on a 400 mAh pack (about 50 % a minute hovering) and landed with about a
/// quarter left: one more hop (up to 8 m and down, 14 s), which the model's 5000 mAh pack
/// flies on 1 % and keeps its 20 % reserve, is refused at start at its measured
/// consumption.
fn measured_consumption_refuses_uav_3(skein: &Skein) {
    let (status, m) = skein.post(
        "/api/v1/missions",
        json!({"name": "one more hop", "groups": {"three": {"vehicles": ["uav-3"]}},
            "steps": [{"kind": "takeoff", "group": "three", "altitude_m": 8},
                {"kind": "land", "group": "three"}]}),
    );
    assert_eq!(status, 201, "{m}");
    let (status, e) = control(skein, m["id"].as_str().unwrap(), "start");
    let error = e["error"].as_str().unwrap_or_default();
    assert_eq!(status, 400, "{e}");
    assert!(
        error.contains("uav-3 needs") && error.contains("measured consumption"),
        "{e}"
    );
    println!("refused: {error}");
}

/// Plans refused when posted (naming the step and field) and at start (naming what the
/// swarm lacks).
fn refusals(skein: &Skein) {
    for (body, field) in [
        (json!({"name": "x", "steps": []}), "steps"),
        (
            json!({"name": "x", "steps": [{"kind": "station", "points": [[0, 0], [1, 0]],
                "altitude_m": 8, "duration_s": 1}]}),
            "steps[0].points[1]",
        ),
        (
            json!({"name": "x", "steps": [{"kind": "transit", "waypoints": [[9000, 0]],
                "altitude_m": 8, "speed_m_s": 3}]}),
            "steps[0].waypoints[0]",
        ),
        (
            json!({"name": "x", "steps": [{"kind": "hover"}]}),
            "steps[0]",
        ),
    ] {
        let (status, e) = skein.post("/api/v1/missions", body.clone());
        assert_eq!(status, 400, "{body}: {e}");
        assert!(
            e["field"].as_str().unwrap_or("").starts_with(field),
            "{body}: {e}"
        );
    }
    let (status, m) = skein.post(
        "/api/v1/missions",
        json!({"name": "ghosts", "groups": {"g": {"vehicles": ["uav-9"]}},
            "steps": [{"kind": "land", "group": "g"}]}),
    );
    assert_eq!(status, 201, "{m}");
    let (status, e) = control(skein, m["id"].as_str().unwrap(), "start");
    assert_eq!(
        (status, e["field"].as_str()),
        (400, Some("steps[0].group")),
        "{e}"
    );
    assert!(e["error"].as_str().unwrap().contains("uav-9"), "{e}");
    assert_eq!(skein.get("/api/v1/missions/m-999").0, 404);
}
