//! Traces of `skein bench tracking` and their replay through the tracker.
//!
//! With `--trace FILE` the bench writes one JSON line per sample: `t_s` (seconds into the
//! measurement), `now_us` (wall clock when the vehicles were read), `truth` (as
//! `GET /api/v1/sim/truth` answered), `viewers` (cameras drawing each intruder), `tracks`
//! (as `GET /api/v1/tracks` listed them), `members` (each vehicle's id, swarm-frame NED
//! position and velocity) and `detectors` (per observation UAV, its detector's payload state reduced
//! to `recent`, the frames of the last half second: at 5 Hz sampling every frame is in
//! some line).
//!
//! `skein bench tracking --replay FILE` runs a fresh [`Tracker`] over the trace's detector
//! frames instead of flying: it steps at [`TRACKER_HZ`] on the frames' clock, each frame
//! delivered [`DELIVERY_US`] after its capture, with the members' positions of the latest
//! sample, forecasts its tracks and groups them into swarms ([`AirPicture`]) at each step
//! as the live tracker does, and scores its tracks and swarms at every sample's time
//! against the recorded truth, from [`WARM_UP_S`] after the first frame on. (Lines also
//! carry the live `swarms`, for reference.) The same trace always gives the same figures,
//! so a change of the tracker can be measured on the flights that showed a problem, in
//! seconds and without the simulator's run-to-run variation.

use super::score::Scorer;
use super::swarm_score::SwarmScorer;
use serde_json::{Value, json};
use skein_swarm::tracking::detection::{self, parse_detections};
use skein_swarm::tracking::{
    AirPicture, GroupingConfig, MemberPose, TRACKER_HZ, Tracker, TrackerConfig,
};
use std::collections::{BTreeMap, HashMap};
use std::io::{BufRead, Write};

/// Assumed time from a frame's capture to the tracker's reading it, µs (the detector's
/// processing and the payload state's publication).
pub const DELIVERY_US: u64 = 50_000;

/// The replay scores no sample in the first seconds after the trace's first frame: its
/// tracker starts there with no track, where the live one had tracked through the
/// bench's warm-up.
pub const WARM_UP_S: f64 = 3.0;

/// One trace line (see the module docs) from one sample of the live bench.
pub(super) fn trace_line(
    t_s: f64,
    now_us: u64,
    vehicles: &[Value],
    truth: &Value,
    viewers: &BTreeMap<String, usize>,
    tracks: &[Value],
    swarms: &[Value],
) -> Value {
    let members: Vec<Value> = vehicles
        .iter()
        .filter(|v| v["position"].is_object())
        .map(|v| json!({"id": v["id"], "position": v["position"], "velocity": v["velocity"]}))
        .collect();
    let detectors: BTreeMap<String, Value> = vehicles
        .iter()
        .filter_map(|v| {
            let id = v["id"].as_str()?.to_string();
            let state = super::payload_state(v, "detector")?;
            Some((id, json!({"recent": state["recent"]})))
        })
        .collect();
    json!({"t_s": t_s, "now_us": now_us, "truth": truth, "viewers": viewers,
        "tracks": tracks, "swarms": swarms, "members": members, "detectors": detectors})
}

struct Sample {
    t_s: f64,
    now_us: u64,
    truth: Value,
    viewers: BTreeMap<String, usize>,
    members: Vec<MemberPose>,
}

/// A detector frame of a trace: capture time µs, observer vehicle id, the frame.
type TracedFrame = (u64, String, Value);

/// Reads a trace: its samples in order, and every detector frame once (as
/// [`detection::new_frames`] gives them to the live tracker), oldest first.
fn read(path: &std::path::Path) -> Result<(Vec<Sample>, Vec<TracedFrame>), String> {
    let file = std::fs::File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut samples = Vec::new();
    let mut frames = Vec::new();
    let mut newest: HashMap<String, u64> = HashMap::new();
    for (n, line) in std::io::BufReader::new(file).lines().enumerate() {
        let line = line.map_err(|e| format!("{}: {e}", path.display()))?;
        let v: Value = serde_json::from_str(&line)
            .map_err(|e| format!("{} line {}: {e}", path.display(), n + 1))?;
        let (Some(t_s), Some(now_us)) = (v["t_s"].as_f64(), v["now_us"].as_u64()) else {
            return Err(format!(
                "{} line {}: no t_s or now_us (a trace of an older skein?)",
                path.display(),
                n + 1
            ));
        };
        // Read as the live tracker reads a detector's state: its frames newer than the
        // last one taken from that vehicle.
        for (id, state) in v["detectors"].as_object().into_iter().flatten() {
            for f in detection::new_frames(state, newest.get(id).copied()) {
                if let Some(n) = f["frame"].as_u64() {
                    newest.insert(id.clone(), n);
                }
                // A frame without a capture time sorts first and is counted as malformed.
                let stamp = f["stamp_us"].as_u64().unwrap_or(0);
                frames.push((stamp, id.clone(), f.clone()));
            }
        }
        let members = v["members"]
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(|m| {
                let p = super::score::ned(&m["position"])?;
                // Traces of older benches have no velocity: at rest.
                let v = &m["velocity"];
                let v = [
                    v["north_m_s"].as_f64().unwrap_or(0.0),
                    v["east_m_s"].as_f64().unwrap_or(0.0),
                    v["down_m_s"].as_f64().unwrap_or(0.0),
                ];
                Some(MemberPose {
                    id: m["id"].as_str()?.to_string(),
                    position: nalgebra::Vector3::from(p),
                    velocity: nalgebra::Vector3::from(v),
                })
            })
            .collect();
        let viewers = serde_json::from_value(v["viewers"].clone()).unwrap_or_default();
        samples.push(Sample {
            t_s,
            now_us,
            truth: v["truth"].clone(),
            viewers,
            members,
        });
    }
    frames.sort_by_key(|f| f.0);
    Ok((samples, frames))
}

