//! Counter-UAS routes: the tracker's tracks and the simulator's ground truth.
//!
//! - `GET /api/v1/tracks`: `{"tracks": [TrackView…]}`, each `{"id": "track-3", "status":
//!   "tentative" | "confirmed" | "lost", "position": {"north_m", "east_m", "down_m"},
//!   "velocity": {"north_m_s", "east_m_s", "down_m_s"}, "covariance_ne_m2": [[nn, ne], [ne,
//!   ee]], "position_sigma_m", "hits", "triangulated_hits", "observers", "age_s",
//!   "unseen_s"}` (swarm frame; see `skein_swarm::tracking`).
//!   Each track also lists `observed_by`: the vehicles whose gimbals follow it.
//! - `POST /api/v1/tracks/{id}/observe` `{"vehicles"?: ["uav-2", …]}` (operator): point the
//!   gimbals of those vehicles (default: every vehicle with a gimbal) at the track and keep
//!   them on it; `{"track", "vehicles"}`. 404 `id` for an unknown track, 409 `id` for a
//!   lost one, 400 `vehicles` for an unknown vehicle or one without a gimbal.
//! - `DELETE /api/v1/tracks/{id}/observe` (operator): stop; the gimbals hold their angles;
//!   `{"track", "released"}`.
//! - `GET /api/v1/sim/truth`: the embedded simulator's ground truth, for evaluation only:
//!   `{"vehicles": [...], "intruders": [{"id", "pattern", "position": {"lat_deg", "lon_deg",
//!   "alt_amsl_m"}, "north_m", "east_m", "down_m", "velocity", "span_m"}]}` (swarm-frame
//!   fields `null` until the swarm frame is anchored); 404 when no simulator is embedded.

use crate::ApiState;
use crate::error::ApiError;
use axum::Json;
use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use skein_swarm::CoordinatorMsg;

/// `GET /api/v1/tracks`.
pub async fn list_tracks(State(s): State<ApiState>) -> Result<Response, ApiError> {
    let (tracks, observing) = s.ask(CoordinatorMsg::GetTracks).await?;
    let tracks: Vec<serde_json::Value> = tracks
        .into_iter()
        .map(|t| {
            let by: Vec<&String> = observing
                .iter()
                .filter(|(_, track)| *track == t.id)
                .map(|(v, _)| v)
                .collect();
            let mut v = serde_json::to_value(&t).unwrap_or_default();
            v["observed_by"] = serde_json::json!(by);
            v
        })
        .collect();
    Ok(Json(serde_json::json!({ "tracks": tracks })).into_response())
}

/// The `vehicles` of an observe request (`None`: all); errors name the field.
fn observe_vehicles(body: &[u8]) -> Result<Option<Vec<String>>, ApiError> {
    if body.iter().all(u8::is_ascii_whitespace) {
        return Ok(None);
    }
    let v: serde_json::Value = serde_json::from_slice(body)
        .map_err(|e| ApiError::bad_request(format!("body is not JSON: {e}")))?;
    let obj = v
        .as_object()
        .ok_or_else(|| ApiError::bad_request("body must be a JSON object"))?;
    if let Some(k) = obj.keys().find(|k| *k != "vehicles") {
        return Err(ApiError::field(
            k,
            format!("unknown field `{k}` (known: vehicles)"),
        ));
    }
    match obj.get("vehicles") {
        None | Some(serde_json::Value::Null) => Ok(None),
        Some(serde_json::Value::Array(list)) => list
            .iter()
            .map(|x| {
                x.as_str()
                    .map(str::to_string)
                    .ok_or_else(|| ApiError::field("vehicles", "must be an array of vehicle ids"))
            })
            .collect::<Result<Vec<_>, _>>()
            .map(Some),
        Some(_) => Err(ApiError::field(
            "vehicles",
            "must be an array of vehicle ids",
        )),
    }
}

/// `POST /api/v1/tracks/{id}/observe`.
pub async fn observe(
    State(s): State<ApiState>,
    Path(id): Path<String>,
    body: Bytes,
) -> Result<Response, ApiError> {
    let vehicles = observe_vehicles(&body)?;
    let track = id.clone();
    match s
        .ask(move |r| CoordinatorMsg::ObserveTrack(track, vehicles, r))
        .await?
    {
        Ok(vehicles) => {
            Ok(Json(serde_json::json!({"track": id, "vehicles": vehicles})).into_response())
        }
        Err(refusal) => {
            use skein_swarm::coordinator::observe::ObserveRefusal as R;
            let status = match refusal {
                R::UnknownTrack(_) => StatusCode::NOT_FOUND,
                R::TrackLost(_) => StatusCode::CONFLICT,
                R::BadVehicle(_) => StatusCode::BAD_REQUEST,
            };
            Err(ApiError {
                status,
                error: refusal.message().to_string(),
                field: Some(refusal.field().to_string()),
            })
        }
    }
}

/// `DELETE /api/v1/tracks/{id}/observe`.
pub async fn stop_observing(
    State(s): State<ApiState>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let track = id.clone();
    let released = s
        .ask(move |r| CoordinatorMsg::StopObserving(track, r))
        .await?;
    Ok(Json(serde_json::json!({"track": id, "released": released})).into_response())
}

/// `GET /api/v1/sim/truth`.
pub async fn sim_truth(State(s): State<ApiState>) -> Result<Response, ApiError> {
    match s.ask(CoordinatorMsg::GetSimTruth).await? {
        Some(truth) => Ok(Json(truth).into_response()),
        None => Err(ApiError::not_found(
            "no simulator is embedded (ground truth exists only with `skein up --sim N`)",
        )),
    }
}
