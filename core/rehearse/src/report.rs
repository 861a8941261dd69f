//! What a rehearsal reports (`POST /api/v1/missions/{id}/rehearse`, `skein mission
//! rehearse`): how the mission ended and how long it took, each step's start and end, the
//! smallest separation and geofence margin, each vehicle's battery at landing, the
//! surveys' coverage, the reactions fired (and the longest gap of a low-battery swap), the commands refused, how fast it ran, and a
//! picture of the paths over the plan.

use crate::flight::Flight;
use serde::Serialize;
use skein_mission::RunState;
use skein_mission::run::{Reaction, StepStatus};
use std::collections::BTreeMap;
use utoipa::ToSchema;

/// The smallest distance between two airborne vehicles.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct SeparationFigure {
    /// Metres (between the simulated aircraft's true positions).
    pub distance_m: f64,
    /// The two vehicles.
    pub vehicles: [String; 2],
    /// When, mission seconds.
    pub at_s: f64,
}

/// The smallest geofence margin of an airborne vehicle.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct FenceFigure {
    /// Metres to the nearest boundary (circle, polygon, exclusion, ceiling; negative:
    /// outside).
    pub margin_m: f64,
    /// The vehicle.
    pub vehicle: String,
    /// When, mission seconds.
    pub at_s: f64,
}

/// One survey's coverage.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct SurveyFigure {
    /// The survey's step (index).
    pub step: usize,
    /// Fraction of its polygon seen at the planned overlap, 0 to 1.
    pub coverage: f64,
}

/// A rehearsal's figures (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct RehearsalReport {
    /// How the mission ended: `done`, `aborted`, `paused` (stopped by a refusal: see
    /// `error`), or `running` (still flying at `max_duration_s`).
    pub state: RunState,
    /// Why it stopped, when something refused it.
    pub error: Option<String>,
    /// Mission seconds from start to its end.
    pub duration_s: f64,
    /// Every step: state, vehicles, mission seconds of its start and end, progress.
    pub steps: Vec<StepStatus>,
    /// The closest two airborne vehicles came; `null` when fewer than two flew.
    pub min_separation_m: Option<f64>,
    /// Who and when.
    pub min_separation: Option<SeparationFigure>,
    /// The smallest geofence margin of an airborne vehicle, metres; `null` when none flew.
    pub min_fence_margin_m: Option<f64>,
    /// Who and when.
    pub min_fence_margin: Option<FenceFigure>,
    /// Battery each vehicle had left when it last landed (or at the end, for one that did
    /// not land), percent, by id.
    pub energy_left: BTreeMap<String, f64>,
    /// The smallest coverage of the plan's surveys, 0 to 1; `null` without a survey.
    pub coverage: Option<f64>,
    /// Each survey's coverage.
    pub surveys: Vec<SurveyFigure>,
    /// What the plan's reactions did, oldest first.
    pub reactions: Vec<Reaction>,
    /// The longest a route taken by a reserve went unflown (a low-battery swap's gap, its
    /// reaction's `gap_s`), seconds; `null` without one.
    pub max_swap_gap_s: Option<f64>,
    /// Commands the vehicles refused, in words.
    pub refusals: Vec<String>,
    /// Virtual seconds simulated (boot included).
    pub virtual_s: f64,
    /// Wall-clock seconds the rehearsal took.
    pub wall_s: f64,
    /// Virtual seconds per wall-clock second.
    pub speed_factor: f64,
    /// The paths flown over the plan, as SVG (north up).
    pub picture_svg: String,
}

impl RehearsalReport {
    /// The figures of `flight`, flown in `wall_s` seconds.
    pub(crate) fn of(flight: &Flight, wall_s: f64) -> Self {
        let status = flight.run.status();
        let r = &flight.record;
        let mut energy_left = r.energy_at_landing.clone();
        for a in &flight.aircraft {
            if (a.state.is_airborne() || !energy_left.contains_key(&a.id))
                && let Some(b) = a.battery_percent()
            {
                energy_left.insert(a.id.clone(), b);
            }
        }
        let surveys: Vec<SurveyFigure> = r
            .coverage
            .iter()
            .map(|(step, c)| SurveyFigure {
                step: *step,
                coverage: c.fraction(),
            })
            .collect();
        let virtual_s = flight.time_s();
        RehearsalReport {
            state: status.state,
            error: status.error.clone(),
            duration_s: status.elapsed_s,
            steps: status.steps.clone(),
            min_separation_m: r.closest.as_ref().map(|c| c.distance_m),
            min_separation: r.closest.as_ref().map(|c| SeparationFigure {
                distance_m: c.distance_m,
                vehicles: c.pair.clone(),
                at_s: c.at_s,
            }),
            min_fence_margin_m: r.nearest_fence.as_ref().map(|n| n.margin_m),
            min_fence_margin: r.nearest_fence.as_ref().map(|n| FenceFigure {
                margin_m: n.margin_m,
                vehicle: n.vehicle.clone(),
                at_s: n.at_s,
            }),
            energy_left,
            coverage: surveys.iter().map(|s| s.coverage).reduce(f64::min),
            surveys,
            reactions: status.reactions.clone(),
            max_swap_gap_s: status
                .reactions
                .iter()
                .filter_map(|r| r.gap_s)
                .reduce(f64::max),
            refusals: flight.refusals.clone(),
            virtual_s,
            wall_s,
            speed_factor: virtual_s / wall_s.max(1e-9),
            picture_svg: crate::picture::svg(flight.run.plan(), flight.fence(), r),
        }
    }
}
