//! Formation flight over the API: the formation (`GET` / `PUT` / `DELETE
//! /api/v1/formation`), its shapes, and the motion of its reference point (`POST
//! /api/v1/formation/leader/{goto,waypoints,orbit,hold}`, one route each).
//!
//! The bodies are parsed by [`crate::requests::formation`] and
//! [`crate::requests::leader`]; what depends on the swarm (its vehicles, geofence, speed
//! limits and separation) the coordinator checks, naming the field (see
//! [`crate::error`]), and each operation lists those fields in the contract
//! (`x-skein-swarm-checks`).

use crate::ApiState;
use crate::error::ApiError;
use crate::requests::formation::FormationRequest;
use crate::requests::leader::{
    self, LeaderGoToRequest, LeaderHoldRequest, LeaderOrbitRequest, LeaderWaypointsRequest,
};
use crate::responses::ShapeInfo;
use axum::Json;
use axum::body::Bytes;
use axum::extract::State;
use skein_model::formation::Shape;
use skein_swarm::formation::LeaderMotion;
use skein_swarm::{FormationMsg, FormationStatus};

/// The formation status
#[utoipa::path(get, path = "/api/v1/formation",
    responses((status = 200, body = FormationStatus)))]
pub(crate) async fn get_formation(
    State(s): State<ApiState>,
) -> Result<Json<FormationStatus>, ApiError> {
    Ok(Json(s.reads.formation()))
}

/// Fly a formation
#[utoipa::path(put, path = "/api/v1/formation", request_body = FormationRequest,
    responses((status = 200, body = FormationStatus), (status = 400), (status = 503)),
    extensions(("x-skein-swarm-checks" = json!({
        "shape": "enough vehicles that can fly it (GET /api/v1/formation/shapes)",
        "spacing_m": "at least √2 × (minimum separation + tracking margin)",
        "leader": "a vehicle of the swarm, \"virtual\", or a confirmed track",
        "offsets": "custom shapes only, and slots apart as spacing_m must be",
        "altitude_m": "above 0, at most the geofence's max_altitude_m",
        "standoff_m": "only with a track as leader, and then required"
    }))))]
pub(crate) async fn put_formation(
    State(s): State<ApiState>,
    body: Bytes,
) -> Result<Json<FormationStatus>, ApiError> {
    let spec = crate::requests::formation::formation(&body)?;
    Ok(Json(
        s.write(move |r| FormationMsg::SetFormation(spec, r).into())
            .await??,
    ))
}

/// Stop flying the formation (members hold where they are)
#[utoipa::path(delete, path = "/api/v1/formation",
    responses((status = 200, body = FormationStatus), (status = 503)))]
pub(crate) async fn delete_formation(
    State(s): State<ApiState>,
) -> Result<Json<FormationStatus>, ApiError> {
    Ok(Json(
        s.write(|r| FormationMsg::ClearFormation(r).into()).await?,
    ))
}

/// The shapes, with the fewest vehicles each needs
#[utoipa::path(get, path = "/api/v1/formation/shapes",
    responses((status = 200, body = [ShapeInfo])))]
pub(crate) async fn shapes() -> Json<Vec<ShapeInfo>> {
    Json(
        Shape::ALL
            .iter()
            .map(|s| ShapeInfo {
                shape: *s,
                min_vehicles: s.min_vehicles(),
            })
            .collect(),
    )
}

/// Hands a leader motion to the coordinator: the formation status, or its refusal (400
/// naming the field, 409 `formation` without a formation).
async fn move_leader(
    s: &ApiState,
    motion: LeaderMotion,
) -> Result<Json<FormationStatus>, ApiError> {
    Ok(Json(
        s.write(move |r| FormationMsg::LeaderMotion(motion, r).into())
            .await??,
    ))
}

/// Move the formation's reference to a point
#[utoipa::path(post, path = "/api/v1/formation/leader/goto", request_body = LeaderGoToRequest,
    responses((status = 200, body = FormationStatus), (status = 400), (status = 409),
        (status = 503)),
    extensions(("x-skein-swarm-checks" = json!({
        "speed_m_s": "at most the slowest vehicle model's max_speed_m_s",
        "north_m": "the point inside the geofence (GET /api/v1/geofence)"
    }))))]
pub(crate) async fn leader_goto(
    State(s): State<ApiState>,
    body: Bytes,
) -> Result<Json<FormationStatus>, ApiError> {
    move_leader(&s, leader::goto(&body)?).await
}

/// Move the formation's reference along waypoints
#[utoipa::path(post, path = "/api/v1/formation/leader/waypoints",
    request_body = LeaderWaypointsRequest,
    responses((status = 200, body = FormationStatus), (status = 400), (status = 409),
        (status = 503)),
    extensions(("x-skein-swarm-checks" = json!({
        "speed_m_s": "at most the slowest vehicle model's max_speed_m_s",
        "waypoints": "every point inside the geofence (GET /api/v1/geofence)"
    }))))]
pub(crate) async fn leader_waypoints(
    State(s): State<ApiState>,
    body: Bytes,
) -> Result<Json<FormationStatus>, ApiError> {
    move_leader(&s, leader::waypoints(&body)?).await
}

/// Orbit the formation's reference around a centre
#[utoipa::path(post, path = "/api/v1/formation/leader/orbit", request_body = LeaderOrbitRequest,
    responses((status = 200, body = FormationStatus), (status = 400), (status = 409),
        (status = 503)),
    extensions(("x-skein-swarm-checks" = json!({
        "speed_m_s": "at most the slowest vehicle model's max_speed_m_s",
        "radius_m": "at least the minimum separation plus margin; the circle inside the geofence"
    }))))]
pub(crate) async fn leader_orbit(
    State(s): State<ApiState>,
    body: Bytes,
) -> Result<Json<FormationStatus>, ApiError> {
    move_leader(&s, leader::orbit(&body)?).await
}

/// Stop the formation's reference
#[utoipa::path(post, path = "/api/v1/formation/leader/hold",
    request_body = Option<LeaderHoldRequest>,
    responses((status = 200, body = FormationStatus), (status = 400), (status = 409),
        (status = 503)))]
pub(crate) async fn leader_hold(
    State(s): State<ApiState>,
    body: Bytes,
) -> Result<Json<FormationStatus>, ApiError> {
    move_leader(&s, leader::hold(&body)?).await
}
