//! The battery a plan takes, per vehicle, checked at start against what each vehicle has
//! left plus a reserve. Each vehicle's place is followed through the steps (from where it
//! is now), each step's flight turned into time (distance at the speed it flies, climbs
//! and descents at PX4's rates, holds and waits) and the time into battery at the
//! model's consumption: hovering, plus a share per m/s of cruise; a vehicle that has
//! flown enough is estimated at its own measured rates ([`crate::consumption`]).
//!
//! The default consumption is the simulator's pack (`BAT1_CAPACITY` 5000 mAh; 12 A
//! hovering, 0.6 A more per m/s): 4 % a minute hovering, 0.2 % a minute more per m/s. A
//! patrol without a duration is flown until skipped: it counts one lap.

use crate::lanes;
use crate::plan::{MissionPlan, Point, StepKind};
use crate::validate::PlanError;
use skein_model::geofence::polygon::distance;
use std::collections::BTreeMap;

/// Battery used per minute hovering, percent (the default model's).
pub const HOVER_PERCENT_PER_MIN: f64 = 4.0;
/// Battery used per minute per m/s of horizontal speed on top of hovering, percent.
pub const CRUISE_PERCENT_PER_MIN_PER_M_S: f64 = 0.2;
/// Battery kept in reserve at the end of a plan, percent (above PX4's `BAT_LOW_THR`
/// 15 %).
pub const RESERVE_PERCENT: f64 = 20.0;
/// Climb and descent rates the estimate uses, m/s (PX4's `MPC_Z_VEL_MAX_UP` 3 and its
/// landing speed `MPC_LAND_SPEED` 0.7).
const CLIMB_M_S: f64 = 3.0;
const LAND_M_S: f64 = 0.7;

/// How a vehicle uses its battery.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnergyModel {
    /// Percent per minute hovering.
    pub hover_percent_per_min: f64,
    /// Percent per minute per m/s of horizontal speed on top of hovering.
    pub cruise_percent_per_min_per_m_s: f64,
    /// The speed it flies between points without a given speed, m/s.
    pub cruise_speed_m_s: f64,
}

impl Default for EnergyModel {
    fn default() -> Self {
        EnergyModel {
            hover_percent_per_min: HOVER_PERCENT_PER_MIN,
            cruise_percent_per_min_per_m_s: CRUISE_PERCENT_PER_MIN_PER_M_S,
            cruise_speed_m_s: 5.0,
        }
    }
}

/// A vehicle at the start of a plan.
#[derive(Debug, Clone, PartialEq)]
pub struct Start {
    /// Where it is, `[north_m, east_m]` in the swarm frame.
    pub at: Point,
    /// Its battery, percent; `None`: unknown (not checked).
    pub battery_percent: Option<f64>,
    /// Its consumption as measured in flight ([`crate::consumption`]); `None`: the
    /// model's defaults.
    pub measured: Option<EnergyModel>,
}

/// What one vehicle's part of a plan takes.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimate {
    /// Flight time, seconds.
    pub flight_s: f64,
    /// Battery used, percent.
    pub percent: f64,
    /// Its hover rate, percent per minute, when measured (not the model's default).
    pub measured_hover_percent_per_min: Option<f64>,
}

/// Each vehicle's estimate for `plan` with its steps' vehicles `groups` (from
/// [`crate::resolve::groups`]), starting from `starts`: at each vehicle's measured
/// consumption where it has one, else at `model`'s (whose cruise speed all keep).
pub fn estimate(
    plan: &MissionPlan,
    groups: &[Vec<String>],
    starts: &BTreeMap<String, Start>,
    model: &EnergyModel,
) -> BTreeMap<String, Estimate> {
    let mut at: BTreeMap<String, Point> = starts.iter().map(|(id, s)| (id.clone(), s.at)).collect();
    let mut out: BTreeMap<String, Estimate> = starts
        .keys()
        .map(|id| {
            (
                id.clone(),
                Estimate {
                    flight_s: 0.0,
                    percent: 0.0,
                    measured_hover_percent_per_min: starts[id]
                        .measured
                        .map(|m| m.hover_percent_per_min),
                },
            )
        })
        .collect();
    let homes = at.clone();
    for (step, ids) in plan.steps.iter().zip(groups) {
        let plans = legs(&step.kind, ids, &at, &homes, model);
        for (id, (end, legs)) in plans {
            let e = out.get_mut(&id).expect("a known vehicle");
            let rates = starts[&id].measured.as_ref().unwrap_or(model);
            for (secs, speed) in legs {
                e.flight_s += secs;
                e.percent += secs / 60.0
                    * (rates.hover_percent_per_min + rates.cruise_percent_per_min_per_m_s * speed);
            }
            at.insert(id, end);
        }
    }
    out
}

