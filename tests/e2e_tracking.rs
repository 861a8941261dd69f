//! Counter-UAS end to end, from the outside: `skein up --sim 4 --intruders 1` with the
//! intruder on a straight pass 60 m east of the swarm; the two observation UAVs (uav-2,
//! uav-4: gimbal, camera, detector, loaded from the built plugins with `dlopen`) hover at
//! 10 m with their cameras turned east. The intruder has no link: only the cameras' frames,
//! the detectors' image processing and the coordinator's tracker can find it. Checked over
//! HTTP against the simulator's ground truth (`GET /api/v1/sim/truth`): a confirmed track
//! within 5 s of the intruder entering both cameras' view; then `POST
//! /api/v1/tracks/{id}/observe` turns both gimbals onto the track and keeps the intruder in
//! both cameras' view while it flies far past the edge of their first view; position RMSE
//! under 3 m over the whole pass, one track id, no track on a swarm member, the
//! `track_confirmed` event on the stream and the tracker's counters in `/metrics`. Last, a
//! wedge takes the track as its leader with a 30 m stand-off and follows the intruder at
//! that distance, without a separation or geofence violation.
//!
//! Hostile swarms: `skein up --sim 4 --intruders 5 --intruder-pattern formation`, a V of
//! five on the same pass (started again once the cameras point east, through the
//! simulator's stats socket), is one `swarm_detected` of five tracks; observing it flies the
//! two observation UAVs to stations that keep the stand-off, the slot distance and the
//! geofence, where they arrive without a separation or fence violation.

mod support;

/// The hostile swarm's test (its own file: a test crate's root holds no folder of its own).
#[path = "e2e_tracking/hostile_swarm.rs"]
mod hostile_swarm;

use serde_json::{Value, json};
use std::time::{Duration, Instant};
use support::counter_uas::{OBSERVERS, build_plugins, up_with_intruder_pass};
use support::{EventLog, Skein, one_at_a_time};

/// The ids of the intruders the camera of `vehicle` drew in its last frame (the simulated
/// camera's own account of what it drew, for evaluation).
fn drawn_intruders(vehicles: &[Value], vehicle: &str) -> Vec<Value> {
    vehicles
        .iter()
        .find(|v| v["id"] == vehicle)
        .and_then(|v| v["payloads"].as_array())
        .and_then(|ps| ps.iter().find(|p| p["slot"] == "camera"))
        .and_then(|p| p["state"]["visible"].as_array())
        .map(|vis| {
            vis.iter()
                .filter(|a| a["intruder"] == true)
                .map(|a| a["id"].clone())
                .collect()
        })
        .unwrap_or_default()
}

/// True when the camera of `vehicle` drew an intruder in its last frame.
fn camera_sees_intruder(vehicles: &[Value], vehicle: &str) -> bool {
    !drawn_intruders(vehicles, vehicle).is_empty()
}

/// How many intruders both observers' cameras drew in their last frames (by id).
fn seen_by_both(vehicles: &[Value]) -> usize {
    let second = drawn_intruders(vehicles, OBSERVERS[1]);
    drawn_intruders(vehicles, OBSERVERS[0])
        .iter()
        .filter(|id| second.contains(id))
        .count()
}

/// Every track against the simulator's truth, for a failure's story: id, status, swarm,
/// velocity σ (m/s), the nearest intruder and the distance to it (m).
fn tracks_vs_truth(skein: &Skein) -> String {
    let (_, tracks) = skein.get("/api/v1/tracks");
    let (_, truth) = skein.get("/api/v1/sim/truth");
    let intruders = truth["intruders"].as_array().cloned().unwrap_or_default();
    let tracks = tracks["tracks"].as_array().cloned().unwrap_or_default();
    let lines: Vec<String> = tracks
        .iter()
        .map(|t| {
            let p = ned(&t["position"]);
            let nearest = intruders
                .iter()
                .map(|i| (i["id"].as_str().unwrap_or("?"), dist(p, ned(i))))
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .map_or("none".to_string(), |(id, d)| format!("{id} at {d:.1} m"));
            format!(
                "{} {} {} σv {:.1} {nearest}",
                t["id"].as_str().unwrap_or("?"),
                t["status"].as_str().unwrap_or("?"),
                t["swarm"].as_str().unwrap_or("-"),
                t["velocity_sigma_m_s"].as_f64().unwrap_or(f64::NAN),
            )
        })
        .collect();
    lines.join("; ")
}

