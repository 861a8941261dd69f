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
use crate::requests::tracks::ObserveRequest;
use axum::Json;
use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use skein_swarm::CoordinatorMsg;
use skein_swarm::tracking::TrackView;
use utoipa::ToSchema;

/// `GET /api/v1/tracks`.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct TracksListing {
    /// The tracks, tentative, confirmed and lost.
    pub tracks: Vec<TrackEntry>,
}

/// A track and the vehicles whose gimbals follow it.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct TrackEntry {
    /// The track (swarm frame).
    #[serde(flatten)]
    pub track: TrackView,
    /// Vehicles observing it (`POST /api/v1/tracks/{id}/observe`).
    pub observed_by: Vec<String>,
}

/// `POST /api/v1/tracks/{id}/observe`.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct Observing {
    /// The track.
    pub track: String,
    /// The vehicles now keeping it in view.
    pub vehicles: Vec<String>,
}

/// `DELETE /api/v1/tracks/{id}/observe`.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct Released {
    /// The track.
    pub track: String,
    /// The vehicles that stopped observing it (their gimbals hold their angles).
    pub released: Vec<String>,
}

/// `GET /api/v1/tracks`.
pub async fn list_tracks(State(s): State<ApiState>) -> Result<Response, ApiError> {
    let (tracks, observing) = s.ask(CoordinatorMsg::GetTracks).await?;
    let tracks = tracks
        .into_iter()
        .map(|track| TrackEntry {
            observed_by: observing
                .iter()
                .filter(|(_, t)| *t == track.id)
                .map(|(v, _)| v.clone())
                .collect(),
            track,
        })
        .collect();
    Ok(Json(TracksListing { tracks }).into_response())
}

/// `POST /api/v1/tracks/{id}/observe`.
pub async fn observe(
    State(s): State<ApiState>,
    Path(id): Path<String>,
    body: Bytes,
) -> Result<Response, ApiError> {
    let vehicles = crate::requests::parse_or_empty::<ObserveRequest>(&body)?.vehicles;
    let track = id.clone();
    match s
        .ask(move |r| CoordinatorMsg::ObserveTrack(track, vehicles, r))
        .await?
    {
        Ok(vehicles) => Ok(Json(Observing {
            track: id,
            vehicles,
        })
        .into_response()),
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
    Ok(Json(Released {
        track: id,
        released,
    })
    .into_response())
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
