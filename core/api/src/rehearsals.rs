//! The missions' rehearsals as jobs: `POST /api/v1/missions/{id}/rehearse` starts one on
//! its own thread (at nice 19) and answers at once; `GET
//! /api/v1/missions/{id}/rehearsal` follows it (mission seconds flown so far) and, once
//! it ended, holds its report. A rehearsal of a long plan takes minutes on a small
//! companion computer: no HTTP request (nor a proxy in front of the API) waits for it.
//! One rehearsal runs at a time; the latest of each mission is kept.

use crate::ApiState;
use crate::error::ApiError;
use crate::path_params::MissionId;
use axum::Json;
use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use skein_rehearse::{Progress, RehearsalReport};
use skein_swarm::coordinator::missions::{MissionError, MissionMsg};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Instant;
use utoipa::ToSchema;

/// Where a rehearsal is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum RehearsalState {
    /// The mission was never rehearsed.
    None,
    /// Flying in virtual time.
    Running,
    /// Ended with a report (`report`; how the mission ended is its `state`).
    Done,
    /// Ended without a report (`error` says why: simulated vehicles that did not boot).
    Failed,
}

/// A mission's latest rehearsal (`GET /api/v1/missions/{id}/rehearsal`).
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct RehearsalStatus {
    /// The mission rehearsed (`m-1`).
    pub mission: String,
    /// `none`, `running`, `done` or `failed`.
    pub state: RehearsalState,
    /// Mission seconds flown in virtual time so far (all of them once ended).
    pub mission_s: f64,
    /// Wall-clock seconds since it started, until it ended.
    pub wall_s: f64,
    /// The figures, once `done`.
    pub report: Option<RehearsalReport>,
    /// Why it `failed`.
    pub error: Option<String>,
}

/// One rehearsal, running or ended.
struct Entry {
    progress: Arc<Progress>,
    started: Instant,
    ended: Option<(f64, Result<RehearsalReport, String>)>,
}

/// The latest rehearsal of each mission.
#[derive(Default)]
pub struct Rehearsals {
    by_mission: Mutex<HashMap<String, Entry>>,
}

impl Rehearsals {
    /// Records a rehearsal of `mission` starting now (replacing its previous one); the
    /// returned progress is what the rehearsal's thread writes.
    pub fn started(&self, mission: &str) -> Arc<Progress> {
        let progress = Arc::new(Progress::default());
        let entry = Entry {
            progress: progress.clone(),
            started: Instant::now(),
            ended: None,
        };
        self.lock().insert(mission.to_string(), entry);
        progress
    }

    /// Records how `mission`'s rehearsal ended: its report or why it has none.
    pub fn ended(&self, mission: &str, outcome: Result<RehearsalReport, String>) {
        if let Some(e) = self.lock().get_mut(mission) {
            e.ended = Some((e.started.elapsed().as_secs_f64(), outcome));
        }
    }

    /// `mission`'s latest rehearsal; `None` when it was never rehearsed (here).
    pub fn status(&self, mission: &str) -> Option<RehearsalStatus> {
        let map = self.lock();
        let e = map.get(mission)?;
        let (state, wall_s, report, error) = match &e.ended {
            None => (
                RehearsalState::Running,
                e.started.elapsed().as_secs_f64(),
                None,
                None,
            ),
            Some((wall_s, Ok(r))) => (RehearsalState::Done, *wall_s, Some(r.clone()), None),
            Some((wall_s, Err(why))) => (RehearsalState::Failed, *wall_s, None, Some(why.clone())),
        };
        Some(RehearsalStatus {
            mission: mission.to_string(),
            state,
            mission_s: e.progress.mission_s(),
            wall_s,
            report,
            error,
        })
    }

    /// The map; a panic while holding it poisons nothing worth refusing for (each write
    /// is one insert).
    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<String, Entry>> {
        self.by_mission
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

/// How long a rehearsal waits for a vehicle's pack capacity.
const CAPACITY_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(2);

/// Vehicle `id`'s pack capacity (PX4 `BAT1_CAPACITY`, mAh), when its link answers in
/// time with a positive value.
async fn battery_capacity_mah(s: &ApiState, id: &str) -> Option<f64> {
    let link = crate::px4_params::link_of(s, id).await.ok()?;
    let asked = link.call(
        |r| skein_link::Px4LinkMsg::ParamGet("BAT1_CAPACITY".into(), r),
        Some(CAPACITY_TIMEOUT),
    );
    match asked.await {
        Ok(ractor::rpc::CallResult::Success(Ok(v))) => {
            Some(v.as_f64()).filter(|c| c.is_finite() && *c > 0.0)
        }
        _ => None,
    }
}

/// One rehearsal at a time: it takes a core while it runs.
static REHEARSING: tokio::sync::Semaphore = tokio::sync::Semaphore::const_new(1);

/// Rehearse a mission in virtual time
///
/// Starts flying the plan with the swarm as it is now (each vehicle from the ground at
/// its home, its model's limits, its battery (PX4 `BAT1_CAPACITY`); the geofence and
/// separation in force) on PX4-faithful simulated vehicles stepped faster than real time,
/// with the code that flies the swarm: the mission run, the formation engine, each
/// vehicle's state machine, procedures and setpoint shaper. The body (optional) adds
/// `intruders` (the simulator's paths, held as tracks from their truth), a `seed`, a
/// `max_duration_s`. 202 at once with the rehearsal (`running`); `GET
/// /api/v1/missions/{id}/rehearsal` follows it to its report. 400 names the field (a
/// group the swarm lacks, a scenario field); 409 while another rehearsal runs or before
/// the swarm has a frame. It runs at the lowest CPU priority (nice 19): flying vehicles
/// come first.
#[utoipa::path(post, path = "/api/v1/missions/{id}/rehearse", params(MissionId),
    request_body(content = Option<skein_rehearse::Scenario>, content_type = "application/json"),
    responses((status = 202, body = RehearsalStatus), (status = 400),
        (status = 404), (status = 409), (status = 503)))]
