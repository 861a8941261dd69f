//! Counter-UAS routes: the tracker's tracks and the simulator's ground truth.
//!
//! - `GET /api/v1/tracks`: `{"tracks": [TrackView…]}`, each `{"id": "track-3", "status":
//!   "tentative" | "confirmed" | "lost", "position": {"north_m", "east_m", "down_m"},
//!   "velocity": {"north_m_s", "east_m_s", "down_m_s"}, "covariance_ne_m2": [[nn, ne], [ne,
//!   ee]], "position_sigma_m", "hits", "triangulated_hits", "observers", "age_s",
//!   "unseen_s"}` (swarm frame; see `skein_swarm::tracking`).
//!   Each track also lists `velocity_sigma_m_s`, its `forecast` (5, 10, 20 s: `{"horizon_s",
//!   "position", "sigma_m", "model"}`), its `swarm` (`swarm-N` or null), `observed_by`:
//!   the vehicles whose gimbals follow it, and `stations` when they observe it from
//!   stations.
//! - `POST /api/v1/tracks/{id}/observe` `{"vehicles"?: ["uav-2", …], "stations"?: false,
//!   "standoff_m"?: 25}` (operator): point the gimbals of those vehicles (default: every
//!   vehicle with a gimbal) at the track and keep them on it, and with `stations` fly them
//!   to the stations that fix it best; `{"track", "vehicles"}`. 404 `id` for an unknown
//!   track, 409 `id` for a lost one, 400 `vehicles` for an unknown vehicle or one without a
//!   gimbal, 400 `standoff_m` out of range, 409 `stations` when no stations meet the limits.
//! - `DELETE /api/v1/tracks/{id}/observe` (operator): stop; the gimbals hold their angles;
//!   `{"track", "released"}`.
//! - `GET /api/v1/sim/truth`: the embedded simulator's ground truth, for evaluation only:
//!   `{"vehicles": [...], "intruders": [{"id", "pattern", "position": {"lat_deg", "lon_deg",
//!   "alt_amsl_m"}, "north_m", "east_m", "down_m", "velocity", "span_m"}]}` (swarm-frame
//!   fields `null` until the swarm frame is anchored); 404 when no simulator is embedded.

use crate::ApiState;
use crate::error::ApiError;
use crate::path_params::TrackId;
use crate::requests::tracks::ObserveRequest;
use axum::Json;
use axum::body::Bytes;
use axum::extract::{Path, State};
use serde::Serialize;
use skein_swarm::TrackingMsg;
use skein_swarm::coordinator::observe::ObserveSpec;
use skein_swarm::coordinator::stations::StationsView;
use skein_swarm::tracks::TrackView;
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
    /// Their stations, when they observe it from stations.
    pub stations: Option<StationsView>,
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

/// The counter-UAS tracks (swarm frame) and who observes each
#[utoipa::path(get, path = "/api/v1/tracks",
    responses((status = 200, body = TracksListing)))]
pub(crate) async fn list_tracks(
    State(s): State<ApiState>,
) -> Result<Json<TracksListing>, ApiError> {
    let picture = s.reads.air_picture();
    let seen = &picture.observations;
    let tracks = picture
        .tracks
        .into_iter()
        .map(|track| TrackEntry {
            observed_by: observed_by(&seen.observing, &track.id),
            stations: seen
                .stations
                .iter()
                .find(|st| st.target == track.id)
                .cloned(),
            track,
        })
        .collect();
    Ok(Json(TracksListing { tracks }))
}

/// The vehicles of `observing` (vehicle, target) observing `target`.
pub(crate) fn observed_by(observing: &[(String, String)], target: &str) -> Vec<String> {
    observing
        .iter()
        .filter(|(_, t)| t == target)
        .map(|(v, _)| v.clone())
        .collect()
}

/// Point gimbals at the track and keep them on it
///
/// The gimbals of the given vehicles (default: every observation UAV); with `stations`,
/// they also fly to the stations that fix the track best.
#[utoipa::path(post, path = "/api/v1/tracks/{id}/observe", params(TrackId),
    request_body = Option<ObserveRequest>,
    responses((status = 200, body = Observing), (status = 400), (status = 404),
        (status = 409), (status = 503)),
    extensions(("x-skein-swarm-checks" = json!({
        "vehicles": "vehicles of the swarm that have a gimbal"
    }))))]
pub(crate) async fn observe(
    State(s): State<ApiState>,
    Path(TrackId { id }): Path<TrackId>,
    body: Bytes,
) -> Result<Json<Observing>, ApiError> {
    let req = crate::requests::parse_or_empty::<ObserveRequest>(&body)?;
    let spec = ObserveSpec {
        target: id.clone(),
        vehicles: req.vehicles,
        stations: req.stations.unwrap_or(false),
        standoff_m: req.standoff_m,
    };
    let vehicles = s
        .write(move |r| TrackingMsg::Observe(spec, r).into())
        .await??;
    Ok(Json(Observing {
        track: id,
        vehicles,
    }))
}

/// Stop observing the track; the gimbals hold their angles, observers on stations hold
#[utoipa::path(delete, path = "/api/v1/tracks/{id}/observe", params(TrackId),
    responses((status = 200, body = Released), (status = 503)))]
pub(crate) async fn stop_observing(
    State(s): State<ApiState>,
    Path(TrackId { id }): Path<TrackId>,
) -> Result<Json<Released>, ApiError> {
    let track = id.clone();
    let released = s
        .write(move |r| TrackingMsg::StopObserving(track, r).into())
        .await?;
    Ok(Json(Released {
        track: id,
        released,
    }))
}

/// The embedded simulator's ground truth
///
/// Vehicles and intruders, for evaluation only.
#[utoipa::path(get, path = "/api/v1/sim/truth",
    responses((status = 200, body = Object), (status = 404), (status = 503)))]
pub(crate) async fn sim_truth(
    State(s): State<ApiState>,
) -> Result<Json<serde_json::Value>, ApiError> {
    s.ask(|r| TrackingMsg::GetSimTruth(r).into())
        .await?
        .map(Json)
        .ok_or_else(|| {
            ApiError::not_found(
                "no simulator is embedded (ground truth exists only with `skein up --sim N`)",
            )
        })
}