/// Refuses a plan some vehicle's battery cannot fly with the reserve left.
///
/// # Errors
/// `steps`, naming the vehicle, what it needs and what it has.
pub fn check(
    estimates: &BTreeMap<String, Estimate>,
    starts: &BTreeMap<String, Start>,
) -> Result<(), PlanError> {
    for (id, e) in estimates {
        let Some(has) = starts.get(id).and_then(|s| s.battery_percent) else {
            continue;
        };
        if has - e.percent < RESERVE_PERCENT {
            let at = e.measured_hover_percent_per_min.map_or(String::new(), |h| {
                format!(" at its measured consumption ({h:.1} %/min hovering)")
            });
            return Err(PlanError::new(
                "steps",
                format!(
                    "{id} needs {:.0} % of its battery for its part ({:.0} s of flight{at}) \
                     and {RESERVE_PERCENT:.0} % in reserve, and has {has:.0} %",
                    e.percent, e.flight_s
                ),
            ));
        }
    }
    Ok(())
}

/// A vehicle's flight in a step: where it ends, and its legs as (seconds, horizontal
/// m/s).
type Flight = (Point, Vec<(f64, f64)>);

/// Each vehicle's [`Flight`] in a step.
type Legs = BTreeMap<String, Flight>;

fn legs(
    kind: &StepKind,
    ids: &[String],
    at: &BTreeMap<String, Point>,
    homes: &BTreeMap<String, Point>,
    model: &EnergyModel,
) -> Legs {
    let v = model.cruise_speed_m_s;
    let here = |id: &String| at.get(id).copied().unwrap_or([0.0, 0.0]);
    let fly = |from: Point, to: &[Point], speed: f64| -> Flight {
        let mut p = from;
        let mut legs = Vec::new();
        for q in to {
            legs.push((distance(p, *q) / speed, speed));
            p = *q;
        }
        (p, legs)
    };
    let each = |f: &dyn Fn(usize, &String) -> Flight| -> Legs {
        ids.iter()
            .enumerate()
            .map(|(i, id)| (id.clone(), f(i, id)))
            .collect()
    };
    match kind {
        StepKind::Takeoff(t) => each(&|i, id| {
            let wait = i as f64 * t.interval_s;
            (here(id), vec![(t.altitude_m / CLIMB_M_S + wait, 0.0)])
        }),
        StepKind::Transit(t) => each(&|_, id| fly(here(id), &t.waypoints, t.speed_m_s)),
        StepKind::Survey(s) => {
            let spacing = s
                .lane_spacing_m
                .or(s.camera.map(|c| c.lane_spacing_m(s.altitude_m)))
                .unwrap_or(f64::INFINITY);
            let blocks = lanes::split(&lanes::lanes(&s.polygon, spacing), ids.len());
            let from: Vec<Point> = ids.iter().map(&here).collect();
            let ways = lanes::sweep(&blocks, &from);
            each(&|i, id| fly(here(id), &ways[i], v))
        }
        StepKind::Patrol(p) => each(&|_, id| {
            let mut lap = p.route.clone();
            lap.push(p.route[0]);
            let (end, mut legs) = fly(here(id), &lap, v);
            if let Some(d) = p.duration_s {
                legs.push((d, v));
            }
            (end, legs)
        }),
        StepKind::Station(s) => each(&|i, id| {
            let point = s.points[i % s.points.len()];
            let (end, mut legs) = fly(here(id), &[point], v);
            legs.push((s.duration_s, 0.0));
            (end, legs)
        }),
        StepKind::Return(t) => each(&|i, id| {
            let home = homes.get(id).copied().unwrap_or(here(id));
            let (end, mut legs) = fly(here(id), &[home], v);
            legs.push((i as f64 * t.interval_s + 30.0 / LAND_M_S, 0.0));
            (end, legs)
        }),
        StepKind::Land(t) => each(&|i, id| {
            (
                here(id),
                vec![(i as f64 * t.interval_s + 30.0 / LAND_M_S, 0.0)],
            )
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan(steps: &str) -> MissionPlan {
        serde_json::from_str(&format!(r#"{{"name": "t", "steps": {steps}}}"#)).unwrap()
    }

    fn starts(battery: f64) -> BTreeMap<String, Start> {
        [("uav-1", [0.0, 0.0]), ("uav-2", [0.0, 10.0])]
            .into_iter()
            .map(|(id, at)| {
                (
                    id.to_string(),
                    Start {
                        at,
                        battery_percent: Some(battery),
                        measured: None,
                    },
                )
            })
            .collect()
    }

    #[test]
    fn a_transit_costs_its_flight_time() {
        let p = plan(
            r#"[{"kind": "transit", "waypoints": [[300, 0]], "altitude_m": 20, "speed_m_s": 5}]"#,
        );
        let ids = vec!["uav-1".to_string(), "uav-2".into()];
        let e = estimate(&p, &[ids], &starts(90.0), &EnergyModel::default());
        // 300 m at 5 m/s: 60 s, at 4 + 1 % a minute.
        assert!((e["uav-1"].flight_s - 60.0).abs() < 1e-9, "{e:?}");
        assert!((e["uav-1"].percent - 5.0).abs() < 1e-9, "{e:?}");
        assert!(e["uav-2"].flight_s > 60.0, "{e:?}");
        assert_eq!(check(&e, &starts(90.0)), Ok(()));
        let low = check(&e, &starts(24.0)).unwrap_err();
        assert!(
            low.error.contains("uav-1 needs 5 %") && low.error.contains("has 24 %"),
            "{low}"
        );
    }

    #[test]
    fn a_vehicle_s_measured_consumption_replaces_the_model_s() {
        let p = plan(
            r#"[{"kind": "transit", "waypoints": [[300, 0]], "altitude_m": 20, "speed_m_s": 5}]"#,
        );
        let ids = vec!["uav-1".to_string(), "uav-2".into()];
        let mut s = starts(60.0);
        s.get_mut("uav-1").unwrap().measured = Some(EnergyModel {
            hover_percent_per_min: 40.0,
            cruise_percent_per_min_per_m_s: 2.0,
            ..EnergyModel::default()
        });
        let e = estimate(&p, &[ids], &s, &EnergyModel::default());
        // 60 s at 40 + 10 % a minute: 50 %, where the model's pack would use 5 %.
        assert!((e["uav-1"].percent - 50.0).abs() < 1e-9, "{e:?}");
        assert!(e["uav-2"].percent < 6.0, "{e:?}");
        let refused = check(&e, &s).unwrap_err();
        assert!(
            refused.error.contains("uav-1 needs 50 %")
                && refused
                    .error
                    .contains("measured consumption (40.0 %/min hovering)"),
            "{refused}"
        );
    }

    #[test]
    fn a_survey_splits_its_lanes_between_the_vehicles() {
        let p = plan(
            r#"[{"kind": "survey", "polygon": [[0,0],[0,100],[40,100],[40,0]], "altitude_m": 20,
                 "lane_spacing_m": 10}]"#,
        );
        let ids = vec!["uav-1".to_string(), "uav-2".into()];
        let e = estimate(&p, &[ids], &starts(90.0), &EnergyModel::default());
        // Four 100 m lanes: two each, 200 m of lanes, 10 m across, and the way there
        // (uav-1 from the near corner, uav-2 to the far pair).
        assert!((43.0..43.01).contains(&e["uav-1"].flight_s), "{e:?}");
        assert!((47.0..48.0).contains(&e["uav-2"].flight_s), "{e:?}");
    }
}
