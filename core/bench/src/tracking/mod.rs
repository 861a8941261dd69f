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
//!
//! The track figures are computed in [`score`]; `--trace FILE` writes every sample, with
//! the detector frames, and `--replay FILE` runs the tracker again over such a trace
//! without flying ([`trace`]).
//!
//! `--scenario NAME` flies a hostile-swarm scenario instead of the mixed intruders
//! ([`scenario`]: a V of five, a weaving V, two Vs crossing, a V splitting), with the
//! observers fixed and then on observation stations, and adds the swarm figures
//! ([`swarm_score`]: time to recognition, membership precision and recall, forecast
//! errors at 5/10/20 s) to each run's report; a replay scores swarms and forecasts too.

mod scenario;
mod score;
mod swarm_score;
mod trace;

use crate::up_process::UpProcess;
use scenario::Mode;
use score::Scorer;
use serde_json::{Value, json};
use std::collections::{BTreeMap, HashMap};
use std::time::{Duration, Instant};
use swarm_score::SwarmScorer;

/// Arguments of `skein bench tracking`.
#[derive(clap::Args, Debug, Clone)]
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
    /// file, to see where a metric comes from (a scenario's runs: `FILE.fixed`,
    /// `FILE.geometry`).
    #[arg(long, value_name = "FILE")]
    pub trace: Option<std::path::PathBuf>,
    /// Fly nothing: replay a `--trace` file's detector frames through a fresh tracker and
    /// print its track figures (see `core/bench/src/tracking/trace.rs`); with `--trace`, write the
    /// replay's samples there.
    #[arg(long, value_name = "FILE")]
    pub replay: Option<std::path::PathBuf>,
    /// A hostile-swarm scenario (formation, formation_zigzag, crossing, split), flown with
    /// fixed observers and with observation geometry on the same seed.
    #[arg(long, value_name = "NAME")]
    pub scenario: Option<String>,
    /// With `--scenario`: only one of its runs, `fixed` or `geometry`.
    #[arg(long, value_name = "MODE")]
    pub observation: Option<String>,
}

/// `skein up` with the bench's scene (4 observation UAVs, seeded intruders; a scenario's
/// when `scene` names one).
fn start(args: &TrackingBenchArgs, scene: Option<&str>) -> Result<UpProcess, String> {
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
    ];
    match scene {
        Some(name) => a.extend(scenario::intruder_args(name)),
        None => a.extend([
            "--intruders",
            &intruders,
            "--intruder-range-m",
            "80",
            "--intruder-altitude-m",
            "15",
        ]),
    }
    let dir = args
        .plugin_dir
        .as_ref()
        .map(|d| d.to_string_lossy().into_owned());
    if let Some(d) = &dir {
        a.extend(["--plugin-dir", d]);
    }
    UpProcess::start(&a)
}

/// The state of a vehicle's payload in `slot`, from `GET /api/v1/vehicles`.
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

/// The `--trace` file, created.
fn trace_file(
    args: &TrackingBenchArgs,
) -> Result<Option<std::io::BufWriter<std::fs::File>>, String> {
    let Some(p) = &args.trace else {
        return Ok(None);
    };
    let file = std::fs::File::create(p).map_err(|e| format!("{}: {e}", p.display()))?;
    Ok(Some(std::io::BufWriter::new(file)))
}

/// Runs the benchmark (blocking: HTTP polling of a child `skein up`).
pub fn tracking(args: &TrackingBenchArgs) -> Result<Value, String> {
    if let Some(path) = &args.replay {
        let mut file = trace_file(args)?;
        let out = file.as_mut().map(|f| f as &mut dyn std::io::Write);
        let config = skein_swarm::tracking::TrackerConfig::default();
        let (tracks, swarms) = trace::replay(path, config, out)?;
        return Ok(
            json!({"replay": path.display().to_string(), "tracks": tracks, "swarms": swarms}),
        );
    }
    let Some(name) = &args.scenario else {
        return fly(args, None);
    };
    let modes = match args.observation.as_deref() {
        None => vec![Mode::Fixed, Mode::Geometry],
        Some("fixed") => vec![Mode::Fixed],
        Some("geometry") => vec![Mode::Geometry],
        Some(other) => {
            return Err(format!("unknown --observation {other:?} (fixed, geometry)"));
        }
    };
    scenario::run(args, name, &modes)
}

/// One flight: the mixed intruders (`scene` `None`), or a scenario with its observers in
/// a mode.
fn fly(args: &TrackingBenchArgs, scene: Option<(&str, Mode)>) -> Result<Value, String> {
    let up = start(args, scene.map(|s| s.0))?;
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
    scenario::point_cameras(&up)?;
    std::thread::sleep(Duration::from_secs(5));
    eprintln!("bench tracking: flying, measuring {} s", args.seconds);

    let start = Instant::now();
    let mut tally = Tally::default();
    let mut last_frame: HashMap<String, u64> = HashMap::new();
    let mut scorer = Scorer::default();
    let mut swarm_scorer = SwarmScorer::default();
    let mut observer = scene.map(|(_, mode)| scenario::Observer::new(mode));
    let mut trace = trace_file(args)?;
    while start.elapsed().as_secs_f64() < args.seconds {
        let t = start.elapsed().as_secs_f64();
        let vehicles = up.get("/api/v1/vehicles")?;
        let now_us = skein_swarm::tracking::now_us();
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
        let swarms = up.get("/api/v1/swarms")?["swarms"]
            .as_array()
            .cloned()
            .unwrap_or_default();
        let assigned = scorer.sample(t, &truth, &viewers, &tracks);
        let observing = match observer.as_mut() {
            Some(o) => o.manage(&up, &swarms)?,
            None => false,
        };
        swarm_scorer.sample(t, &truth, &assigned, &tracks, &swarms, observing);
        if let Some(w) = trace.as_mut() {
            use std::io::Write;
            let line = trace::trace_line(t, now_us, &vs, &truth, &viewers, &tracks, &swarms);
            writeln!(w, "{line}").map_err(|e| format!("trace: {e}"))?;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    let ratio = |a: u64, b: u64| {
        if b == 0 {
            Value::Null
        } else {
            json!(a as f64 / b as f64)
        }
    };
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
        "tracks": scorer.report(),
        "swarms": swarm_scorer.report(),
        "observation": observer.map(|o| o.report()),
    }))
}
