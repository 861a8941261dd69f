//! What the swarm says about itself, read-only: `GET /api/v1/health` (public),
//! `GET /api/v1/supervision` (the actor tree), `GET /metrics` (Prometheus),
//! `GET /api/v1/links` (MAVLink counters per endpoint).

use crate::ApiState;
use crate::error::ApiError;
use axum::Json;
use axum::extract::State;
use axum::http::header;
use axum::response::{IntoResponse, Response};
use skein_swarm::coordinator::messages::{EndpointStats, Health};
use skein_swarm::supervision::TreeNode;
use skein_swarm::{AdminMsg, FleetMsg};

/// Swarm health (never needs a token)
#[utoipa::path(get, path = "/api/v1/health",
    responses((status = 200, body = Health), (status = 503)))]
pub(crate) async fn health(State(s): State<ApiState>) -> Result<Json<Health>, ApiError> {
    let mut h = s.ask(|r| AdminMsg::Health(r).into()).await?;
    h.coordinator_role = s.election.as_ref().map(|e| e.borrow().role);
    Ok(Json(h))
}

/// The actor tree: status, restarts, failures
#[utoipa::path(get, path = "/api/v1/supervision",
    responses((status = 200, body = TreeNode)))]
pub(crate) async fn supervision_tree(
    State(s): State<ApiState>,
) -> Result<Json<TreeNode>, ApiError> {
    Ok(Json(s.reads.supervision()))
}

/// Prometheus / OpenMetrics counters
#[utoipa::path(get, path = "/metrics",
    responses((status = 200, body = String, content_type = "application/openmetrics-text"),
        (status = 503)))]
pub(crate) async fn metrics(State(s): State<ApiState>) -> Result<Response, ApiError> {
    let text = s.ask(|r| AdminMsg::RenderMetrics(r).into()).await?;
    Ok((
        [(
            header::CONTENT_TYPE,
            "application/openmetrics-text; version=1.0.0; charset=utf-8",
        )],
        text,
    )
        .into_response())
}

/// MAVLink counters per endpoint
#[utoipa::path(get, path = "/api/v1/links",
    responses((status = 200, body = [EndpointStats]), (status = 503)))]
pub(crate) async fn links(State(s): State<ApiState>) -> Result<Json<Vec<EndpointStats>>, ApiError> {
    Ok(Json(s.ask(|r| FleetMsg::LinkStats(r).into()).await?))
}
