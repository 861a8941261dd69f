//! `skein bench tracking`: the counter-UAS chain measured against the simulator's truth,
//! as the tracking literature measures it.
//!
//! 1. starts `skein up --sim 4 --sim-model observation --intruders 3` (this binary, its
//!    plugins from its own directory: build with `cargo build --release` first) on free
//!    ports, intruders on seeded mixed paths (straight, loiter, zig-zag) 15 m up;
//! 2. takes the four off to 10 m, flies them as a line (8 m spacing, virtual leader) and
//!    turns the cameras of uav-1 and uav-3 north, uav-2 and uav-4 south (two pairs with a
//!    16 m baseline across their view);
//! 3. samples the API at 5 Hz for `--seconds`: the truth (`GET /api/v1/sim/truth`), the
//!    tracks, and each camera's own account of what it drew next to its detector's last
//!    detections;
//! 4. prints one JSON object:
//!    - `detection`: per-frame `precision` and `recall` of the detectors (a detection is
//!      right when its centre lies within the drawn aircraft's radius + 3 px; frames where
//!      the detector's last frame is the camera's last frame), over swarm members and
//!      intruders alike (`frames`, `true_positives`, `false_positives`, `misses`);
//!    - intruders are matched to confirmed tracks one-to-one within 10 m, as CLEAR-MOT
//!      does (an intruder keeps its previous track while that one stays within 10 m;
//!      the rest go nearest first), so two intruders passing close by do not share one
//!      track and a track is not counted as switching back and forth between them;
//!    - `tracks`: `rmse_m` of the track matched to each intruder within 100 m of
//!      the swarm (`samples`), `time_to_confirm_s` (from the
//!      first sample with the intruder in two cameras' view to the first with a confirmed
//!      track within 5 m of it, the clock restarting when the intruder leaves every
//!      camera's view unconfirmed; per intruder, `null` when never),
//!      `id_switches` (changes of the track id matched to an intruder), of them
//!      `id_switches_in_view` (the intruder was in some camera's view at every sample since
//!      its previous match: the tracker had bearings to keep its id) and
//!      `reacquisitions` (it was out of every camera's view in between: a new id after a
//!      blind spot), both also per path kind in `id_switches_by_pattern`,
//!      `false_tracks` (confirmed tracks never matched to an intruder, duplicates
//!      included) and `false_track_longest_s`.

use super::up_process::UpProcess;
use serde_json::{Value, json};
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::time::{Duration, Instant};

/// Arguments of `skein bench tracking`.
#[derive(clap::Args, Debug)]
pub struct TrackingBenchArgs {
    /// Seconds of flight measured.
    #[arg(long, default_value_t = 120.0)]
    pub seconds: f64,
    /// Intruders.
    #[arg(long, default_value_t = 3)]
    pub intruders: usize,
    /// Seed of the simulator and the intruders' paths.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Plugin directory of the `skein up` it starts (default: this executable's).
    #[arg(long, value_name = "DIR")]
    pub plugin_dir: Option<std::path::PathBuf>,
    /// Also write every sample (the truth's intruders, the tracks) as JSON lines to this
    /// file, to see where a metric comes from.
    #[arg(long, value_name = "FILE")]
    pub trace: Option<std::path::PathBuf>,
}

/// `skein up` with the bench's scene (4 observation UAVs, seeded intruders).
fn start(args: &TrackingBenchArgs) -> Result<UpProcess, String> {
    let (seed, intruders) = (args.seed.to_string(), args.intruders.to_string());
    let mut a: Vec<&str> = vec![
        "--sim",
        "4",
        "--sim-model",
        "observation",
        "--sim-base-port",
        "0",
        "--sim-seed",
        &seed,
        "--intruders",
        &intruders,
        "--intruder-range-m",
        "80",
        "--intruder-altitude-m",
        "15",
    ];
    let dir = args
        .plugin_dir
        .as_ref()
        .map(|d| d.to_string_lossy().into_owned());
    if let Some(d) = &dir {
        a.extend(["--plugin-dir", d]);
    }
    UpProcess::start(&a)
}

