//! PX4 parameters through a vehicle's link: `GET /api/v1/vehicles/{id}/params`, `GET` /
//! `PUT /api/v1/vehicles/{id}/params/{name}` (`{"name", "value", "type"}`), each answered
//! once PX4's PARAM_VALUE arrives (resends included).

use crate::error::ApiError;
use crate::{ApiState, COORDINATOR_TIMEOUT, payloads, requests, responses};
use axum::Json;
use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use ractor::ActorRef;
use skein_swarm::CoordinatorMsg;
use skein_swarm::payload::PayloadCommandError;
use std::time::Duration;

/// How long a parameter exchange may take (resends included).
const PARAM_TIMEOUT: Duration = Duration::from_secs(15);

async fn link_of(s: &ApiState, id: &str) -> Result<ActorRef<skein_link::Px4LinkMsg>, ApiError> {
    let id2 = id.to_string();
    match s.ask(move |r| CoordinatorMsg::GetLink(id2, r)).await? {
        Ok(link) => Ok(link),
        Err(PayloadCommandError::NotFound(why)) => Err(ApiError::not_found(why)),
        Err(PayloadCommandError::Unavailable(why) | PayloadCommandError::Refused(why)) => {
            Err(ApiError::unavailable(why))
        }
        Err(e) => Err(payloads::payload_error(e)),
    }
}

/// The answer for a parameter value: an integer for `int32`, a number for `real32`.
///
/// # Errors
/// 502 for a non-finite `real32` (JSON has no NaN; PX4 sends none).
fn param_json(name: &str, v: skein_mavlink::param::ParamValue) -> Result<Response, ApiError> {
    use skein_mavlink::param::ParamValue;
    let (value, param_type) = match v {
        ParamValue::Int32(i) => (serde_json::Number::from(i), "int32"),
        ParamValue::Real32(f) => (
            serde_json::Number::from_f64(f64::from(f)).ok_or_else(|| {
                ApiError::status(
                    StatusCode::BAD_GATEWAY,
                    format!("the vehicle sent `{name}` = {f}, not a finite number"),
                )
            })?,
            "real32",
        ),
    };
    Ok(Json(responses::ParamValue {
        name: name.to_string(),
        value,
        param_type,
    })
    .into_response())
}

/// A parameter exchange that failed. The link answers [`LinkError::NoLink`] when the
/// vehicle is not heard; a timeout with the vehicle heard means it did not answer for
/// this name after every resend, which is what PX4 does for a parameter it does not have:
/// 404 naming `name`.
fn link_error(name: &str, e: skein_link::LinkError) -> ApiError {
    use skein_link::LinkError;
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
    if name.is_empty() || name.len() > 16 || !name.is_ascii() {
        return Err(ApiError::field(
            "name",
            format!("`{name}` is not a PX4 parameter name (1 to 16 ASCII characters)"),
        ));
    }
    Ok(())
}

pub(crate) async fn list_params(
    State(s): State<ApiState>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let link = link_of(&s, &id).await?;
    match link
        .call(skein_link::Px4LinkMsg::Params, Some(COORDINATOR_TIMEOUT))
        .await
    {
        Ok(ractor::rpc::CallResult::Success(all)) => Ok(Json(
            all.into_iter()
                .map(|(name, v)| responses::ParamEntry {
                    name,
                    value: v.as_f64(),
                })
                .collect::<Vec<_>>(),
        )
        .into_response()),
        _ => Err(ApiError::unavailable(format!(
            "the link of `{id}` did not answer"
        ))),
    }
}

pub(crate) async fn get_param(
    State(s): State<ApiState>,
    Path((id, name)): Path<(String, String)>,
) -> Result<Response, ApiError> {
    check_param_name(&name)?;
    let link = link_of(&s, &id).await?;
    let n = name.clone();
    match link
        .call(
            move |r| skein_link::Px4LinkMsg::ParamGet(n, r),
            Some(PARAM_TIMEOUT),
        )
        .await
    {
        Ok(ractor::rpc::CallResult::Success(Ok(v))) => param_json(&name, v),
        Ok(ractor::rpc::CallResult::Success(Err(e))) => Err(link_error(&name, e)),
        _ => Err(ApiError::unavailable(format!(
            "the link of `{id}` did not answer"
        ))),
    }
}

pub(crate) async fn put_param(
    State(s): State<ApiState>,
    Path((id, name)): Path<(String, String)>,
    body: Bytes,
) -> Result<Response, ApiError> {
    check_param_name(&name)?;
    let value = requests::px4_param_write::param_value(&body)?;
    let link = link_of(&s, &id).await?;
    let n = name.clone();
    match link
        .call(
            move |r| skein_link::Px4LinkMsg::ParamSet(n, value, r),
            Some(PARAM_TIMEOUT),
        )
        .await
    {
        Ok(ractor::rpc::CallResult::Success(Ok(v))) => param_json(&name, v),
        Ok(ractor::rpc::CallResult::Success(Err(e))) => Err(link_error(&name, e)),
        _ => Err(ApiError::unavailable(format!(
            "the link of `{id}` did not answer"
        ))),
    }
}
