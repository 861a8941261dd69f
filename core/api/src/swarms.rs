//! Hostile swarm routes: the swarms the tracker recognised, and observing one.
//!
//! - `GET /api/v1/swarms`: `{"swarms": [SwarmView…]}`, each `{"id": "swarm-2", "members":
//!   ["track-1", …], "centroid": {"north_m", "east_m", "down_m"}, "velocity": {"north_m_s",
//!   "east_m_s", "down_m_s"}, "speed_m_s", "course_deg", "shape": "line" | "wedge" |
//!   "cluster", "shape_heading_deg", "extent": {"length_m", "width_m", "radius_m"},
//!   "forecast": [{"horizon_s", "position", "sigma_m", "model"}], "age_s"}` (swarm frame;
//!   see `skein_swarm::tracking::swarms`), with `observed_by` and `stations`.
//! - `POST /api/v1/swarms/{id}/observe` `{"vehicles"?: […], "stations"?: true,
//!   "standoff_m"?: 25}` (operator): the observers' gimbals follow the swarm's centroid and,
//!   unless `"stations": false`, they fly to the stations that keep every member in two
//!   cameras' view at the best triangulation angle, re-planned as it moves; `{"swarm",
//!   "vehicles"}`. 404 `id`, 400 `vehicles` / `standoff_m`, 409 `stations` (no stations
//!   meet the limits: the reason).
//! - `DELETE /api/v1/swarms/{id}/observe` (operator): stop; the gimbals hold their angles,
//!   the observers hold where they are; `{"swarm", "released"}`.

use crate::ApiState;
use crate::error::ApiError;
use crate::path_params::SwarmId;
use crate::requests::tracks::ObserveRequest;
use crate::tracks::observed_by;
use axum::Json;
use axum::body::Bytes;
use axum::extract::{Path, State};
use serde::Serialize;
use skein_swarm::TrackingMsg;
use skein_swarm::coordinator::observe::{ObserveRefusal, ObserveSpec};
use skein_swarm::coordinator::stations::StationsView;
use skein_swarm::tracks::SwarmView;
use utoipa::ToSchema;

/// `GET /api/v1/swarms`.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct SwarmsListing {
    /// The hostile swarms.
    pub swarms: Vec<SwarmEntry>,
}

/// A hostile swarm and who observes it.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct SwarmEntry {
    /// The swarm (swarm frame).
    #[serde(flatten)]
    pub swarm: SwarmView,
    /// Vehicles whose gimbals follow it (`POST /api/v1/swarms/{id}/observe`).
    pub observed_by: Vec<String>,
    /// Their stations, when they observe it from stations.
    pub stations: Option<StationsView>,
}

/// `POST /api/v1/swarms/{id}/observe`.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct ObservingSwarm {
    /// The swarm.
    pub swarm: String,
    /// The vehicles now keeping it in view.
    pub vehicles: Vec<String>,
}

/// `DELETE /api/v1/swarms/{id}/observe`.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct ReleasedSwarm {
    /// The swarm.
    pub swarm: String,
    /// The vehicles that stopped observing it.
    pub released: Vec<String>,
}

/// The hostile swarms (swarm frame), their forecasts and who observes each
#[utoipa::path(get, path = "/api/v1/swarms",
    responses((status = 200, body = SwarmsListing)))]
pub(crate) async fn list_swarms(
    State(s): State<ApiState>,
) -> Result<Json<SwarmsListing>, ApiError> {
    let picture = s.reads.air_picture();
    let seen = &picture.observations;
    let swarms = picture
        .swarms
        .into_iter()
        .map(|swarm| SwarmEntry {
            observed_by: observed_by(&seen.observing, &swarm.id),
            stations: seen
                .stations
                .iter()
                .find(|st| st.target == swarm.id)
                .cloned(),
            swarm,
        })
        .collect();
    Ok(Json(SwarmsListing { swarms }))
}

/// Observe the swarm from the best stations
///
/// The gimbals of the given vehicles (default: every observation UAV) follow the swarm's
/// centroid and, unless `"stations": false`, the vehicles fly to the stations that fix
/// every member best, re-planned as the swarm moves.
#[utoipa::path(post, path = "/api/v1/swarms/{id}/observe", params(SwarmId),
    request_body = Option<ObserveRequest>,
    responses((status = 200, body = ObservingSwarm), (status = 400), (status = 404),
        (status = 409), (status = 503)),
    extensions(("x-skein-swarm-checks" = json!({
        "vehicles": "vehicles of the swarm that have a gimbal, airborne for stations",
        "stations": "stations must keep the stand-off, the separation and the geofence"
    }))))]
pub(crate) async fn observe_swarm(
    State(s): State<ApiState>,
    Path(SwarmId { id }): Path<SwarmId>,
    body: Bytes,
) -> Result<Json<ObservingSwarm>, ApiError> {
    let req = crate::requests::parse_or_empty::<ObserveRequest>(&body)?;
    let spec = ObserveSpec {
        target: id.clone(),
        vehicles: req.vehicles,
        stations: req.stations.unwrap_or(true),
        standoff_m: req.standoff_m,
    };
    if !id.starts_with(skein_swarm::tracks::SWARM_PREFIX) {
        return Err(ObserveRefusal::UnknownTarget(format!(
            "no swarm `{id}` (see GET /api/v1/swarms)"
        ))
        .into());
    }
    let vehicles = s
        .write(move |r| TrackingMsg::Observe(spec, r).into())
        .await??;
    Ok(Json(ObservingSwarm {
        swarm: id,
        vehicles,
    }))
}

/// Stop observing the swarm; the gimbals hold their angles, the observers hold
#[utoipa::path(delete, path = "/api/v1/swarms/{id}/observe", params(SwarmId),
    responses((status = 200, body = ReleasedSwarm), (status = 503)))]
pub(crate) async fn stop_observing_swarm(
    State(s): State<ApiState>,
    Path(SwarmId { id }): Path<SwarmId>,
) -> Result<Json<ReleasedSwarm>, ApiError> {
    let swarm = id.clone();
    let released = s
        .write(move |r| TrackingMsg::StopObserving(swarm, r).into())
        .await?;
    Ok(Json(ReleasedSwarm {
        swarm: id,
        released,
    }))
}
