//! PX4 parameters through a vehicle's link: `GET /api/v1/vehicles/{id}/params`, `GET` /
//! `PUT /api/v1/vehicles/{id}/params/{name}` (`{"name", "value", "type"}`), each answered
//! once PX4's PARAM_VALUE arrives (resends included).

use crate::error::ApiError;
use crate::path_params::{PX4_PARAM_NAME_MAX, VehicleId, VehicleParam};
use crate::requests::px4_param_write::ParamValueRequest;
use crate::responses::{ParamEntry, ParamValue};
use crate::{ApiState, COORDINATOR_TIMEOUT, requests};
use axum::Json;
use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use ractor::ActorRef;
use skein_link::{LinkError, Px4LinkMsg};
use skein_swarm::FleetMsg;
use skein_swarm::payload::PayloadCommandError;
use std::time::Duration;

/// How long a parameter exchange may take (resends included).
const PARAM_TIMEOUT: Duration = Duration::from_secs(15);

/// The PX4 link of vehicle `id`: 404 for an unknown vehicle, 503 when it has none now.
pub(crate) async fn link_of(s: &ApiState, id: &str) -> Result<ActorRef<Px4LinkMsg>, ApiError> {
    let id2 = id.to_string();
    match s.ask(move |r| FleetMsg::GetLink(id2, r).into()).await? {
        Ok(link) => Ok(link),
        Err(PayloadCommandError::Refused(why)) => Err(ApiError::unavailable(why)),
        Err(e) => Err(e.into()),
    }
}

/// Asks vehicle `id`'s link; 503 when it does not answer within `timeout`.
pub(crate) async fn ask_link<T: Send + 'static>(
    link: &ActorRef<Px4LinkMsg>,
    msg: impl FnOnce(ractor::RpcReplyPort<T>) -> Px4LinkMsg,
    timeout: Duration,
    id: &str,
) -> Result<T, ApiError> {
    match link.call(msg, Some(timeout)).await {
        Ok(ractor::rpc::CallResult::Success(v)) => Ok(v),
        _ => Err(ApiError::unavailable(format!(
            "the link of `{id}` did not answer"
        ))),
    }
}

/// The answer for a parameter value: an integer for `int32`, a number for `real32`.
///
/// # Errors
/// 502 for a non-finite `real32` (JSON has no NaN; PX4 sends none).
fn param_json(
    name: &str,
    v: skein_mavlink::param::ParamValue,
) -> Result<Json<ParamValue>, ApiError> {
    use skein_mavlink::param::ParamValue as Value;
    let (value, param_type) = match v {
        Value::Int32(i) => (serde_json::Number::from(i), "int32"),
        Value::Real32(f) => (
            serde_json::Number::from_f64(f64::from(f)).ok_or_else(|| {
                ApiError::status(
                    StatusCode::BAD_GATEWAY,
                    format!("the vehicle sent `{name}` = {f}, not a finite number"),
                )
            })?,
            "real32",
        ),
    };
    Ok(Json(ParamValue {
        name: name.to_string(),
        value,
        param_type,
    }))
}

/// A parameter exchange that failed. The link answers [`LinkError::NoLink`] when the
/// vehicle is not heard; a timeout with the vehicle heard means it did not answer for
/// this name after every resend, which is what PX4 does for a parameter it does not have:
/// 404 naming `name`.
fn link_error(name: &str, e: LinkError) -> ApiError {
    let status = match &e {
        LinkError::Timeout { .. } => {
            return ApiError {
                status: StatusCode::NOT_FOUND,
                error: format!(
                    "the vehicle did not answer for parameter `{name}` ({e}): PX4 answers nothing for a parameter it does not have"
                ),
                field: Some("name".into()),
            };
        }
        LinkError::Rejected { .. } | LinkError::ModeNotConfirmed { .. } => StatusCode::CONFLICT,
        LinkError::NoLink | LinkError::Send(_) => StatusCode::SERVICE_UNAVAILABLE,
    };
    ApiError::status(status, e.to_string())
}

fn check_param_name(name: &str) -> Result<(), ApiError> {
    if name.is_empty() || name.len() > PX4_PARAM_NAME_MAX || !name.is_ascii() {
        return Err(ApiError::field(
            "name",
            format!(
                "`{name}` is not a PX4 parameter name (1 to {PX4_PARAM_NAME_MAX} ASCII characters)"
            ),
        ));
    }
    Ok(())
}

/// The PX4 parameters seen so far
#[utoipa::path(get, path = "/api/v1/vehicles/{id}/params", params(VehicleId),
    responses((status = 200, body = [ParamEntry]), (status = 404), (status = 503)))]
pub(crate) async fn list_params(
    State(s): State<ApiState>,
    Path(VehicleId { id }): Path<VehicleId>,
) -> Result<Json<Vec<ParamEntry>>, ApiError> {
    let link = link_of(&s, &id).await?;
    let all = ask_link(&link, Px4LinkMsg::Params, COORDINATOR_TIMEOUT, &id).await?;
    Ok(Json(
        all.into_iter()
            .map(|(name, v)| ParamEntry {
                name,
                value: v.as_f64(),
            })
            .collect(),
    ))
}

/// Read a PX4 parameter (PARAM_REQUEST_READ)
#[utoipa::path(get, path = "/api/v1/vehicles/{id}/params/{name}", params(VehicleParam),
    responses((status = 200, body = ParamValue), (status = 400), (status = 404),
        (status = 409), (status = 503)))]
pub(crate) async fn get_param(
    State(s): State<ApiState>,
    Path(VehicleParam { id, name }): Path<VehicleParam>,
) -> Result<Json<ParamValue>, ApiError> {
    check_param_name(&name)?;
    let link = link_of(&s, &id).await?;
    let n = name.clone();
    let v = ask_link(
        &link,
        move |r| Px4LinkMsg::ParamGet(n, r),
        PARAM_TIMEOUT,
        &id,
    )
    .await?
    .map_err(|e| link_error(&name, e))?;
    param_json(&name, v)
}

/// Write a PX4 parameter (PARAM_SET), answered with the value PX4 confirms
#[utoipa::path(put, path = "/api/v1/vehicles/{id}/params/{name}", params(VehicleParam),
    request_body = ParamValueRequest,
    responses((status = 200, body = ParamValue), (status = 400), (status = 404),
        (status = 409), (status = 503)))]
pub(crate) async fn put_param(
    State(s): State<ApiState>,
    Path(VehicleParam { id, name }): Path<VehicleParam>,
    body: Bytes,
) -> Result<Json<ParamValue>, ApiError> {
    check_param_name(&name)?;
    let value = requests::px4_param_write::param_value(&body)?;
    let link = link_of(&s, &id).await?;
    let n = name.clone();
    let v = ask_link(
        &link,
        move |r| Px4LinkMsg::ParamSet(n, value, r),
        PARAM_TIMEOUT,
        &id,
    )
    .await?
    .map_err(|e| link_error(&name, e))?;
    param_json(&name, v)
}
