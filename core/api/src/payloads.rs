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

use crate::ApiState;
use crate::error::ApiError;
use crate::path_params::{PayloadSlot, VehicleId};
use crate::requests::payloads::AttachRequest;
use crate::responses::{Detached, PayloadView};
use axum::Json;
use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use serde_json::Value;
use skein_swarm::PayloadMsg;

pub use crate::requests::payloads::parse_attach;

/// Refuses a command to a payload that is not running (`waiting_for_plugin`, `failed`,
/// `stopped`, `restarting`): 409 naming `slot`, a state of the resource the caller can
/// see in `GET …/payloads` (and the message says which), not a failure of the server.
/// A payload that fails or hangs on the command itself is a 503 (see [`crate::error`]).
///
/// # Errors
/// 404 for an unknown vehicle, 409 as above.
pub async fn require_running(s: &ApiState, id: &str, slot: &str) -> Result<(), ApiError> {
    let Some(vehicle) = s.reads.vehicle(id) else {
        return Err(ApiError::no_vehicle(id));
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

/// The vehicle's payload slots
#[utoipa::path(get, path = "/api/v1/vehicles/{id}/payloads", params(VehicleId),
    responses((status = 200, body = [PayloadView]), (status = 404)))]
pub(crate) async fn list_payloads(
    State(s): State<ApiState>,
    Path(VehicleId { id }): Path<VehicleId>,
) -> Result<Json<Vec<Value>>, ApiError> {
    s.reads
        .vehicle(&id)
        .map(|v| Json(v.payloads))
        .ok_or_else(|| ApiError::no_vehicle(&id))
}

/// A payload's own JSON command; answered with its answer
#[utoipa::path(post, path = "/api/v1/vehicles/{id}/payloads/{slot}", params(PayloadSlot),
    request_body = Object,
    responses((status = 200, body = Object), (status = 400), (status = 404), (status = 409),
        (status = 503)),
    extensions(("x-skein-swarm-checks" = json!({
        "body": "the payload's own command, read by its plugin (gimbal: set_angles, …)"
    }))))]
pub(crate) async fn payload_command(
    State(s): State<ApiState>,
    Path(PayloadSlot { id, slot }): Path<PayloadSlot>,
    body: Bytes,
) -> Result<Json<Value>, ApiError> {
    let cmd = Value::Object(crate::requests::object(&body)?);
    require_running(&s, &id, &slot).await?;
    Ok(Json(
        s.ask(move |r| PayloadMsg::PayloadCommand(id, slot, cmd, r).into())
            .await??,
    ))
}

/// Attach a payload (until restart)
///
/// 201 with the payload as listed, once its driver exists.
#[utoipa::path(post, path = "/api/v1/vehicles/{id}/payloads", params(VehicleId),
    request_body = AttachRequest,
    responses((status = 201, body = PayloadView), (status = 400), (status = 404),
        (status = 409), (status = 503)),
    extensions(("x-skein-swarm-checks" = json!({
        "kind": "a kind a loaded plugin (or the built-in provider) provides",
        "plugin": "a loaded plugin that provides kind",
        "config": "what the plugin accepts at creation"
    }))))]
pub(crate) async fn attach_payload(
    State(s): State<ApiState>,
    Path(VehicleId { id }): Path<VehicleId>,
    body: Bytes,
) -> Result<(StatusCode, Json<Value>), ApiError> {
    let spec = parse_attach(&body)?;
    let payload = s
        .ask(move |r| PayloadMsg::AttachPayload(id, spec, r).into())
        .await??;
    Ok((StatusCode::CREATED, Json(payload)))
}

/// Detach a payload (until restart), after its driver's shutdown ran
#[utoipa::path(delete, path = "/api/v1/vehicles/{id}/payloads/{slot}", params(PayloadSlot),
    responses((status = 200, body = Detached), (status = 404), (status = 409),
        (status = 503)))]
pub(crate) async fn detach_payload(
    State(s): State<ApiState>,
    Path(PayloadSlot { id, slot }): Path<PayloadSlot>,
) -> Result<Json<Value>, ApiError> {
    Ok(Json(
        s.ask(move |r| PayloadMsg::DetachPayload(id, slot, r).into())
            .await??,
    ))
}