fn ned(v: &Value) -> Option<[f64; 3]> {
    Some([
        v["north_m"].as_f64()?,
        v["east_m"].as_f64()?,
        v["down_m"].as_f64()?,
    ])
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

fn payload_state<'a>(v: &'a Value, slot: &str) -> Option<&'a Value> {
    v["payloads"]
        .as_array()?
        .iter()
        .find(|p| p["slot"] == slot)
        .map(|p| &p["state"])
}

#[derive(Default)]
struct Tally {
    frames: u64,
    tp: u64,
    fp: u64,
    misses: u64,
}

impl Tally {
    /// Scores one frame: the detector's detections against what the camera drew.
    fn frame(&mut self, camera: &Value, detections: &[Value]) {
        let (w, h) = (
            camera["width_px"].as_f64().unwrap_or(0.0),
            camera["height_px"].as_f64().unwrap_or(0.0),
        );
        let drawn: Vec<(f64, f64, f64)> = camera["visible"]
            .as_array()
            .map(|a| {
                a.iter()
                    .filter_map(|v| {
                        Some((
                            v["x_px"].as_f64()?,
                            v["y_px"].as_f64()?,
                            v["radius_px"].as_f64()?,
                        ))
                    })
                    .filter(|(x, y, _)| (0.0..w).contains(x) && (0.0..h).contains(y))
                    .collect()
            })
            .unwrap_or_default();
        let mut found = vec![false; drawn.len()];
        for d in detections {
            let (Some(x), Some(y)) = (d["center_px"]["x"].as_f64(), d["center_px"]["y"].as_f64())
            else {
                continue;
            };
            match drawn
                .iter()
                .position(|(ax, ay, r)| (ax - x).hypot(ay - y) <= r + 3.0)
            {
                Some(i) => {
                    self.tp += 1;
                    found[i] = true;
                }
                None => self.fp += 1,
            }
        }
        self.misses += found.iter().filter(|f| !**f).count() as u64;
        self.frames += 1;
    }
}

/// Intruders matched one-to-one to confirmed tracks within 10 m, as CLEAR-MOT does: an
/// intruder keeps its previous track while that one is still within the gate and not
/// taken; the others go to the nearest free track, closest pairs first. Returns intruder
/// id → (track id, distance m).
fn assign(
    intruders: &[(String, [f64; 3])],
    confirmed: &[(String, [f64; 3])],
    previous: &BTreeMap<String, Option<String>>,
) -> BTreeMap<String, (String, f64)> {
    const GATE_M: f64 = 10.0;
    let mut out: BTreeMap<String, (String, f64)> = BTreeMap::new();
    let mut taken: BTreeSet<&str> = BTreeSet::new();
    for (iid, p) in intruders {
        if let Some(Some(prev)) = previous.get(iid)
            && let Some((tid, q)) = confirmed.iter().find(|(t, _)| t == prev)
            && dist(*p, *q) <= GATE_M
            && taken.insert(tid.as_str())
        {
            out.insert(iid.clone(), (tid.clone(), dist(*p, *q)));
        }
    }
    let mut pairs: Vec<(f64, &String, &String)> = intruders
        .iter()
        .filter(|(iid, _)| !out.contains_key(iid))
        .flat_map(|(iid, p)| {
            confirmed
                .iter()
                .map(move |(tid, q)| (dist(*p, *q), iid, tid))
        })
        .filter(|(d, _, tid)| *d <= GATE_M && !taken.contains(tid.as_str()))
        .collect();
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    for (d, iid, tid) in pairs {
        if out.contains_key(iid) || taken.contains(tid.as_str()) {
            continue;
        }
        taken.insert(tid.as_str());
        out.insert(iid.clone(), (tid.clone(), d));
    }
    out
}

