//! `POST /api/v1/faults`: make a named actor panic, hang, stop or fail, to rehearse
//! recovery (only with `--enable-fault-injection`: 403 otherwise).

use crate::ApiState;
use crate::error::ApiError;
use crate::requests::faults::FaultRequest;
use crate::responses::FaultInjected;
use axum::Json;
use axum::body::Bytes;
use axum::extract::State;
use axum::http::StatusCode;
use skein_swarm::AdminMsg;

/// Inject a fault into an actor (only with --enable-fault-injection)
#[utoipa::path(post, path = "/api/v1/faults", request_body = FaultRequest,
    responses((status = 202, body = FaultInjected), (status = 400), (status = 403),
        (status = 404), (status = 503)))]
pub(crate) async fn inject_fault(
    State(s): State<ApiState>,
    body: Bytes,
) -> Result<(StatusCode, Json<FaultInjected>), ApiError> {
    let (target, kind) = crate::requests::faults::fault(&body)?;
    let t = target.clone();
    s.ask(move |r| AdminMsg::InjectFault(t, kind, r).into())
        .await??;
    Ok((StatusCode::ACCEPTED, Json(FaultInjected { target, kind })))
}
