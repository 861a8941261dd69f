//! Missions rehearsed in virtual time. [`rehearse`] flies a mission plan with the swarm
//! as it is ([`SwarmSetup`]: its vehicles where they stand, their limits and batteries,
//! the geofence and separation in force) on PX4-faithful simulated multicopters
//! ([`skein_sim::VirtualVehicle`]: PX4 v1.16's position control on SIH-like physics,
//! with its battery draining) stepped as fast as the CPU allows, deterministically, with
//! the code that flies the real swarm: the [`skein_mission::MissionRun`], the formation
//! engine, each vehicle's FSM, procedures and setpoint shaper, the link's telemetry and
//! command encoding. Intruders of a [`Scenario`] fly the simulator's own paths and are
//! held as tracks from their truth ([`tracks`]). It reports ([`RehearsalReport`]) the
//! duration, each step's start and end, the smallest separation and geofence margin,
//! the energy left per vehicle, the surveys' coverage ([`coverage`]), the reactions
//! fired, and a picture ([`picture`]).
//!
//! - [`aircraft`]: one vehicle, driven as the Vehicle actor drives one.
//! - [`flight`]: the loop on the virtual clock; the mission's actions.
//! - [`tracks`]: intruders seen as tracks.
//! - [`coverage`]: the surveys' coverage.
//! - [`record`]: what is measured on the way.
//! - [`report`]: the figures; [`picture`]: the SVG.
#![warn(missing_docs)]

mod aircraft;
pub mod coverage;
mod flight;
pub mod picture;
mod progress;
mod record;
pub mod report;
pub mod tracks;

pub use progress::Progress;
pub use report::RehearsalReport;
pub use skein_mission::swarm::{SwarmSetup, VehicleSetup};

use serde::Deserialize;
use skein_mission::{MissionPlan, MissionRun};
use skein_sim::intruders::{IntruderConfig, IntruderPattern, Intruders};
use std::time::Instant;
use utoipa::ToSchema;

/// The longest mission time rehearsed by default, seconds (3 h).
pub const DEFAULT_MAX_DURATION_S: f64 = 10_800.0;

/// What the world does during a rehearsal (`POST /api/v1/missions/{id}/rehearse`'s body).
#[derive(Debug, Clone, Default, PartialEq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Intruders that fly during the rehearsal (none by default).
    #[serde(default)]
    pub intruders: Option<IntruderScenario>,
    /// Seed of the simulated vehicles' noise and the intruders' paths (default 1).
    #[serde(default)]
    pub seed: Option<u64>,
    /// Longest mission time rehearsed, seconds (1 to 86 400; default 10 800).
    #[serde(default)]
    #[schema(minimum = 1, maximum = 86400)]
    pub max_duration_s: Option<f64>,
}

/// Intruders in a rehearsal: the simulator's intruder paths (`skein up --intruders`)
/// around the swarm origin.
#[derive(Debug, Clone, PartialEq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct IntruderScenario {
    /// How many (1 to 20).
    #[schema(minimum = 1, maximum = 20)]
    pub count: usize,
    /// Their pattern: `straight`, `loiter`, `zigzag`, `formation`, `formation_zigzag`,
    /// `crossing`, `split`, or `mixed` (default).
    #[serde(default)]
    pub pattern: Option<String>,
    /// Speed, m/s (default 5).
    #[serde(default)]
    pub speed_m_s: Option<f64>,
    /// Height above the swarm origin, metres (default 20).
    #[serde(default)]
    pub altitude_m: Option<f64>,
    /// Half a pass's length, metres (default 120).
    #[serde(default)]
    pub range_m: Option<f64>,
    /// Heading of the (first) straight pass, degrees from north (default: seeded).
    #[serde(default)]
    pub heading_deg: Option<f64>,
    /// Distance from the origin to the pass's closest point of approach, on its left,
    /// metres (default: seeded in 10 to 50).
    #[serde(default)]
    pub cpa_m: Option<f64>,
    /// When their paths start, mission seconds (default 0).
    #[serde(default)]
    pub start_s: f64,
}

/// A scenario field that does not make sense: its path and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ScenarioError {
    /// `intruders.count`, `max_duration_s` ...
    pub field: String,
    /// What is wrong.
    pub error: String,
}

impl std::fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.field, self.error)
    }
}

impl std::error::Error for ScenarioError {}