pub(crate) async fn rehearse(
    State(s): State<ApiState>,
    Path(MissionId { id }): Path<MissionId>,
    body: Bytes,
) -> Result<Response, ApiError> {
    let scenario: skein_rehearse::Scenario = crate::requests::parse_or_empty(&body)?;
    scenario
        .check()
        .map_err(|e| ApiError::field(&e.field, e.error))?;
    let mut setup = match s
        .ask(|r| MissionMsg::Rehearsal(id.clone(), r).into())
        .await?
    {
        Ok(setup) => setup,
        Err(MissionError::NotFound(id)) => {
            return Err(ApiError::not_found(format!("no mission {id}")));
        }
        Err(MissionError::Refused(e)) => return Err(ApiError::field(&e.field, e.error)),
        Err(MissionError::Conflict(why)) => return Err(ApiError::conflict(why, None)),
    };
    let one = REHEARSING
        .try_acquire()
        .map_err(|_| ApiError::conflict("a rehearsal is running: one at a time", None))?;
    // Asked of every vehicle at once: a silent one costs the timeout once, not per vehicle.
    let capacities = futures_util::future::join_all(
        setup
            .swarm
            .vehicles
            .iter()
            .map(|v| battery_capacity_mah(&s, &v.id)),
    )
    .await;
    for (v, c) in setup.swarm.vehicles.iter_mut().zip(capacities) {
        v.battery_capacity_mah = c;
    }
    let progress = s.rehearsals.started(&id);
    let (rehearsals, mission) = (s.rehearsals.clone(), id.clone());
    std::thread::Builder::new()
        .name("rehearsal".into())
        .spawn(move || {
            // Optional work: the lowest priority, whatever the process runs at.
            let _ = skein_link::priority::set_current_thread_nice(19);
            let outcome = skein_rehearse::rehearse_watched(
                &setup.plan,
                setup.groups,
                &setup.swarm,
                &scenario,
                &progress,
            );
            rehearsals.ended(
                &mission,
                outcome.map_err(|e| format!("{}: {}", e.field, e.error)),
            );
            drop(one);
        })
        .map_err(|e| ApiError::unavailable(format!("no thread for the rehearsal: {e}")))?;
    let status = s.rehearsals.status(&id);
    Ok((StatusCode::ACCEPTED, Json(status)).into_response())
}

/// A mission's latest rehearsal
///
/// `{"mission", "state" (none, running, done, failed), "mission_s" (mission seconds flown so
/// far), "wall_s", "report", "error"}`. The report, once `done`: `state` (how the
/// mission ended), `duration_s`, each step's `started_s`/`ended_s`, `min_separation_m`,
/// `min_fence_margin_m`, `energy_left` per vehicle (percent), `coverage` (0 to 1) of the
/// surveys, the `reactions` fired, the `refusals`, `speed_factor`, and `picture_svg`
/// (the paths over the plan). `none` for a mission never rehearsed; 404 for no mission.
#[utoipa::path(get, path = "/api/v1/missions/{id}/rehearsal", params(MissionId),
    responses((status = 200, body = RehearsalStatus), (status = 404), (status = 503)))]
pub(crate) async fn rehearsal(
    State(s): State<ApiState>,
    Path(MissionId { id }): Path<MissionId>,
) -> Result<Json<RehearsalStatus>, ApiError> {
    if let Some(status) = s.rehearsals.status(&id) {
        return Ok(Json(status));
    }
    let id2 = id.clone();
    match s.ask(|r| MissionMsg::Get(id2, r).into()).await? {
        Some(_) => Ok(Json(RehearsalStatus {
            mission: id,
            state: RehearsalState::None,
            mission_s: 0.0,
            wall_s: 0.0,
            report: None,
            error: None,
        })),
        None => Err(ApiError::not_found(format!("no mission {id}"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rehearsal_runs_then_fails_and_a_new_one_replaces_it() {
        let r = Rehearsals::default();
        assert!(r.status("m-1").is_none());
        r.started("m-1");
        let s = r.status("m-1").unwrap();
        assert_eq!((s.state, s.mission_s), (RehearsalState::Running, 0.0));
        r.ended("m-1", Err("did not boot".into()));
        let s = r.status("m-1").unwrap();
        assert_eq!(s.state, RehearsalState::Failed);
        assert_eq!(s.error.as_deref(), Some("did not boot"));
        r.started("m-1");
        assert_eq!(r.status("m-1").unwrap().state, RehearsalState::Running);
        assert!(r.status("m-2").is_none());
    }
}
