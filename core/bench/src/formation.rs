//! `skein bench formation`: formation flight in virtual time on the PX4-faithful
//! simulated multicopter (see [`formation`]).

use crate::round;
use serde_json::{Value, json};
use std::time::Instant;

/// `skein bench formation`.
#[derive(clap::Args, Debug, Clone)]
pub struct FormationBenchArgs {
    /// Swarm sizes to fly, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "8,32")]
    pub vehicles: Vec<usize>,
    /// Distance between neighbouring slots, m.
    #[arg(long, default_value_t = 6.0)]
    pub spacing_m: f64,
    /// Speed of the virtual leader on each leg and orbit, m/s.
    #[arg(long, default_value_t = 5.0)]
    pub speed_m_s: f64,
    /// What flies: `px4` (skein's PX4-faithful simulated multicopter, the default) or
    /// `point-mass` (the kinder model of the seeded transition sweeps).
    #[arg(long, default_value = "px4", value_parser = ["px4", "point-mass"])]
    pub airframe: String,
    /// PX4's hover wander on the simulated vehicles (seeded estimator noise).
    #[arg(long)]
    pub estimator_noise: bool,
}

/// `skein bench formation`: for each swarm size, every shape in turn behind a virtual
/// leader (set while it holds: time to converge, until no transition is in flight and the
/// RMS slot error is under 0.2 m; 0.3 m with estimator noise), then a 60 m leg at
/// `speed_m_s` (RMS slot error while cruising, after the first quarter of the cruise
/// samples), then half an orbit of 30 m radius at `speed_m_s` (RMS slot error while
/// orbiting, likewise), with the smallest distance between two vehicles over the whole
/// run. Virtual time (see `crate::rehearsal`), on the PX4-faithful simulated
/// multicopter by default: deterministic, and `wall_s` says how long the CPU took.
///
/// # Errors
/// When a shape does not converge within 300 s of virtual time.
pub fn formation(args: &FormationBenchArgs) -> Result<Value, String> {
    use crate::rehearsal::{AirframeKind, Rehearsal, RehearsalConfig};
    use skein_model::formation::Shape;
    use skein_model::geo::Ned;
    use skein_swarm::formation::{FormationFrame, FormationSpec, VIRTUAL};
    let airframe = match args.airframe.as_str() {
        "point-mass" => AirframeKind::PointMass,
        _ => AirframeKind::Px4 {
            estimator_noise: args.estimator_noise,
        },
    };
    let settled_rms = if args.estimator_noise { 0.3 } else { 0.2 };
    let mut runs = Vec::new();
    for &n in &args.vehicles {
        let started = Instant::now();
        let mut config = RehearsalConfig::new(n);
        config.airframe = airframe;
        let mut r = Rehearsal::new(config);
        let mut converge_s = Vec::new();
        let mut moving_rms = Vec::new();
        let mut orbit_rms = Vec::new();
        // Per shape: time-mean of the RMS slot error cruising and orbiting, m.
        let mut per_shape = serde_json::Map::new();
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
        let mut north = 0.0;
        for shape in Shape::ALL
            .into_iter()
            .filter(|s| *s != Shape::Custom && s.min_vehicles() <= n)
        {
            r.set_formation(FormationSpec {
                shape,
                spacing_m: args.spacing_m,
                leader: Some(VIRTUAL.into()),
                heading_deg: 0.0,
                altitude_m: Some(12.0),
                frame: FormationFrame::World,
                offsets: vec![],
                standoff_m: None,
            });
            let t0 = r.time_s();
            let settled = r.run_until(300.0, |r| {
                let s = r.status();
                s.transition_progress.is_none()
                    && s.pending.is_none()
                    && s.rms_error_m.is_some_and(|e| e < settled_rms)
            });
            if !settled {
                return Err(format!("{n} vehicles: {} did not converge", shape.name()));
            }
            converge_s.push(r.time_s() - t0);
            north = if north == 0.0 { 60.0 } else { 0.0 };
            let moving = r.cruise_to(Ned::new(north, 0.0, -12.0), args.speed_m_s)?;
            // Half an orbit around a point 30 m east of where the leg ended.
            let half_s = std::f64::consts::PI * 30.0 / args.speed_m_s;
            let orbit = r.orbit(Ned::new(north, 30.0, -12.0), 30.0, args.speed_m_s, half_s)?;
            per_shape.insert(
                shape.name().into(),
                json!({"moving": round(mean(&moving), 3), "orbit": round(mean(&orbit), 3)}),
            );
            moving_rms.extend(moving);
            orbit_rms.extend(orbit);
        }
        converge_s.sort_by(f64::total_cmp);
        let stats = r.stats();
        let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
        runs.push(json!({
            "vehicles": n,
            "rms_slot_error_moving_m": {
                "mean": round(mean(&moving_rms), 3),
                "max": round(max(&moving_rms), 3),
            },
            "rms_slot_error_orbit_m": {
                "mean": round(mean(&orbit_rms), 3),
                "max": round(max(&orbit_rms), 3),
            },
            "rms_slot_error_per_shape_m": per_shape,
            "converge_s": {
                "p50": round(converge_s[converge_s.len() / 2], 1),
                "max": round(converge_s.last().copied().unwrap_or(0.0), 1),
            },
            "min_separation_m": round(stats.min_separation_m, 3),
            "separation_violations": stats.separation_violations,
            "fence_violations": stats.fence_violations,
            "virtual_s": round(r.time_s(), 1),
            "wall_s": round(started.elapsed().as_secs_f64(), 2),
        }));
    }
    Ok(json!({
        "bench": "formation",
        "spacing_m": args.spacing_m,
        "speed_m_s": args.speed_m_s,
        "airframe": args.airframe,
        "estimator_noise": args.estimator_noise,
        "runs": runs,
    }))
}