fn wrong(field: &str, error: String) -> ScenarioError {
    ScenarioError {
        field: field.into(),
        error,
    }
}

impl Scenario {
    /// Checks every field.
    ///
    /// # Errors
    /// The first field out of its range (its path and why).
    pub fn check(&self) -> Result<(), ScenarioError> {
        if let Some(m) = self.max_duration_s
            && !(m.is_finite() && (1.0..=86_400.0).contains(&m))
        {
            return Err(wrong("max_duration_s", format!("{m} outside 1 to 86400")));
        }
        if let Some(i) = &self.intruders {
            i.config(0)?;
        }
        Ok(())
    }
}

impl IntruderScenario {
    fn config(&self, seed: u64) -> Result<IntruderConfig, ScenarioError> {
        if !(1..=20).contains(&self.count) {
            return Err(wrong(
                "intruders.count",
                format!("{} outside 1 to 20", self.count),
            ));
        }
        let positive = |v: Option<f64>, field: &str| match v {
            Some(x) if !(x.is_finite() && x > 0.0) => {
                Err(wrong(field, format!("{x}: a positive number")))
            }
            _ => Ok(()),
        };
        positive(self.speed_m_s, "intruders.speed_m_s")?;
        positive(self.range_m, "intruders.range_m")?;
        positive(self.altitude_m, "intruders.altitude_m")?;
        if !(self.start_s.is_finite() && self.start_s >= 0.0) {
            return Err(wrong(
                "intruders.start_s",
                format!("{}: 0 or more", self.start_s),
            ));
        }
        let pattern: Option<IntruderPattern> = match &self.pattern {
            Some(p) => IntruderPattern::parse(p).map_err(|e| wrong("intruders.pattern", e))?,
            None => None,
        };
        let d = IntruderConfig::default();
        Ok(IntruderConfig {
            count: self.count,
            pattern,
            speed_m_s: self.speed_m_s.unwrap_or(d.speed_m_s),
            altitude_m: self.altitude_m.unwrap_or(d.altitude_m),
            range_m: self.range_m.unwrap_or(d.range_m),
            heading_deg: self.heading_deg,
            cpa_m: self.cpa_m,
            seed,
            ..d
        })
    }
}

/// Rehearses `plan`, its steps flown by `groups` (each step's vehicles, as
/// `skein_mission::resolve::groups` gives them), with `swarm` in `scenario`.
///
/// # Errors
/// A scenario that does not make sense (the field and why, see [`Scenario::check`]), or
/// simulated vehicles that did not boot (a simulator fault, not a rehearsal outcome:
/// field `vehicles`).
pub fn rehearse(
    plan: &MissionPlan,
    groups: Vec<Vec<String>>,
    swarm: &SwarmSetup,
    scenario: &Scenario,
) -> Result<RehearsalReport, ScenarioError> {
    rehearse_watched(plan, groups, swarm, scenario, &Progress::default())
}

/// [`rehearse`], with the mission time flown so far kept in `progress` for another
/// thread to read (the API's rehearsal status).
///
/// # Errors
/// As [`rehearse`].
pub fn rehearse_watched(
    plan: &MissionPlan,
    groups: Vec<Vec<String>>,
    swarm: &SwarmSetup,
    scenario: &Scenario,
    progress: &Progress,
) -> Result<RehearsalReport, ScenarioError> {
    let started = Instant::now();
    scenario.check()?;
    let seed = scenario.seed.unwrap_or(1);
    let max_s = scenario.max_duration_s.unwrap_or(DEFAULT_MAX_DURATION_S);
    let intrusion = match &scenario.intruders {
        Some(i) => {
            let config = i.config(seed)?;
            let intruders =
                Intruders::new(swarm.origin, config, started).map_err(|e| wrong("intruders", e))?;
            Some(flight::Intrusion {
                intruders,
                start_s: i.start_s,
            })
        }
        None => None,
    };
    let mut run = MissionRun::new(plan.clone(), groups);
    run.start();
    let mut f = flight::Flight::new(run, swarm, intrusion, seed);
    if !f.boot() {
        return Err(wrong(
            "vehicles",
            "the simulated vehicles did not boot (no home or position)".into(),
        ));
    }
    f.fly(max_s, progress);
    Ok(RehearsalReport::of(&f, started.elapsed().as_secs_f64()))
}
