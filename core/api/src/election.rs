//! The coordinator role in the API (`skein coordinator`): `GET /api/v1/coordinator`
//! shows the election ([`ElectionStatus`]), and a standby refuses every write with a 409
//! naming the active coordinator and where its API is (`standby_refuses_writes`), so
//! an operator is never flying from a coordinator that sends nothing.
//!
//! `skein up` is not a candidate: it has no election, the route answers 404, and no
//! write is refused for this reason.

use crate::ApiState;
use crate::error::ApiError;
use axum::Json;
use axum::extract::{Request, State};
use axum::http::{Method, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use skein_swarm::clocks::ClockOffset;
use skein_swarm::election::{CoordinatorRole, ElectionStatus};
use skein_swarm::link_security::LinkSecurityStatus;
use std::collections::BTreeMap;

/// The election as this candidate sees it, and its peers' clocks.
#[derive(Debug, Clone, serde::Serialize, utoipa::ToSchema)]
pub struct CoordinatorStatus {
    /// The election: this candidate's lease and role, the active one, the peers.
    #[serde(flatten)]
    pub election: ElectionStatus,
    /// The clocks of the agents and coordinators this process exchanged clock samples
    /// with, by id: their offset from this one's (theirs minus this, ms) and its
    /// uncertainty. Their stamps are converted with it before they are aged.
    pub clocks: BTreeMap<String, ClockOffset>,
    /// The swarm link's DDS Security: this coordinator's enclave and, for each remote
    /// vehicle, the agent its certificate proves; `null` when the link is not secured
    /// (any host on the swarm's network can then speak on it).
    pub dds_security: Option<LinkSecurityStatus>,
}

/// The coordinator election as this candidate sees it, and its peers' clocks (skein
/// coordinator only)
#[utoipa::path(get, path = "/api/v1/coordinator",
    responses((status = 200, body = CoordinatorStatus), (status = 404)))]
pub(crate) async fn status(State(s): State<ApiState>) -> Result<Json<CoordinatorStatus>, ApiError> {
    match &s.election {
        Some(e) => Ok(Json(CoordinatorStatus {
            election: e.borrow().clone(),
            clocks: s
                .clocks
                .as_ref()
                .map(|c| c.snapshot(skein_swarm::protocol::wall_us()))
                .unwrap_or_default(),
            dds_security: s.link_security.as_ref().map(|l| l.snapshot()),
        })),
        None => Err(ApiError::not_found(
            "this skein is not a coordinator candidate (`skein up` runs alone; see \
             `skein coordinator --priority P`)",
        )),
    }
}

/// Why a standby refuses a write, naming the active coordinator (or that there is none
/// yet).
pub fn refusal(status: &ElectionStatus) -> String {
    let me = &status.this.coordinator_id;
    match &status.active {
        Some(a) => format!(
            "coordinator `{me}` is a standby: `{}` (priority {}, epoch {}) is active, at {}",
            a.coordinator_id, a.priority, a.epoch, a.api_url
        ),
        None => format!(
            "coordinator `{me}` is a standby and no coordinator is active yet (election in \
             progress); retry in a second"
        ),
    }
}

/// Middleware: on a standby, anything but `GET` / `HEAD` is answered 409 with
/// [`refusal`]; on the active candidate and in `skein up`, everything passes.
pub(crate) async fn standby_refuses_writes(
    State(s): State<ApiState>,
    req: Request,
    next: Next,
) -> Response {
    if req.method() != Method::GET
        && req.method() != Method::HEAD
        && let Some(e) = &s.election
    {
        let refused = {
            let status = e.borrow();
            (status.role == CoordinatorRole::Standby).then(|| refusal(&status))
        };
        if let Some(why) = refused {
            return ApiError::status(StatusCode::CONFLICT, why).into_response();
        }
    }
    next.run(req).await
}
