//! Attaching and detaching payloads at run time, and how payload errors become HTTP
//! answers.
//!
//! - `POST /api/v1/vehicles/{id}/payloads` `{"slot", "kind", "plugin"?, "isolation"?,
//!   "config"?}` → 201 with the payload as `GET …/payloads` lists it, once its driver
//!   exists. 400 naming the field for a malformed body or unknown field, an unknown kind
//!   (`kind`) or plugin (`plugin`), or a config the plugin refused at creation (`config`;
//!   the slot is not kept); 409 naming `slot` for a slot the vehicle has; 404 for an
//!   unknown vehicle.
//! - `DELETE /api/v1/vehicles/{id}/payloads/{slot}` → `{"detached": slot, "kind"}` after
//!   the driver's `shutdown` ran; 404 for an unknown vehicle or slot.
//!
//! Both last until skein restarts: the vehicle model (`skein up --config`) is what a
//! restart starts from.

use crate::error::ApiError;
use crate::{ApiState, requests};
use axum::Json;
use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use skein_swarm::CoordinatorMsg;
use skein_swarm::payload::PayloadCommandError;

pub use crate::requests::payloads::parse_attach;

/// Refuses a command to a payload that is not running (`waiting_for_plugin`, `failed`,
/// `stopped`, `restarting`): 409 naming `slot`, a state of the resource the caller can
/// see in `GET …/payloads` (and the message says which), not a failure of the server.
/// A payload that fails or hangs on the command itself is a 503 ([`payload_error`]).
///
/// # Errors
/// 404 for an unknown vehicle, 409 as above, 503 without an answer from the coordinator.
pub async fn require_running(s: &ApiState, id: &str, slot: &str) -> Result<(), ApiError> {
    let id2 = id.to_string();
    let Some(vehicle) = s.ask(move |r| CoordinatorMsg::GetVehicle(id2, r)).await? else {
        return Err(ApiError::not_found(format!("no vehicle `{id}`")));
    };
    let Some(p) = vehicle.payloads.iter().find(|p| p["slot"] == slot) else {
        return Ok(()); // the vehicle answers 404 naming its slots
    };
    match p["status"].as_str() {
        None | Some("running") => Ok(()),
        Some(status) => {
            let why = p["waiting_for"]
                .as_str()
                .map(|w| format!(": {w}"))
                .unwrap_or_default();
            Err(ApiError::conflict(
                format!("payload `{slot}` of {id} is not running ({status}){why}"),
                Some("slot"),
            ))
        }
    }
}

/// The HTTP answer for a payload request that got no answer from the payload: 404, 503
/// (it failed or hung handling the command, or stopped running meanwhile; a payload known
/// not to be running is refused before, see [`require_running`]), 400 (a plugin's refusal names the field as `"field: message"`
/// by convention), 400 or 409 naming the field.
pub fn payload_error(e: PayloadCommandError) -> ApiError {
    match e {
        PayloadCommandError::NotFound(why) => ApiError::not_found(why),
        PayloadCommandError::Unavailable(why) => ApiError::unavailable(why),
        PayloadCommandError::Refused(why) => {
            let field = why
                .split_once(':')
                .map(|(f, _)| f.trim())
                .filter(|f| {
                    !f.is_empty() && f.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
                })
                .map(str::to_string);
            ApiError {
                status: StatusCode::BAD_REQUEST,
                error: why,
                field,
            }
        }
        PayloadCommandError::Invalid { field, error } => ApiError::field(&field, error),
        PayloadCommandError::Conflict { field, error } => ApiError::conflict(error, Some(&field)),
    }
}

/// `GET /api/v1/vehicles/{id}/payloads`.
pub(crate) async fn list_payloads(
    State(s): State<ApiState>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let id2 = id.clone();
    match s.ask(move |r| CoordinatorMsg::GetVehicle(id2, r)).await? {
        Some(v) => Ok(Json(v.payloads).into_response()),
        None => Err(ApiError::not_found(format!("no vehicle `{id}`"))),
    }
}

/// `POST /api/v1/vehicles/{id}/payloads/{slot}`: the payload's own command.
pub(crate) async fn payload_command(
    State(s): State<ApiState>,
    Path((id, slot)): Path<(String, String)>,
    body: Bytes,
) -> Result<Response, ApiError> {
    let cmd = serde_json::Value::Object(requests::object(&body)?);
    require_running(&s, &id, &slot).await?;
    match s
        .ask(move |r| CoordinatorMsg::PayloadCommand(id, slot, cmd, r))
        .await?
    {
        Ok(answer) => Ok(Json(answer).into_response()),
        Err(e) => Err(payload_error(e)),
    }
}

/// `POST /api/v1/vehicles/{id}/payloads`.
pub(crate) async fn attach_payload(
    State(s): State<ApiState>,
    Path(id): Path<String>,
    body: Bytes,
) -> Result<Response, ApiError> {
    let spec = parse_attach(&body)?;
    match s
        .ask(move |r| CoordinatorMsg::AttachPayload(id, spec, r))
        .await?
    {
        Ok(payload) => Ok((StatusCode::CREATED, Json(payload)).into_response()),
        Err(e) => Err(payload_error(e)),
    }
}

/// `DELETE /api/v1/vehicles/{id}/payloads/{slot}`.
pub(crate) async fn detach_payload(
    State(s): State<ApiState>,
    Path((id, slot)): Path<(String, String)>,
) -> Result<Response, ApiError> {
    match s
        .ask(move |r| CoordinatorMsg::DetachPayload(id, slot, r))
        .await?
    {
        Ok(answer) => Ok(Json(answer).into_response()),
        Err(e) => Err(payload_error(e)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn payload_errors_map_to_statuses_and_fields() {
        let e = payload_error(PayloadCommandError::Conflict {
            field: "slot".into(),
            error: "exists".into(),
        });
        assert_eq!(
            (e.status, e.field.as_deref()),
            (StatusCode::CONFLICT, Some("slot"))
        );
        let e = payload_error(PayloadCommandError::Invalid {
            field: "config".into(),
            error: "lamp config: unknown field `x`".into(),
        });
        assert_eq!(
            (e.status, e.field.as_deref()),
            (StatusCode::BAD_REQUEST, Some("config"))
        );
        let e = payload_error(PayloadCommandError::Refused("on: must be a boolean".into()));
        assert_eq!(e.field.as_deref(), Some("on"));
        let e = payload_error(PayloadCommandError::Unavailable("waiting".into()));
        assert_eq!(e.status, StatusCode::SERVICE_UNAVAILABLE);
    }
}
