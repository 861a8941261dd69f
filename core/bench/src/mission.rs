//! `skein bench mission`: issue 49's rehearsal benchmark. A sortie of `--vehicles`
//! (default 8: the even ones observation UAVs, the last a reserve kept on the ground)
//! rehearsed in virtual time ([`skein_rehearse::rehearse`]): take off in turn, transit in
//! a wedge, sweep a 140 × 84 m area with the cameras (30 % overlap), patrol a 130 × 120 m
//! perimeter for `--patrol-s`, hold stations, land in turn; one intruder crosses during
//! the patrol (the intruder reaction sends two observers), and uav-3 starts at 40 % with
//! the low-battery reaction at 35 % (the reserve takes its place). It prints the
//! rehearsal's figures (those of `POST /api/v1/missions/{id}/rehearse`, without the
//! picture) with `mission_s` (the mission's duration), `wall_s` and `speed_factor`
//! (virtual over wall-clock seconds, boot included).

use crate::round;
use serde_json::{Value, json};
use skein_mission::MissionPlan;
use skein_mission::resolve;
use skein_mission::swarm::VehicleSetup;
use skein_rehearse::Scenario;

/// `skein bench mission`.
#[derive(clap::Args, Debug, Clone)]
pub struct MissionBenchArgs {
    /// Vehicles (3 to 20): uav-1 … uav-N, the last a reserve.
    #[arg(long, default_value_t = 8)]
    pub vehicles: usize,
    /// How long the patrol lasts, seconds of mission time (the default makes a sortie of
    /// about ten minutes).
    #[arg(long, default_value_t = 330.0)]
    pub patrol_s: f64,
    /// Seed of the simulated noise and the intruder's path.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Runs the benchmark (see the module docs).
///
/// # Errors
/// Arguments out of range, or a plan the rehearsal refuses.
pub fn mission(args: &MissionBenchArgs) -> Result<Value, String> {
    if !(3..=20).contains(&args.vehicles) {
        return Err(format!("--vehicles {}: 3 to 20", args.vehicles));
    }
    if !(args.patrol_s.is_finite() && args.patrol_s >= 1.0) {
        return Err(format!("--patrol-s {}: at least 1", args.patrol_s));
    }
    let n = args.vehicles;
    let plan = plan(n, args.patrol_s)?;
    let config = skein_swarm::SwarmConfig::default();
    skein_swarm::coordinator::missions::check_plan(&plan, &config, &config.geofence)
        .map_err(|e| format!("the plan: {}: {}", e.field, e.error))?;
    let spacing_m = 1.05 * std::f64::consts::SQRT_2 * config.setpoint_separation_m();
    let cols = (n as f64).sqrt().ceil() as usize;
    let vehicles: Vec<VehicleSetup> = (1..=n)
        .map(|i| {
            let model = if i % 2 == 0 { "observation" } else { "generic" };
            let m = config.model(model);
            VehicleSetup {
                id: format!("uav-{i}"),
                model: model.into(),
                home: skein_sim::spawn_offset(i - 1, cols, spacing_m.max(3.0)),
                limits: m.limits,
                battery_percent: (i == 3).then_some(40.0),
                battery_capacity_mah: None,
                observer: m.payloads.iter().any(|p| p.kind == "gimbal"),
            }
        })
        .collect();
    let members = skein_mission::swarm::members(&vehicles);
    let groups = resolve::groups(&plan, &members)
        .map_err(|e| format!("the plan: {}: {}", e.field, e.error))?;
    let swarm = skein_swarm::coordinator::missions::rehearsal_swarm(
        &config,
        config.geofence.clone(),
        skein_sim::PX4_SITL_HOME,
        vehicles,
    );
    let scenario: Scenario = serde_json::from_value(json!({
        "seed": args.seed,
        "intruders": {"count": 1, "pattern": "straight", "speed_m_s": 5, "altitude_m": 25,
                      "range_m": 150, "heading_deg": 90, "cpa_m": 40, "start_s": 150}
    }))
    .map_err(|e| e.to_string())?;
    let report =
        skein_rehearse::rehearse(&plan, groups, &swarm, &scenario).map_err(|e| e.to_string())?;
    let mut out = serde_json::to_value(&report).map_err(|e| e.to_string())?;
    if let Some(o) = out.as_object_mut() {
        o.remove("picture_svg");
        o.insert("vehicles".into(), json!(n));
        o.insert("mission_s".into(), json!(round(report.duration_s, 1)));
        o.insert("speed_factor".into(), json!(round(report.speed_factor, 1)));
    }
    Ok(out)
}

/// The sortie of `n` vehicles (the last a reserve) with a patrol of `patrol_s`.
fn plan(n: usize, patrol_s: f64) -> Result<MissionPlan, String> {
    let stations: Vec<[f64; 2]> = (0..n - 1).map(|k| [15.0, -30.0 + 9.0 * k as f64]).collect();
    serde_json::from_value(json!({
        "name": "bench sortie",
        "reactions": {
            "low_battery": {"below_percent": 35, "reserves": [format!("uav-{n}")]},
            "intruder": {"observers": 2}
        },
        "steps": [
            {"kind": "takeoff", "altitude_m": 10, "interval_s": 1},
            {"kind": "transit", "waypoints": [[30, 0]], "altitude_m": 15, "speed_m_s": 5,
             "formation": {"shape": "wedge", "spacing_m": 8}},
            {"kind": "survey", "polygon": [[40, -70], [40, 70], [124, 70], [124, -70]],
             "altitude_m": 15, "camera": {"hfov_deg": 60, "overlap": 0.3}},
            {"kind": "patrol", "route": [[0, -60], [130, -60], [130, 60], [0, 60]],
             "altitude_m": 18, "duration_s": patrol_s},
            {"kind": "station", "points": stations, "altitude_m": 12, "duration_s": 20},
            {"kind": "land", "interval_s": 1}
        ]
    }))
    .map_err(|e| format!("the plan: {e}"))
}