/// Replays the trace at `path` (see the module docs); returns the report's `tracks` object
/// with the replay's counters, and its `swarms` object. With `out`, writes the replay's own trace there (the lines
/// of the input with the replayed tracks, without `members` and `detectors`).
///
/// # Errors
/// The file cannot be read, or a line is not a trace line; `out` cannot be written.
pub fn replay(
    path: &std::path::Path,
    config: TrackerConfig,
    mut out: Option<&mut dyn std::io::Write>,
) -> Result<(Value, Value), String> {
    let (samples, frames) = read(path)?;
    let (Some(first), Some(last)) = (frames.first(), samples.last()) else {
        return Err(format!("{}: no detector frames", path.display()));
    };
    let period_us = (1e6 / TRACKER_HZ) as u64;
    let mut tracker = Tracker::new(config);
    let mut picture = AirPicture::new(GroupingConfig::default());
    let mut scorer = Scorer::default();
    let mut swarm_scorer = SwarmScorer::default();
    // The picture as of the latest step, scored at each sample.
    let (mut tracks_now, mut swarms_now): (Vec<Value>, Vec<Value>) = (Vec::new(), Vec::new());
    let mut step_us = first.0 + period_us;
    let warm_up_us = first.0 + (WARM_UP_S * 1e6) as u64;
    let (mut next_frame, mut malformed) = (0, 0u64);
    let mut members: &[MemberPose] = &[];
    let mut sample_i = 0;
    while step_us <= last.now_us + period_us {
        while sample_i < samples.len() && samples[sample_i].now_us <= step_us {
            let s = &samples[sample_i];
            members = &s.members;
            // Tracks as of the sample's time; their forecasts and swarms as of the last
            // step (at most one step older).
            let tracks: Vec<Value> = tracker
                .tracks(s.now_us)
                .into_iter()
                .map(|t| serde_json::to_value(t).unwrap_or(Value::Null))
                .collect();
            if s.now_us >= warm_up_us {
                let assigned = scorer.sample(s.t_s, &s.truth, &s.viewers, &tracks);
                swarm_scorer.sample(s.t_s, &s.truth, &assigned, &tracks_now, &swarms_now, false);
            }
            if let Some(w) = out.as_mut() {
                let line = json!({"t_s": s.t_s, "now_us": s.now_us, "truth": s.truth,
                    "viewers": s.viewers, "tracks": tracks, "swarms": swarms_now});
                writeln!(w, "{line}").map_err(|e| format!("trace: {e}"))?;
            }
            sample_i += 1;
        }
        let mut bearings = Vec::new();
        while next_frame < frames.len() && frames[next_frame].0 + DELIVERY_US <= step_us {
            let (_, id, f) = &frames[next_frame];
            match parse_detections(id, f) {
                Ok(rays) => bearings.extend(rays),
                Err(_) => malformed += 1,
            }
            next_frame += 1;
        }
        tracker.step(step_us, bearings, members);
        let mut tracks = tracker.tracks(step_us);
        let (swarms, _) = picture.update(step_us, &mut tracks);
        tracks_now = tracks
            .into_iter()
            .map(|t| serde_json::to_value(t).unwrap_or(Value::Null))
            .collect();
        swarms_now = swarms
            .into_iter()
            .map(|s| serde_json::to_value(s).unwrap_or(Value::Null))
            .collect();
        step_us += period_us;
    }
    let mut report = scorer.report();
    report["replay"] = json!({
        "samples": samples.len(),
        "warm_up_s": WARM_UP_S,
        "frames": frames.len(),
        "malformed_frames": malformed,
        "tracker": serde_json::to_value(tracker.counters()).unwrap_or(Value::Null),
    });
    Ok((report, swarm_scorer.report()))
}