fn ned(v: &Value) -> [f64; 3] {
    [
        v["north_m"].as_f64().unwrap_or(f64::NAN),
        v["east_m"].as_f64().unwrap_or(f64::NAN),
        v["down_m"].as_f64().unwrap_or(f64::NAN),
    ]
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// One look at the world: is the intruder in both cameras' view, the confirmed track
/// nearest it (id, distance to the truth, m), how far its bearing from uav-2 is off east.
struct Sample {
    in_view: bool,
    nearest_confirmed: Option<(String, f64)>,
    off_east_deg: f64,
}

fn sample(skein: &Skein) -> Sample {
    let vs = skein.vehicles();
    let in_view = OBSERVERS.iter().all(|o| camera_sees_intruder(&vs, o));
    let (_, tracks) = skein.get("/api/v1/tracks");
    let (_, truth) = skein.get("/api/v1/sim/truth");
    let intruder = ned(&truth["intruders"][0]);
    let tracks = tracks["tracks"].as_array().cloned().unwrap_or_default();
    let vehicles = truth["vehicles"].as_array().cloned().unwrap_or_default();
    // Swarm members are never tracks.
    for t in &tracks {
        for v in &vehicles {
            let d = dist(ned(&t["position"]), ned(v));
            assert!(
                d > 3.0 || t["status"] != "confirmed",
                "a confirmed track on {}: {t}",
                v["id"]
            );
        }
    }
    let nearest_confirmed = tracks
        .iter()
        .filter(|t| t["status"] == "confirmed")
        .map(|t| {
            (
                t["id"].as_str().unwrap_or("?").to_string(),
                dist(ned(&t["position"]), intruder),
            )
        })
        .min_by(|a, b| a.1.total_cmp(&b.1));
    let eye = vehicles
        .iter()
        .find(|v| v["id"] == "uav-2")
        .map(ned)
        .unwrap_or([0.0; 3]);
    let off_east_deg = (intruder[0] - eye[0])
        .atan2(intruder[1] - eye[1])
        .to_degrees()
        .abs();
    Sample {
        in_view,
        nearest_confirmed,
        off_east_deg,
    }
}

#[test]
fn a_passing_intruder_becomes_a_confirmed_track_that_follows_the_truth() {
    let _serial = one_at_a_time();
    let dir = build_plugins("tracking-plugins");
    // Southward along a line 60 m east of home, 14 m up, 5 m/s; 180 m passes.
    let skein = up_with_intruder_pass(&dir, 5.0);
    // Ground truth exists: the intruder, and the vehicles.
    let (status, truth) = skein.get("/api/v1/sim/truth");
    assert_eq!(status, 200, "{truth}");
    assert_eq!(truth["intruders"][0]["id"], "intruder-1", "{truth}");
    assert_eq!(truth["intruders"][0]["pattern"], "straight");
    let stream = EventLog::connect(&skein.base);
    skein.take_off(4, 10.0);
    // The intruder is not a vehicle: no link, no listing.
    assert_eq!(skein.vehicles().len(), 4);
    skein.point_gimbals(&OBSERVERS, 90.0, 3.0);
    let mut record = TrackRecord::default();
    let (id, to_confirm) = confirmed_on_entry(&skein, &mut record);
    let observed = observe_the_track(&skein, &id, &mut record);
    follow_the_track(&skein, &id);
    let (status, body) = skein.delete(&format!("/api/v1/tracks/{id}/observe"));
    assert_eq!(status, 200, "{body}");
    assert_eq!(body["released"], json!(OBSERVERS), "{body}");
    check_the_record(&id, to_confirm, &record, observed);
    check_stream_and_metrics(&skein, &stream, &id);
}

/// What the pass showed of the intruder's track: each sample's distance from the nearest
/// confirmed track to the truth (m), and the ids of those tracks.
#[derive(Default)]
struct TrackRecord {
    errors: Vec<f64>,
    ids: std::collections::BTreeSet<String>,
}

impl TrackRecord {
    /// Records the sample's nearest confirmed track, if any.
    fn note(&mut self, s: &Sample) {
        if let Some((id, err)) = &s.nearest_confirmed {
            self.ids.insert(id.clone());
            self.errors.push(*err);
        }
    }
}

/// How the observed intruder stayed in view: samples in both views, samples, and the
/// widest bearing off the cameras' first axis (degrees).
struct Observed {
    in_view: usize,
    samples: usize,
    widest_deg: f64,
}

/// Watches for the intruder to enter both views (from out of view), then for a confirmed
/// track, recording the track against the truth while it stays in view; returns the
/// track's id and how long after entering it was confirmed.
fn confirmed_on_entry(skein: &Skein, record: &mut TrackRecord) -> (String, Duration) {
    let mut was_in_view = true;
    let mut entered: Option<Instant> = None;
    let mut confirmed: Option<(String, Duration, Instant)> = None;
    let deadline = Instant::now() + Duration::from_secs(150);
    loop {
        assert!(
            Instant::now() < deadline,
            "no pass in time: entered {entered:?}, confirmed {confirmed:?}, {} samples",
            record.errors.len()
        );
        let s = sample(skein);
        match (entered, s.in_view) {
            (None, true) if !was_in_view => entered = Some(Instant::now()),
            (Some(_), false) => panic!("the intruder left the views: confirmed {confirmed:?}"),
            _ => {}
        }
        was_in_view = s.in_view;
        if let Some(t_in) = entered
            && let Some((id, err)) = s.nearest_confirmed
        {
            if confirmed.is_none() {
                confirmed = Some((id.clone(), t_in.elapsed(), Instant::now()));
            }
            record.ids.insert(id);
            record.errors.push(err);
        }
        // Enough of the unsteered pass: observe the track from here on.
        if confirmed
            .as_ref()
            .is_some_and(|c| c.2.elapsed() > Duration::from_secs(4))
        {
            break;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    let (id, to_confirm, _) = confirmed.expect("a confirmed track");
    assert!(
        to_confirm < Duration::from_secs(5),
        "confirmed after {to_confirm:?}"
    );
    (id, to_confirm)
}

/// Observe: refused for an unknown track and for a vehicle without a gimbal, then both
/// gimbals follow the track, which stays in both cameras' view well past the edge of the
/// view they had (20 s, recorded).
fn observe_the_track(skein: &Skein, id: &str, record: &mut TrackRecord) -> Observed {
    let (status, body) = skein.post("/api/v1/tracks/track-999/observe", json!({}));
    assert_eq!(
        (status, body["field"].as_str()),
        (404, Some("id")),
        "{body}"
    );
    let (status, body) = skein.post(
        &format!("/api/v1/tracks/{id}/observe"),
        json!({"vehicles": ["uav-1"]}),
    );
    assert_eq!(
        (status, body["field"].as_str()),
        (400, Some("vehicles")),
        "{body}"
    );
    let (status, body) = skein.post(&format!("/api/v1/tracks/{id}/observe"), json!({}));
    assert_eq!(status, 200, "{body}");
    assert_eq!(body["vehicles"], json!(OBSERVERS), "{body}");
    let (_, tracks) = skein.get("/api/v1/tracks");
    let listed = tracks["tracks"]
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t["id"] == id)
        .cloned();
    assert_eq!(
        listed.map(|t| t["observed_by"].clone()),
        Some(json!(OBSERVERS))
    );
    let observe_start = Instant::now();
    let (mut in_view, mut samples, mut widest_deg) = (0usize, 0usize, 0.0f64);
    while observe_start.elapsed() < Duration::from_secs(20) {
        let s = sample(skein);
        record.note(&s);
        if observe_start.elapsed() > Duration::from_secs(2) {
            samples += 1;
            in_view += usize::from(s.in_view);
            if s.in_view {
                widest_deg = widest_deg.max(s.off_east_deg);
            }
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    Observed {
        in_view,
        samples,
        widest_deg,
    }
}

/// A formation led by the track: refused naming the field for an unknown track or a
/// missing stand-off; then the swarm follows the intruder at the stand-off (the gimbals
/// still on it), keeping its separation and the geofence.
fn follow_the_track(skein: &Skein, id: &str) {
    let wedge = |leader: &str, standoff: Option<f64>| {
        let mut f =
            json!({"shape": "wedge", "spacing_m": 7.0, "leader": leader, "altitude_m": 10.0});
        if let Some(s) = standoff {
            f["standoff_m"] = json!(s);
        }
        f
    };
    let (status, body) = skein.put("/api/v1/formation", wedge("track-999", Some(30.0)));
    assert_eq!(
        (status, body["field"].as_str()),
        (400, Some("leader")),
        "{body}"
    );
    let (status, body) = skein.put("/api/v1/formation", wedge(id, None));
    assert_eq!(
        (status, body["field"].as_str()),
        (400, Some("standoff_m")),
        "{body}"
    );
    const STANDOFF_M: f64 = 30.0;
    let (status, body) = skein.put("/api/v1/formation", wedge(id, Some(STANDOFF_M)));
    assert_eq!(status, 200, "{body}");
    let stats = skein.sim_stats_addr();
    let (_, fence) = skein.get("/api/v1/geofence");
    let fence_radius = fence["radius_m"].as_f64().unwrap_or(f64::INFINITY);
    let follow_start = Instant::now();
    let (mut standoffs, mut min_sep, mut farthest) = (Vec::new(), f64::INFINITY, 0.0f64);
    // Tracking quality while the observers fly (reported, see docs/architecture.md).
    let (mut follow_errors, mut follow_ids) = (Vec::new(), std::collections::BTreeSet::new());
    while follow_start.elapsed() < Duration::from_secs(40) {
        let s = sample(skein);
        if let Some((tid, err)) = s.nearest_confirmed {
            follow_ids.insert(tid);
            follow_errors.push(err);
        }
        let (_, truth) = skein.get("/api/v1/sim/truth");
        let intruder = ned(&truth["intruders"][0]);
        for v in truth["vehicles"].as_array().unwrap() {
            let p = ned(v);
            farthest = farthest.max(p[0].hypot(p[1]));
        }
        min_sep = min_sep.min(support::truth_min_separation(&stats));
        if follow_start.elapsed() > Duration::from_secs(20) {
            let f = skein.formation();
            let r = &f["reference"]["position"];
            let (rn, re) = (
                r["north_m"].as_f64().unwrap(),
                r["east_m"].as_f64().unwrap(),
            );
            standoffs.push((intruder[0] - rn).hypot(intruder[1] - re));
        }
        std::thread::sleep(Duration::from_millis(250));
    }
    let mean_standoff = standoffs.iter().sum::<f64>() / standoffs.len().max(1) as f64;
    let follow_rmse = (follow_errors.iter().map(|e: &f64| e * e).sum::<f64>()
        / follow_errors.len().max(1) as f64)
        .sqrt();
    println!(
        "tracking: formation led by {id}: horizontal distance to the intruder {mean_standoff:.1} m \
         on average (asked {STANDOFF_M} m; {} samples, min {:.1}, max {:.1}), closest pair \
         {min_sep:.2} m, farthest vehicle {farthest:.0} m from the origin; tracking while the \
         observers fly: RMSE {follow_rmse:.2} m over {} samples, ids {follow_ids:?}",
        standoffs.len(),
        standoffs.iter().cloned().fold(f64::INFINITY, f64::min),
        standoffs.iter().cloned().fold(0.0, f64::max),
        follow_errors.len(),
    );
    assert!(
        (mean_standoff - STANDOFF_M).abs() < 12.0,
        "stand-off {mean_standoff:.1} m: {standoffs:?}"
    );
    assert!(min_sep >= 3.0, "closest pair {min_sep:.2} m");
    assert!(
        farthest < fence_radius,
        "{farthest} m outside the {fence_radius} m fence"
    );
    let (status, body) = skein.delete("/api/v1/formation");
    assert!(status < 300, "{body}");
}

/// The track over the whole pass: confirmed, one id, RMSE under 3 m, kept in view while
/// observed, and followed far past the first view.
fn check_the_record(id: &str, to_confirm: Duration, record: &TrackRecord, observed: Observed) {
    let Observed {
        in_view,
        samples,
        widest_deg,
    } = observed;
    let TrackRecord {
        errors,
        ids: ids_seen,
    } = record;
    let rmse = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    println!(
        "tracking: confirmed {id} {:.2} s after the intruder entered both views; RMSE {rmse:.2} m \
         over {} samples (max {:.2} m); ids {ids_seen:?}; observed: in both views {in_view}/{samples} \
         samples, up to {widest_deg:.0} deg off the cameras' first axis",
        to_confirm.as_secs_f64(),
        errors.len(),
        errors.iter().cloned().fold(0.0, f64::max)
    );
    assert!(errors.len() >= 10, "{} samples", errors.len());
    assert!(rmse < 3.0, "RMSE {rmse:.2} m: {errors:?}");
    assert_eq!(ids_seen.len(), 1, "one track for the pass: {ids_seen:?}");
    assert!(
        in_view * 10 >= samples * 9,
        "in view {in_view}/{samples} while observed"
    );
    // Half the camera's 75° view is 37.6°: without the gimbals following, it would be gone.
    assert!(
        widest_deg > 45.0,
        "the intruder never went far: {widest_deg:.0}°"
    );
}

/// The stream said so too, and the metrics count it.
fn check_stream_and_metrics(skein: &Skein, stream: &EventLog, id: &str) {
    let on_stream: Vec<Value> = stream.of_type("track_confirmed");
    assert!(
        on_stream.iter().any(|e| e["track"]["id"] == id),
        "track_confirmed of {id} on the stream: {on_stream:?}"
    );
    assert!(
        !stream.of_type("detections").is_empty() || !stream.of_type("payload_event").is_empty()
    );
    let (_, metrics) = skein.get("/metrics");
    let text = metrics.as_str().unwrap_or_default();
    assert!(
        text.contains("skein_tracker{what=\"tracks_confirmed\"}"),
        "{text}"
    );
    let excluded = text
        .lines()
        .find(|l| l.starts_with("skein_tracker{what=\"bearings_excluded_members\"}"))
        .and_then(|l| l.rsplit(' ').next())
        .and_then(|v| v.parse::<f64>().ok())
        .unwrap_or(0.0);
    println!("tracking: bearings on swarm members excluded: {excluded}");
}

fn horizontal(a: [f64; 3], b: [f64; 3]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}
