//! Vehicle → coordinator: events and answers ([`FromVehicle`]), and why a payload command
//! got no answer from its payload ([`PayloadCommandError`]). The vehicle's state goes the
//! same way, keep-last, as its [`VehicleReport`](crate::VehicleReport)(crate::VehicleReport).

use serde::{Deserialize, Serialize};
use skein_model::fsm::VehicleState;

/// Why a payload command has no answer from the payload.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum PayloadCommandError {
    /// No such vehicle or slot (HTTP 404).
    NotFound(String),
    /// The payload is not running: failed, disabled or restarting (HTTP 503).
    Unavailable(String),
    /// The payload refused the command; its message (HTTP 400).
    Refused(String),
    /// A request field is wrong (HTTP 400 naming it): an attach of an unknown kind or
    /// plugin, or a config the plugin refused.
    Invalid {
        /// The field at fault (`"kind"`, `"plugin"`, `"config"`, `"slot"`).
        field: String,
        /// Why.
        error: String,
    },
    /// The request conflicts with the vehicle's payloads (HTTP 409 naming the field): an
    /// attach to a slot that exists, a detach of a slot being stopped.
    Conflict {
        /// The field at fault (`"slot"`).
        field: String,
        /// Why.
        error: String,
    },
}

/// Vehicle → coordinator (events and answers; the vehicle's state is in
/// [`VehicleReport`](crate::VehicleReport)).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum FromVehicle {
    /// The FSM accepted (`Ok`) or refused (`Err`, naming the state) a command.
    CommandAck {
        /// Vehicle id.
        id: String,
        /// The command's id.
        command_id: u64,
        /// Accepted, or the reason of the refusal.
        result: Result<(), String>,
    },
    /// The FSM state changed.
    StateChanged {
        /// Vehicle id.
        id: String,
        /// Previous state.
        from: VehicleState,
        /// New state.
        to: VehicleState,
    },
    /// The payload's answer to [`ToVehicle::PayloadCommand`](crate::ToVehicle::PayloadCommand).
    PayloadResult {
        /// Vehicle id.
        id: String,
        /// The request's id.
        request_id: u64,
        /// The payload's answer, or why there is none.
        result: Result<serde_json::Value, PayloadCommandError>,
    },
}

impl FromVehicle {
    /// The vehicle that sent it.
    pub fn vehicle_id(&self) -> &str {
        match self {
            FromVehicle::CommandAck { id, .. }
            | FromVehicle::StateChanged { id, .. }
            | FromVehicle::PayloadResult { id, .. } => id,
        }
    }
}
