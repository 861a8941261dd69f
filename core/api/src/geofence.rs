//! The geofence: `GET /api/v1/geofence` (the fence in force) and `PUT /api/v1/geofence`
//! (an operator's new fence: checked, given to every connected autopilot with the
//! mission protocol, then committed, or refused as a whole naming the field or the
//! vehicles; see `skein_swarm::coordinator::geofence`).

use crate::ApiState;
use crate::error::ApiError;
use axum::Json;
use axum::body::Bytes;
use axum::extract::State;
use skein_model::geofence::Geofence;
use skein_swarm::GeofenceMsg;
use skein_swarm::coordinator::geofence::{FenceChange, FenceRefusal};

/// The top-level field of a path (`exclusions[1].polygon` → `exclusions`): what an
/// answer names, the full path staying in the message.
fn top_level(field: &str) -> &str {
    field.split(['[', '.']).next().unwrap_or(field)
}

/// A refused change: 400 naming the field (the fence breaks a rule), 409 (the swarm's
/// state: a vehicle in the air outside, a vehicle's refusal, a change under way).
impl From<FenceRefusal> for ApiError {
    fn from(e: FenceRefusal) -> Self {
        match e {
            FenceRefusal::Invalid { field, error } => {
                ApiError::field(top_level(&field), format!("{field}: {error}"))
            }
            FenceRefusal::Conflict { field, error } => ApiError::conflict(error, field.as_deref()),
        }
    }
}

/// The geofence in force
#[utoipa::path(get, path = "/api/v1/geofence",
    responses((status = 200, body = Geofence), (status = 503)))]
pub(crate) async fn get_geofence(State(s): State<ApiState>) -> Result<Json<Geofence>, ApiError> {
    let live = s.ask(|r| GeofenceMsg::GetGeofence(r).into()).await?;
    Ok(Json(live.fence.clone()))
}

/// Put a new geofence in force, on skein and on every autopilot
///
/// Answered once every connected vehicle's autopilot holds it (uploaded with the mission
/// protocol and read back); if one refuses, none keeps it.
#[utoipa::path(put, path = "/api/v1/geofence", request_body = Geofence,
    responses((status = 200, body = FenceChange), (status = 400), (status = 409),
        (status = 503)),
    extensions(("x-skein-swarm-checks" = json!({
        "radius_m": "in (0, 100000] m",
        "max_altitude_m": "in (0, 10000] m",
        "min_altitude_m": "in [0, max_altitude_m)",
        "polygon": "none, or at least 3 vertices of a simple, non-degenerate polygon inside radius_m",
        "exclusions": "simple, non-degenerate polygons; circles of positive radius; within twice radius_m of the origin",
        "rally_points": "inside the geofence"
    }))))]
pub(crate) async fn put_geofence(
    State(s): State<ApiState>,
    body: Bytes,
) -> Result<Json<FenceChange>, ApiError> {
    let fence: Geofence = crate::requests::parse(&body).map_err(|mut e| {
        if let Some(f) = e.field.as_mut() {
            *f = top_level(f).to_string();
        }
        e
    })?;
    let change = s
        .ask(move |r| GeofenceMsg::SetGeofence(fence, r).into())
        .await??;
    Ok(Json(change))
}
