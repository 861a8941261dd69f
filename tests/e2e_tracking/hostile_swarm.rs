//! The hostile-swarm half of `e2e_tracking` (see its module docs): a V of five on the
//! pass, one swarm of five tracks, observed from stations, followed by a formation.

use super::{Value, dist, horizontal, ned, seen_by_both, tracks_vs_truth};
use crate::support::counter_uas::{OBSERVERS, build_plugins, up_with_formation_pass};
use crate::support::{self, EventLog, Skein, one_at_a_time};
use serde_json::json;
use std::time::{Duration, Instant};

/// A V of five intruders passes 60 m east of the swarm at 2 m/s, seen by the two
/// observers once they stand 20 m apart north–south (from the spawn grid's 5 m, rays of
/// two aircraft of the V met at ghosts up to 130 m out, and the swarm was often whole on
/// neither pass): the tracker recognises one hostile swarm of five (one `swarm_detected` on the stream, `GET /api/v1/swarms` with
/// its shape and forecast). Observing it is refused naming the field for an unknown swarm
/// or a bad stand-off; then the two observation UAVs get stations at least the slot
/// distance apart, inside the geofence and beyond the stand-off, fly there and stay out of
/// the formation, with no pair of vehicles closer than 3 m and none outside the fence. A
/// formation may take the swarm as its leader.
///
/// The stations move with the swarm. At 4 m/s a swarm recognised past its closest approach
/// drags its stations south toward the fence, re-planned every second, and an observer
/// may still be chasing them when the swarm leaves view (2 of 3 runs on the 2-core
/// machine); at 2.5 m/s the observers kept up while the swarm was found early in its pass
/// (the cameras had tracked it since the set-up), but on a pass met fresh (see
/// `start_a_fresh_pass`) it is whole only 20-25 s into both views, and once it left
/// view before the observers reached their stations; at 2 m/s they keep up.
#[test]
fn a_formation_of_five_is_one_hostile_swarm_observed_from_stations() {
    let _serial = one_at_a_time();
    let dir = build_plugins("swarm-plugins");
    let skein = up_with_formation_pass(&dir, 2.0, 5);
    let stream = EventLog::connect(&skein.base);
    skein.take_off(4, 10.0);
    skein.spread_observers(20.0);
    skein.point_gimbals(&OBSERVERS, 90.0, 3.0);
    start_a_fresh_pass(&skein);
    let swarm = the_swarm_of_five(&skein);
    let id = swarm["id"].as_str().unwrap().to_string();
    check_the_swarm(&skein, &stream, &swarm, &id);
    observe_it(&skein, &id);
    let fence_radius = check_the_stations(&skein, &id);
    fly_to_the_stations(&skein, &id, fence_radius);
    follow_it(&skein, &id);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Starts the V's pass again and waits until what the cameras made of it before is gone.
fn start_a_fresh_pass(skein: &Skein) {
    // The V starts its pass now, 90 m out, whatever its phase when the set-up ended, so
    // the test always meets the same pass (before, it met the V wherever a set-up of
    // varying length left it: here tracked since the set-up and whole 0-4 s after the
    // gimbals pointed, with the set-up 30 s longer first grouped as two swarms for 13 s).
    skein.restart_intruders();
    // The tracks the cameras made during the set-up are deleted once unseen for a few
    // seconds (the V re-enters the view some 15 s after the restart), and a swarm of them
    // with them: the swarm found below is the pass's own. (Waiting only for no swarm to be
    // listed, the set-up's tracks once made a swarm just after: stations planned for
    // where they coasted to, and a swarm gone before the observers got there.)
    support::eventually(
        "the tracks and swarms seen before the restart deleted",
        Duration::from_secs(30),
        || {
            let (_, tracks) = skein.get("/api/v1/tracks");
            let (_, swarms) = skein.get("/api/v1/swarms");
            let listed = |v: &Value, k: &str| v[k].as_array().map_or(usize::MAX, Vec::len);
            if listed(&tracks, "tracks") == 0 && listed(&swarms, "swarms") == 0 {
                Ok(())
            } else {
                Err(format!("still listed: {tracks} {swarms}"))
            }
        },
    );
}

/// Waits for one swarm of five listed and returns it (`GET /api/v1/swarms`' entry),
/// printing how the swarms listed changed until then.
fn the_swarm_of_five(skein: &Skein) -> Value {
    // What the run saw at its best, for a failure's message: the most intruders both
    // cameras drew at once, the most tracks and confirmed tracks at once, the largest swarm.
    let mut best = [0usize; 4];
    // Every change of the swarms listed (ids and member counts), with the time since the
    // set-up's tracks were deleted: printed, and in a failure's message.
    let (pointed, mut history, mut last) = (Instant::now(), Vec::<String>::new(), String::new());
    let swarm = support::eventually(
        "one hostile swarm of five",
        Duration::from_secs(150),
        || {
            let (_, swarms) = skein.get("/api/v1/swarms");
            let list = swarms["swarms"].as_array().cloned().unwrap_or_default();
            match list
                .iter()
                .find(|s| s["members"].as_array().is_some_and(|m| m.len() == 5))
            {
                Some(s) => Ok(s.clone()),
                None => {
                    let listed: Vec<String> = list
                        .iter()
                        .map(|s| {
                            let n = s["members"].as_array().map_or(0, Vec::len);
                            format!("{} of {n}", s["id"].as_str().unwrap_or("?"))
                        })
                        .collect();
                    let listed = listed.join(", ");
                    if listed != last {
                        let at = pointed.elapsed().as_secs_f64();
                        history.push(format!("{at:.1} s: [{listed}]"));
                        println!("swarms: {at:.1} s: [{listed}]; {}", tracks_vs_truth(skein));
                        last = listed;
                    }
                    let largest = list
                        .iter()
                        .filter_map(|s| s["members"].as_array().map(Vec::len))
                        .max()
                        .unwrap_or(0);
                    let seen = seen_by_both(&skein.vehicles());
                    // What the tracker has, for the message: id, status, swarm, velocity σ.
                    let (_, tracks) = skein.get("/api/v1/tracks");
                    let all = tracks["tracks"].as_array().cloned().unwrap_or_default();
                    let confirmed = all.iter().filter(|t| t["status"] == "confirmed").count();
                    for (b, now) in best.iter_mut().zip([seen, all.len(), confirmed, largest]) {
                        *b = (*b).max(now);
                    }
                    let tracks: Vec<String> = all
                        .iter()
                        .map(|t| {
                            format!(
                                "{} {} {} σv {:.1}",
                                t["id"],
                                t["status"],
                                t["swarm"],
                                t["velocity_sigma_m_s"].as_f64().unwrap_or(f64::NAN)
                            )
                        })
                        .collect();
                    Err(format!(
                        "swarms {swarms}; tracks {tracks:?}; at best: {} intruders drawn by \
                         both cameras, {} tracks, {} confirmed, a swarm of {}; swarms listed \
                         {history:?}",
                        best[0], best[1], best[2], best[3]
                    ))
                }
            }
        },
    );
    println!(
        "swarms: found after {:.1} s; listed before {history:?}; at best {} intruders drawn by \
         both cameras, {} tracks, {} confirmed",
        pointed.elapsed().as_secs_f64(),
        best[0],
        best[1],
        best[2]
    );
    swarm
}

/// The swarm's shape and forecast, the only swarm listed, one `swarm_detected` of it on
/// `stream`, and five tracks in it.
fn check_the_swarm(skein: &Skein, stream: &EventLog, swarm: &Value, id: &str) {
    println!(
        "swarms: {id} of {} as a {} heading {:.0} deg, {:.1} m/s, forecast {}",
        swarm["members"],
        swarm["shape"],
        swarm["shape_heading_deg"],
        swarm["speed_m_s"],
        swarm["forecast"]
    );
    assert!(
        ["line", "wedge", "cluster"].contains(&swarm["shape"].as_str().unwrap_or("")),
        "{swarm}"
    );
    assert_eq!(
        swarm["forecast"].as_array().map(Vec::len),
        Some(3),
        "{swarm}"
    );
    // One swarm listed, announced by one swarm_detected (a pair of young tracks grouped
    // early and then lost would be a second one: printed, not failed).
    let (_, listed) = skein.get("/api/v1/swarms");
    assert_eq!(
        listed["swarms"].as_array().map(Vec::len),
        Some(1),
        "{listed}"
    );
    let detected = stream.of_type("swarm_detected");
    let of_it = detected.iter().filter(|e| e["swarm"]["id"] == id).count();
    assert_eq!(of_it, 1, "one swarm_detected of {id}: {detected:?}");
    println!("swarms: {} swarm_detected events in all", detected.len());
    let (_, tracks) = skein.get("/api/v1/tracks");
    let in_swarm = tracks["tracks"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|t| t["swarm"] == id)
        .count();
    assert_eq!(in_swarm, 5, "{tracks}");
}

/// Observing an unknown swarm or with a bad stand-off is refused naming the field; then
/// the observers take it.
fn observe_it(skein: &Skein, id: &str) {
    let (status, body) = skein.post("/api/v1/swarms/swarm-999/observe", json!({}));
    assert_eq!(
        (status, body["field"].as_str()),
        (404, Some("id")),
        "{body}"
    );
    let (status, body) = skein.post(
        &format!("/api/v1/swarms/{id}/observe"),
        json!({"standoff_m": 2.0}),
    );
    assert_eq!(
        (status, body["field"].as_str()),
        (400, Some("standoff_m")),
        "{body}"
    );
    let (status, body) = skein.post(&format!("/api/v1/swarms/{id}/observe"), json!({}));
    assert_eq!(status, 200, "{body}");
    assert_eq!(body["vehicles"], json!(OBSERVERS), "{body}");
}

/// The planned stations keep the stand-off, the slot distance and the fence; returns the
/// fence's radius, m.
fn check_the_stations(skein: &Skein, id: &str) -> f64 {
    // The stations keep the stand-off, the slot distance and the fence.
    let (_, fence) = skein.get("/api/v1/geofence");
    let fence_radius = fence["radius_m"].as_f64().unwrap_or(f64::INFINITY);
    let (_, swarms) = skein.get("/api/v1/swarms");
    let listed = swarms["swarms"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["id"] == id)
        .cloned()
        .expect("the swarm is still listed");
    assert_eq!(listed["observed_by"], json!(OBSERVERS), "{listed}");
    let st = &listed["stations"];
    let stations: Vec<(String, [f64; 3])> = st["stations"]
        .as_array()
        .expect("stations")
        .iter()
        .map(|s| {
            (
                s["vehicle"].as_str().unwrap().to_string(),
                ned(&s["position"]),
            )
        })
        .collect();
    assert_eq!(stations.len(), 2, "{st}");
    assert!(dist(stations[0].1, stations[1].1) >= 4.9, "{st}");
    let centroid = ned(&listed["centroid"]);
    for (_, p) in &stations {
        assert!(
            p[0].hypot(p[1]) <= fence_radius - 5.0,
            "{p:?} outside the fence"
        );
        assert!(
            horizontal(*p, centroid) >= 20.0,
            "{p:?} within the stand-off of {centroid:?}"
        );
    }
    println!(
        "swarms: stations {stations:?}, predicted sigma {:.2} m at {:.0} deg",
        st["predicted_sigma_m"].as_f64().unwrap_or(f64::NAN),
        st["triangulation_angle_deg"].as_f64().unwrap_or(f64::NAN)
    );
    fence_radius
}

/// The observers fly to their stations, never too close to another vehicle, never outside
/// the fence (`fence_radius`, m), never back into the formation.
fn fly_to_the_stations(skein: &Skein, id: &str, fence_radius: f64) {
    // The observers fly there (re-planned as the swarm moves), never too close to another
    // vehicle, never outside the fence, and not back into the formation meanwhile.
    let stats = skein.sim_stats_addr();
    let (mut min_sep, mut farthest) = (f64::INFINITY, 0.0f64);
    // Each observer's progress to its station: the smallest fraction left of the distance
    // it had when that station was planned (stations move as the swarm does), and when it
    // first got within 3 m of one or covered 70 % of the way to one.
    let mut progress: std::collections::BTreeMap<String, ([f64; 3], f64, f64, Option<f64>)> =
        std::collections::BTreeMap::new();
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(40) {
        let (_, truth) = skein.get("/api/v1/sim/truth");
        let (_, swarms) = skein.get("/api/v1/swarms");
        let now = swarms["swarms"]
            .as_array()
            .and_then(|l| l.iter().find(|s| s["id"] == id).cloned());
        let Some(now) = now else {
            break; // the swarm flew out of view: its observation ended
        };
        let vehicles = truth["vehicles"].as_array().unwrap();
        for v in vehicles {
            let p = ned(v);
            farthest = farthest.max(p[0].hypot(p[1]));
        }
        for s in now["stations"]["stations"].as_array().into_iter().flatten() {
            let vid = s["vehicle"].as_str().unwrap().to_string();
            let Some(v) = vehicles.iter().find(|v| v["id"] == vid) else {
                continue;
            };
            let station = ned(&s["position"]);
            let d = dist(ned(v), station);
            let e = progress
                .entry(vid)
                .or_insert((station, d.max(1e-9), 1.0, None));
            if dist(e.0, station) > 1.0 {
                // Planned again: progress toward the new one.
                (e.0, e.1) = (station, d.max(1e-9));
            }
            e.2 = e.2.min(d / e.1);
            if (d < 3.0 || d / e.1 < 0.3) && e.3.is_none() {
                e.3 = Some(start.elapsed().as_secs_f64());
            }
        }
        for v in skein.vehicles() {
            if OBSERVERS.contains(&v["id"].as_str().unwrap_or("")) {
                assert_ne!(
                    v["state"], "InFormation",
                    "an observer joined the formation: {v}"
                );
            }
        }
        min_sep = min_sep.min(support::truth_min_separation(&stats));
        if progress.len() == OBSERVERS.len() && progress.values().all(|c| c.3.is_some()) {
            break;
        }
        std::thread::sleep(Duration::from_millis(250));
    }
    println!(
        "swarms: observers' progress to their stations (station, distance when planned m, \
         least fraction left, s to arrival): {progress:?}; closest pair {min_sep:.2} m, \
         farthest vehicle {farthest:.0} m from the origin"
    );
    assert_eq!(progress.len(), OBSERVERS.len(), "{progress:?}");
    assert!(
        progress.values().all(|c| c.3.is_some()),
        "the observers never reached their stations: {progress:?}"
    );
    assert!(min_sep >= 3.0, "closest pair {min_sep:.2} m");
    assert!(
        farthest < fence_radius,
        "{farthest} m outside the {fence_radius} m fence"
    );
}

/// A formation may follow the swarm (while it is listed); an unknown one is refused naming
/// the field; then the observation ends.
fn follow_it(skein: &Skein, id: &str) {
    // A formation may follow the swarm; an unknown one is refused naming the field.
    let wedge = |leader: &str| json!({"shape": "wedge", "spacing_m": 7.0, "leader": leader, "altitude_m": 10.0, "standoff_m": 30.0});
    let (status, body) = skein.put("/api/v1/formation", wedge("swarm-999"));
    assert_eq!(
        (status, body["field"].as_str()),
        (400, Some("leader")),
        "{body}"
    );
    let (_, swarms) = skein.get("/api/v1/swarms");
    if swarms["swarms"]
        .as_array()
        .is_some_and(|l| l.iter().any(|s| s["id"] == id))
    {
        let (status, body) = skein.put("/api/v1/formation", wedge(id));
        assert_eq!(status, 200, "{body}");
        assert_eq!(body["leader"], json!(id), "{body}");
        let (status, body) = skein.delete("/api/v1/formation");
        assert!(status < 300, "{body}");
    }
    let (status, body) = skein.delete(&format!("/api/v1/swarms/{id}/observe"));
    assert_eq!(status, 200, "{body}");
}
