//! The hostile-swarm scenarios of `skein bench tracking --scenario NAME`: five intruders
//! flying `formation` (a V), `formation_zigzag` (a weaving V), `crossing` (a V of three and
//! a V of two crossing at right angles) or `split` (a V whose right arm breaks away), on a
//! straight pass southward 50 m east of the swarm, 15 m up, at 5 m/s, from 150 m out.
//!
//! Each scenario is flown twice on the same seed, side by side in one report: `fixed`
//! (the observers stay where they started, in their line; their gimbals follow the swarms
//! they observe) and `geometry` (they fly to the stations that fix the swarms best,
//! `POST /api/v1/swarms/{id}/observe` with `"stations": true`). In both, as soon as the
//! tracker recognises swarms the bench observes the first two (by id) with the four
//! observation UAVs, shared round-robin, and again whenever the swarms change; with none
//! left the gimbals turn back to their first view (north and south), and the observers
//! return to the formation. `rmse_reduction` is `1 − geometry / fixed` of the track RMSE.

use super::TrackingBenchArgs;
use crate::up_process::UpProcess;
use serde_json::{Value, json};
use std::collections::BTreeMap;

/// The observation UAVs of the bench's scene, and where their cameras look at first
/// (earth-frame yaw, degrees).
pub(super) const CAMERAS: [(&str, f64); 4] = [
    ("uav-1", 0.0),
    ("uav-3", 0.0),
    ("uav-2", 180.0),
    ("uav-4", 180.0),
];

/// The scenarios.
pub const SCENARIOS: [&str; 4] = ["formation", "formation_zigzag", "crossing", "split"];

/// How the observers observe.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Held where they started, gimbals following.
    Fixed,
    /// Flown to the stations that fix the swarm best.
    Geometry,
}

impl Mode {
    /// `fixed` or `geometry`.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Fixed => "fixed",
            Mode::Geometry => "geometry",
        }
    }
}

/// The intruders' arguments of `skein up` for scenario `name`.
pub(super) fn intruder_args(name: &str) -> Vec<&'static str> {
    let pattern = match name {
        "formation" => "formation",
        "formation_zigzag" => "formation_zigzag",
        "crossing" => "crossing",
        _ => "split",
    };
    vec![
        "--intruders",
        "5",
        "--intruder-pattern",
        pattern,
        "--intruder-heading-deg",
        "180",
        "--intruder-cpa-m",
        "50",
        "--intruder-range-m",
        "150",
        "--intruder-altitude-m",
        "15",
    ]
}

/// Points the cameras where they look at first.
pub(super) fn point_cameras(up: &UpProcess) -> Result<(), String> {
    for (v, yaw) in CAMERAS {
        up.call(
            "POST",
            &format!("/api/v1/vehicles/{v}/payloads/gimbal"),
            Some(json!({"command": "set_angles", "pitch_deg": 4.0, "yaw_deg": yaw, "yaw_frame": "earth"})),
        )?;
    }
    Ok(())
}

/// Who observes which swarm, kept up to date with the swarms the tracker lists.
pub(super) struct Observer {
    mode: Mode,
    assigned: BTreeMap<String, Vec<String>>,
    requests: u64,
    refused: Vec<String>,
    angles: Vec<f64>,
    sigmas: Vec<f64>,
}

impl Observer {
    pub(super) fn new(mode: Mode) -> Self {
        Observer {
            mode,
            assigned: BTreeMap::new(),
            requests: 0,
            refused: Vec::new(),
            angles: Vec::new(),
            sigmas: Vec::new(),
        }
    }

    /// Observes the first two of `swarms` (as `GET /api/v1/swarms` lists them); returns
    /// whether some swarm is observed now.
    pub(super) fn manage(&mut self, up: &UpProcess, swarms: &[Value]) -> Result<bool, String> {
        let mut ids: Vec<&str> = swarms.iter().filter_map(|s| s["id"].as_str()).collect();
        ids.truncate(2);
        let mut wanted: BTreeMap<String, Vec<String>> = BTreeMap::new();
        if !ids.is_empty() {
            for (j, (v, _)) in CAMERAS.iter().enumerate() {
                wanted
                    .entry(ids[j % ids.len()].to_string())
                    .or_default()
                    .push(v.to_string());
            }
        }
        for s in swarms {
            if let Some(st) = s["stations"].as_object() {
                self.angles
                    .extend(st.get("triangulation_angle_deg").and_then(Value::as_f64));
                self.sigmas
                    .extend(st.get("predicted_sigma_m").and_then(Value::as_f64));
            }
        }
        if wanted == self.assigned {
            return Ok(!wanted.is_empty());
        }
        if wanted.is_empty() {
            point_cameras(up)?;
        }
        for (swarm, vehicles) in &wanted {
            self.requests += 1;
            let body = json!({"vehicles": vehicles, "stations": self.mode == Mode::Geometry});
            if let Err(e) = up.call(
                "POST",
                &format!("/api/v1/swarms/{swarm}/observe"),
                Some(body),
            ) {
                // The swarm was lost meanwhile, or no stations met the limits.
                self.refused.push(e);
            }
        }
        self.assigned = wanted;
        Ok(!self.assigned.is_empty())
    }

    /// The `observation` object of the report.
    pub(super) fn report(&self) -> Value {
        let mean = |v: &[f64]| (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64);
        json!({
            "mode": self.mode.name(),
            "observe_requests": self.requests,
            "refused": self.refused,
            "triangulation_angle_deg_mean": mean(&self.angles),
            "predicted_sigma_m_mean": mean(&self.sigmas),
        })
    }
}

/// Flies scenario `name` in each mode of `modes` on the same seed; the report puts them
/// side by side.
///
/// # Errors
/// An unknown scenario, or a failed run.
pub(super) fn run(args: &TrackingBenchArgs, name: &str, modes: &[Mode]) -> Result<Value, String> {
    if !SCENARIOS.contains(&name) {
        return Err(format!(
            "unknown scenario {name:?} ({})",
            SCENARIOS.join(", ")
        ));
    }
    let mut out = json!({"scenario": name, "seed": args.seed, "seconds": args.seconds});
    for mode in modes {
        eprintln!("bench tracking: scenario {name}, observers {}", mode.name());
        let mut run = args.clone();
        run.trace = args.trace.as_ref().map(|p| {
            let mut p = p.clone().into_os_string();
            p.push(format!(".{}", mode.name()));
            p.into()
        });
        out[mode.name()] = super::fly(&run, Some((name, *mode)))?;
    }
    let rmse = |m: &str| out[m]["tracks"]["rmse_m"].as_f64();
    if let (Some(f), Some(g)) = (rmse("fixed"), rmse("geometry")) {
        out["rmse_reduction"] = json!(1.0 - g / f);
    }
    let observed = |m: &str| out[m]["swarms"]["rmse_observed_m"].as_f64();
    if let (Some(f), Some(g)) = (observed("fixed"), observed("geometry")) {
        out["rmse_observed_reduction"] = json!(1.0 - g / f);
    }
    Ok(out)
}