/// Runs the benchmark (blocking: HTTP polling of a child `skein up`).
pub fn tracking(args: &TrackingBenchArgs) -> Result<Value, String> {
    let up = start(args)?;
    eprintln!("bench tracking: skein up at {}", up.base);
    up.wait_vehicles(
        4,
        "4 vehicles with positions",
        Duration::from_secs(60),
        |v| v["link"]["connected"] == true && v["position"].is_object(),
    )?;
    up.call(
        "POST",
        "/api/v1/swarm/commands",
        Some(json!({"command": "takeoff", "altitude_m": 10.0})),
    )?;
    up.wait_vehicles(4, "4 vehicles hovering", Duration::from_secs(90), |v| {
        v["state"] == "Hovering"
    })?;
    up.call(
        "PUT",
        "/api/v1/formation",
        Some(json!({"shape": "line", "spacing_m": 8.0, "leader": "virtual", "altitude_m": 10.0})),
    )?;
    for (v, yaw) in [
        ("uav-1", 0.0),
        ("uav-3", 0.0),
        ("uav-2", 180.0),
        ("uav-4", 180.0),
    ] {
        up.call(
            "POST",
            &format!("/api/v1/vehicles/{v}/payloads/gimbal"),
            Some(json!({"command": "set_angles", "pitch_deg": 4.0, "yaw_deg": yaw, "yaw_frame": "earth"})),
        )?;
    }
    std::thread::sleep(Duration::from_secs(5));
    eprintln!("bench tracking: flying, measuring {} s", args.seconds);

    let start = Instant::now();
    let mut tally = Tally::default();
    let mut last_frame: HashMap<String, u64> = HashMap::new();
    let mut sq_err = Vec::new();
    let mut in_view_since: BTreeMap<String, f64> = BTreeMap::new();
    let mut confirmed_after: BTreeMap<String, Option<f64>> = BTreeMap::new();
    let mut matched: BTreeMap<String, Option<String>> = BTreeMap::new();
    let mut switches = 0u64;
    // Per intruder: out of every camera's view since its last match.
    let mut unseen_since_match: BTreeMap<String, bool> = BTreeMap::new();
    // Per path kind: (switches in view, reacquisitions).
    let mut by_pattern: BTreeMap<String, (u64, u64)> = BTreeMap::new();
    let mut confirmed_seen: BTreeMap<String, (f64, f64)> = BTreeMap::new();
    let mut near_intruder: BTreeSet<String> = BTreeSet::new();
    let mut trace = match &args.trace {
        Some(p) => Some(std::io::BufWriter::new(
            std::fs::File::create(p).map_err(|e| format!("{}: {e}", p.display()))?,
        )),
        None => None,
    };
    while start.elapsed().as_secs_f64() < args.seconds {
        let t = start.elapsed().as_secs_f64();
        let vehicles = up.get("/api/v1/vehicles")?;
        let tracks = up.get("/api/v1/tracks")?["tracks"]
            .as_array()
            .cloned()
            .unwrap_or_default();
        let truth = up.get("/api/v1/sim/truth")?;
        let vs = vehicles.as_array().cloned().unwrap_or_default();
        // Detection, per new frame whose camera account matches.
        let mut viewers: BTreeMap<String, usize> = BTreeMap::new();
        for v in &vs {
            let id = v["id"].as_str().unwrap_or("?").to_string();
            let (Some(cam), Some(det)) = (payload_state(v, "camera"), payload_state(v, "detector"))
            else {
                continue;
            };
            for a in cam["visible"].as_array().into_iter().flatten() {
                if a["intruder"] == true {
                    *viewers
                        .entry(a["id"].as_str().unwrap_or("?").to_string())
                        .or_default() += 1;
                }
            }
            let frame = det["last"]["frame"].as_u64();
            if frame.is_some()
                && frame == cam["frames"].as_u64()
                && last_frame.get(&id) != frame.as_ref()
            {
                last_frame.insert(id, frame.unwrap_or(0));
                let dets = det["last"]["detections"]
                    .as_array()
                    .cloned()
                    .unwrap_or_default();
                tally.frame(cam, &dets);
            }
        }
        // Tracks against the truth.
        let members: Vec<[f64; 3]> = truth["vehicles"]
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(ned)
            .collect();
        let centre = members
            .iter()
            .fold([0.0; 3], |c, p| [c[0] + p[0], c[1] + p[1], c[2] + p[2]]);
        let centre = centre.map(|c| c / members.len().max(1) as f64);
        let confirmed: Vec<(String, [f64; 3])> = tracks
            .iter()
            .filter(|t| t["status"] == "confirmed")
            .filter_map(|t| Some((t["id"].as_str()?.to_string(), ned(&t["position"])?)))
            .collect();
        for (id, _) in &confirmed {
            let e = confirmed_seen.entry(id.clone()).or_insert((t, t));
            e.1 = t;
        }
        let intruders: Vec<(String, [f64; 3])> = truth["intruders"]
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(|i| Some((i["id"].as_str()?.to_string(), ned(i)?)))
            .collect();
        let assigned = assign(&intruders, &confirmed, &matched);
        for i in truth["intruders"].as_array().into_iter().flatten() {
            let (Some(iid), Some(p)) = (i["id"].as_str(), ned(i)) else {
                continue;
            };
            let nearest = assigned.get(iid).map(|(id, d)| (id, *d));
            if let Some((id, _)) = nearest {
                near_intruder.insert(id.clone());
            }
            let views = viewers.get(iid).copied().unwrap_or(0);
            let pattern = i["pattern"].as_str().unwrap_or("?").to_string();
            let kind = by_pattern.entry(pattern).or_default();
            if confirmed_after.get(iid).is_none_or(Option::is_none) {
                if views >= 2 {
                    in_view_since.entry(iid.to_string()).or_insert(t);
                    confirmed_after.entry(iid.to_string()).or_insert(None);
                } else if views == 0 {
                    // Out of every camera's view, still unconfirmed: the clock restarts
                    // when it is next in two views.
                    in_view_since.remove(iid);
                }
                if let Some(&t_in) = in_view_since.get(iid)
                    && nearest.is_some_and(|(_, d)| d <= 5.0)
                {
                    confirmed_after.insert(iid.to_string(), Some(t - t_in));
                }
            }
            let unseen = unseen_since_match.entry(iid.to_string()).or_insert(false);
            if views == 0 {
                *unseen = true;
            }
            let within = dist(p, centre) <= 100.0;
            if let Some((id, d)) = nearest.filter(|(_, d)| *d <= 10.0) {
                if within {
                    sq_err.push(d * d);
                }
                let last = matched.entry(iid.to_string()).or_insert(None);
                if last.as_ref().is_some_and(|l| l != id) {
                    switches += 1;
                    if *unseen {
                        kind.1 += 1;
                    } else {
                        kind.0 += 1;
                    }
                }
                *last = Some(id.clone());
                *unseen = false;
            }
        }
        if let Some(w) = trace.as_mut() {
            use std::io::Write;
            let line = json!({"t_s": t, "intruders": truth["intruders"], "viewers": viewers,
                "centre": centre, "tracks": tracks});
            writeln!(w, "{line}").map_err(|e| format!("trace: {e}"))?;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    let false_tracks: Vec<(&String, f64)> = confirmed_seen
        .iter()
        .filter(|(id, _)| !near_intruder.contains(*id))
        .map(|(id, (a, b))| (id, b - a))
        .collect();
    let ratio = |a: u64, b: u64| {
        if b == 0 {
            Value::Null
        } else {
            json!(a as f64 / b as f64)
        }
    };
    let times: Vec<f64> = confirmed_after.values().flatten().copied().collect();
    Ok(json!({
        "seconds": args.seconds,
        "intruders": args.intruders,
        "seed": args.seed,
        "detection": {
            "frames": tally.frames,
            "true_positives": tally.tp,
            "false_positives": tally.fp,
            "misses": tally.misses,
            "precision": ratio(tally.tp, tally.tp + tally.fp),
            "recall": ratio(tally.tp, tally.tp + tally.misses),
        },
        "tracks": {
            "rmse_m": (!sq_err.is_empty()).then(|| (sq_err.iter().sum::<f64>() / sq_err.len() as f64).sqrt()),
            "samples": sq_err.len(),
            "time_to_confirm_s": confirmed_after,
            "time_to_confirm_max_s": times.iter().cloned().reduce(f64::max),
            "in_two_views": confirmed_after.len(),
            "id_switches": switches,
            "id_switches_in_view": by_pattern.values().map(|k| k.0).sum::<u64>(),
            "reacquisitions": by_pattern.values().map(|k| k.1).sum::<u64>(),
            "id_switches_by_pattern": by_pattern.iter().map(|(p, k)| {
                (p.clone(), json!({"in_view": k.0, "reacquisitions": k.1}))
            }).collect::<BTreeMap<_, _>>(),
            "confirmed_tracks": confirmed_seen.len(),
            "false_tracks": false_tracks.len(),
            "false_track_longest_s": false_tracks.iter().map(|f| f.1).reduce(f64::max),
        },
    }))
}
