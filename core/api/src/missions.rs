//! Missions over the API: `POST /api/v1/missions` (a plan: 201 with the mission, 400
//! naming the step and field), `GET /api/v1/missions` and `GET /api/v1/missions/{id}`
//! (state, step, each step's state and progress), and `POST
//! /api/v1/missions/{id}/{start|pause|resume|abort|skip}`. See `skein_mission` for the
//! plan and how it is flown, and `skein_swarm::coordinator::missions` for where; the
//! rehearsals are in [`crate::rehearsals`].

use crate::ApiState;
use crate::error::ApiError;
use crate::path_params::{MissionAction, MissionId};
use axum::Json;
use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use skein_mission::MissionPlan;
use skein_model::geo::NedFrame;
use skein_swarm::AdminMsg;
use skein_swarm::coordinator::missions::{MissionControl, MissionError, MissionInfo, MissionMsg};

/// Store a mission plan
///
/// The plan (`{"name", "groups"?, "steps": [{"kind", "group"?, ...}], "abort"?}`) is
/// checked against the geofence in force with its margin, the separation the swarm
/// keeps, and the vehicles' speed limit, and stored: 201 with the mission (`ready`). 400
/// names the field (`steps[2].polygon[1]`) and says why. A point may be given as
/// `{"lat_deg", "lon_deg"}` (WGS-84 degrees) instead of `[north_m, east_m]`: it is stored
/// in the swarm frame (400 naming the point while the swarm frame is not anchored yet).
#[utoipa::path(post, path = "/api/v1/missions", request_body = MissionPlan,
    responses((status = 201, body = MissionInfo), (status = 400), (status = 503)))]
pub(crate) async fn create(State(s): State<ApiState>, body: Bytes) -> Result<Response, ApiError> {
    let plan = plan_in_swarm_frame(&s, &body).await?;
    let info = s
        .ask(|r| MissionMsg::Create(plan, r).into())
        .await?
        .map_err(ApiError::from)?;
    Ok((StatusCode::CREATED, Json(info)).into_response())
}

/// The plan in `body`, its latitude/longitude points (if any) put into the swarm frame
/// ([`skein_mission::geodetic`]).
///
/// # Errors
/// 400 naming the field: the body is not a plan, or a point is not a valid
/// latitude/longitude or has no swarm frame to go into; 503 without a coordinator.
async fn plan_in_swarm_frame(s: &ApiState, body: &[u8]) -> Result<MissionPlan, ApiError> {
    let mut plan = crate::requests::object(body)?;
    let health = s.ask(|r| AdminMsg::Health(r).into()).await?;
    let frame = health.swarm_origin.map(NedFrame::new);
    skein_mission::geodetic::points_to_swarm_frame(&mut plan, frame.as_ref())
        .map_err(|e| ApiError::field(&e.field, format!("{}: {}", e.field, e.error)))?;
    crate::requests::from_map(plan)
}

/// Every mission
#[utoipa::path(get, path = "/api/v1/missions",
    responses((status = 200, body = [MissionInfo]), (status = 503)))]
pub(crate) async fn list(State(s): State<ApiState>) -> Result<Json<Vec<MissionInfo>>, ApiError> {
    Ok(Json(s.ask(|r| MissionMsg::List(r).into()).await?))
}

/// One mission
///
/// `{"id", "name", "state" (ready, running, paused, done, aborted), "step", "elapsed_s",
/// "steps": [{"kind", "state", "vehicles", "started_s", "ended_s", "progress"}], "error",
/// "plan"}`.
#[utoipa::path(get, path = "/api/v1/missions/{id}", params(MissionId),
    responses((status = 200, body = MissionInfo), (status = 404), (status = 503)))]
pub(crate) async fn get(
    State(s): State<ApiState>,
    Path(MissionId { id }): Path<MissionId>,
) -> Result<Json<MissionInfo>, ApiError> {
    let id2 = id.clone();
    s.ask(|r| MissionMsg::Get(id2, r).into())
        .await?
        .map(Json)
        .ok_or_else(|| ApiError::not_found(format!("no mission {id}")))
}

/// Start, pause, resume, abort or skip a step of a mission
///
/// `start`: its groups are resolved to the swarm's vehicles and its energy checked (400
/// naming the group or the vehicle short of battery), then it flies (409 while another
/// mission flies). `pause` holds its vehicles, `resume` carries on, `skip` ends the step
/// flown now, `abort` holds every airborne vehicle then returns or lands them (the plan's
/// `abort`). 409 when the mission's state does not allow it.
#[utoipa::path(post, path = "/api/v1/missions/{id}/{action}", params(MissionAction),
    responses((status = 200, body = MissionInfo), (status = 400), (status = 404),
        (status = 409), (status = 503)))]
pub(crate) async fn control(
    State(s): State<ApiState>,
    Path(MissionAction { id, action }): Path<MissionAction>,
) -> Result<Json<MissionInfo>, ApiError> {
    let what = match action.as_str() {
        "start" => MissionControl::Start,
        "pause" => MissionControl::Pause,
        "resume" => MissionControl::Resume,
        "abort" => MissionControl::Abort,
        "skip" => MissionControl::Skip,
        other => {
            return Err(ApiError::field(
                "action",
                format!("`{other}`: start, pause, resume, abort or skip"),
            ));
        }
    };
    match s.ask(|r| MissionMsg::Control(id, what, r).into()).await? {
        Ok(info) => Ok(Json(info)),
        Err(MissionError::NotFound(id)) => Err(ApiError::not_found(format!("no mission {id}"))),
        Err(MissionError::Refused(e)) => Err(ApiError::field(&e.field, e.error)),
        Err(MissionError::Conflict(why)) => Err(ApiError::conflict(why, None)),
    }
}
