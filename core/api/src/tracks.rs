//! Counter-UAS routes: the tracker's tracks and the simulator's ground truth.
//!
//! - `GET /api/v1/tracks`: `{"tracks": [TrackView…]}`, each `{"id": "track-3", "status":
//!   "tentative" | "confirmed" | "lost", "position": {"north_m", "east_m", "down_m"},
//!   "velocity": {"north_m_s", "east_m_s", "down_m_s"}, "covariance_ne_m2": [[nn, ne], [ne,
//!   ee]], "position_sigma_m", "hits", "triangulated_hits", "observers", "age_s",
//!   "unseen_s"}` (swarm frame; see `skein_swarm::tracking`).
//! - `GET /api/v1/sim/truth`: the embedded simulator's ground truth, for evaluation only:
//!   `{"vehicles": [...], "intruders": [{"id", "pattern", "position": {"lat_deg", "lon_deg",
//!   "alt_amsl_m"}, "north_m", "east_m", "down_m", "velocity", "span_m"}]}` (swarm-frame
//!   fields `null` until the swarm frame is anchored); 404 when no simulator is embedded.

use crate::ApiState;
use crate::error::ApiError;
use axum::Json;
use axum::extract::State;
use axum::response::{IntoResponse, Response};
use skein_swarm::CoordinatorMsg;

/// `GET /api/v1/tracks`.
pub async fn list_tracks(State(s): State<ApiState>) -> Result<Response, ApiError> {
    let tracks = s.ask(CoordinatorMsg::GetTracks).await?;
    Ok(Json(serde_json::json!({ "tracks": tracks })).into_response())
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
