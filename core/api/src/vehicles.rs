//! The vehicles: `GET /api/v1/vehicles`, `GET /api/v1/vehicles/{id}`, and commands to one
//! vehicle or to the whole swarm (`POST …/commands`: 202 with the command id once the
//! state machine accepted it; what PX4 then did follows on the stream as a
//! `command_result` event).
//!
//! The command body is [`crate::requests::commands`]' type: its parser and schema live
//! there, and these handlers only name it.

use crate::ApiState;
use crate::error::ApiError;
use crate::path_params::VehicleId;
use crate::requests::commands::{self, Command, SwarmCommandRequest, VehicleCommandRequest};
use crate::responses::Cleared;
use axum::Json;
use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use skein_model::vehicle::VehicleSnapshot;
use skein_swarm::{CommandMsg, CommandOutcome, FormationMsg};

/// Every vehicle, sorted by id.
#[utoipa::path(get, path = "/api/v1/vehicles",
    responses((status = 200, body = [VehicleSnapshot])))]
pub(crate) async fn list_vehicles(
    State(s): State<ApiState>,
) -> Result<Json<Vec<VehicleSnapshot>>, ApiError> {
    Ok(Json(s.reads.vehicles()))
}

/// One vehicle.
#[utoipa::path(get, path = "/api/v1/vehicles/{id}", params(VehicleId),
    responses((status = 200, body = VehicleSnapshot), (status = 404)))]
pub(crate) async fn get_vehicle(
    State(s): State<ApiState>,
    Path(VehicleId { id }): Path<VehicleId>,
) -> Result<Json<VehicleSnapshot>, ApiError> {
    s.reads
        .vehicle(&id)
        .map(Json)
        .ok_or_else(|| ApiError::no_vehicle(&id))
}

/// The coordinator's refusal of a command to vehicle `id`: no such vehicle (`None`, 404),
/// or why its state refuses it (409 naming `command`).
fn refused(id: &str, reason: Option<String>) -> ApiError {
    match reason {
        None => ApiError::no_vehicle(id),
        Some(reason) => ApiError::conflict(reason, Some("command")),
    }
}

fn accepted(outcome: CommandOutcome) -> Response {
    (StatusCode::ACCEPTED, Json(outcome)).into_response()
}

/// A command for one vehicle
///
/// 202 once its state machine accepted it (the outcome follows on the stream);
/// `clear_hazard` answers 200.
#[utoipa::path(post, path = "/api/v1/vehicles/{id}/commands", params(VehicleId),
    request_body = VehicleCommandRequest,
    responses((status = 202, body = CommandOutcome), (status = 200, body = Cleared),
        (status = 400), (status = 404), (status = 409), (status = 503)))]
pub(crate) async fn vehicle_command(
    State(s): State<ApiState>,
    Path(VehicleId { id }): Path<VehicleId>,
    body: Bytes,
) -> Result<Response, ApiError> {
    let id2 = id.clone();
    match commands::vehicle_command(&body)? {
        Command::ClearHazard => {
            s.write(move |r| FormationMsg::ClearHazard(id2, r).into())
                .await?
                .map_err(|e| refused(&id, e))?;
            Ok(Json(Cleared { cleared: id }).into_response())
        }
        cmd => {
            let outcome = s
                .write(move |r| CommandMsg::VehicleCommand(id2, cmd, r).into())
                .await?
                .map_err(|e| refused(&id, e))?;
            s.record_command(outcome.command_id, &id, &body);
            Ok(accepted(outcome))
        }
    }
}

/// A command for every vehicle
///
/// 409 when every vehicle refused.
#[utoipa::path(post, path = "/api/v1/swarm/commands",
    request_body = SwarmCommandRequest,
    responses((status = 202, body = CommandOutcome), (status = 400), (status = 409),
        (status = 503)))]
pub(crate) async fn swarm_command(
    State(s): State<ApiState>,
    body: Bytes,
) -> Result<Response, ApiError> {
    let cmd = commands::swarm_command(&body)?;
    let outcome = s
        .write(move |r| CommandMsg::SwarmCommand(cmd, r).into())
        .await?;
    if outcome.accepted.is_empty() {
        let error = if outcome.refused.is_empty() {
            "no vehicles in the swarm".to_string()
        } else {
            outcome
                .refused
                .iter()
                .map(|r| format!("{}: {}", r.id, r.reason))
                .collect::<Vec<_>>()
                .join("; ")
        };
        return Err(ApiError::conflict(error, Some("command")));
    }
    s.record_command(outcome.command_id, "swarm", &body);
    Ok(accepted(outcome))
}
