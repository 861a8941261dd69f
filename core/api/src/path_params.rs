//! The path parameters of the API's routes, as types: a handler extracts its parameters
//! with one of these (`Path<VehicleId>`) and names the same type in its
//! `#[utoipa::path(params(...))]`, so the contract describes what the handler parses.
//! The examples name what a `skein up --sim 3` has (uav-2 is an observation vehicle with
//! a gimbal and a camera).

use serde::Deserialize;
use utoipa::IntoParams;

/// `{id}` of `/api/v1/vehicles/{id}…`.
#[derive(Debug, Clone, Deserialize, IntoParams)]
#[into_params(parameter_in = Path)]
pub struct VehicleId {
    /// Vehicle id (`uav-1`).
    #[param(min_length = 1, example = "uav-2")]
    pub id: String,
}

/// `{id}` and `{name}` of `/api/v1/vehicles/{id}/params/{name}`.
#[derive(Debug, Clone, Deserialize, IntoParams)]
#[into_params(parameter_in = Path)]
pub struct VehicleParam {
    /// Vehicle id (`uav-1`).
    #[param(min_length = 1, example = "uav-2")]
    pub id: String,
    /// PX4 parameter name (`MPC_XY_VEL_MAX`): 1 to 16 ASCII characters (PARAM_VALUE's
    /// `param_id`).
    #[param(
        min_length = 1,
        max_length = 16,
        pattern = "^[\\x00-\\x7F]*$",
        example = "MPC_XY_VEL_MAX"
    )]
    pub name: String,
}

/// `{id}` and `{log_id}` of `/api/v1/vehicles/{id}/logs/{log_id}…`.
#[derive(Debug, Clone, Deserialize, IntoParams)]
#[into_params(parameter_in = Path)]
pub struct VehicleLog {
    /// Vehicle id (`uav-1`).
    #[param(min_length = 1, example = "uav-1")]
    pub id: String,
    /// The vehicle's log id (`LOG_ENTRY.id`, 0 to 65535; PX4 numbers from 0): read with
    /// [`VehicleLog::log_id`], which refuses anything else naming `log_id`.
    #[param(
        pattern = "^(0|[1-9][0-9]{0,3}|[1-5][0-9]{4}|6[0-4][0-9]{3}|65[0-4][0-9]{2}|655[0-2][0-9]|6553[0-5])$",
        example = "0"
    )]
    pub log_id: String,
}

impl VehicleLog {
    /// The log id as a number.
    ///
    /// # Errors
    /// 400 naming `log_id` when it is no number from 0 to 65535.
    pub fn log_id(&self) -> Result<u16, crate::error::ApiError> {
        self.log_id.parse().map_err(|_| {
            crate::error::ApiError::field(
                "log_id",
                format!("`{}` is no log id (0 to 65535)", self.log_id),
            )
        })
    }
}

/// Longest PX4 parameter name, bytes (MAVLink PARAM_VALUE `param_id`, `char[16]`): the
/// `max_length` of [`VehicleParam::name`] in the contract.
pub const PX4_PARAM_NAME_MAX: usize = 16;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_contract_states_the_px4_parameter_name_length() {
        let params = VehicleParam::into_params(|| None);
        let name = params.iter().find(|p| p.name == "name").unwrap();
        let schema = serde_json::to_value(&name.schema).unwrap();
        assert_eq!(schema["maxLength"], PX4_PARAM_NAME_MAX);
    }
}

/// `{id}` and `{slot}` of `/api/v1/vehicles/{id}/payloads/{slot}…`.
#[derive(Debug, Clone, Deserialize, IntoParams)]
#[into_params(parameter_in = Path)]
pub struct PayloadSlot {
    /// Vehicle id (`uav-1`).
    #[param(min_length = 1, example = "uav-2")]
    pub id: String,
    /// Payload slot (`camera`).
    #[param(min_length = 1, example = "gimbal")]
    pub slot: String,
}

/// `{id}` of `/api/v1/swarms/{id}…`.
#[derive(Debug, Clone, Deserialize, IntoParams)]
#[into_params(parameter_in = Path)]
pub struct SwarmId {
    /// Hostile swarm id (`swarm-2`), as `GET /api/v1/swarms` lists them.
    #[param(min_length = 1, example = "swarm-1")]
    pub id: String,
}

/// `{id}` of `/api/v1/tracks/{id}…`.
#[derive(Debug, Clone, Deserialize, IntoParams)]
#[into_params(parameter_in = Path)]
pub struct TrackId {
    /// Track id (`track-3`), as `GET /api/v1/tracks` lists them.
    #[param(min_length = 1, example = "track-1")]
    pub id: String,
}

/// `{id}` of `/api/v1/missions/{id}`.
#[derive(Debug, Clone, Deserialize, IntoParams)]
#[into_params(parameter_in = Path)]
pub struct MissionId {
    /// Mission id (`m-1`).
    #[param(min_length = 1, example = "m-1")]
    pub id: String,
}

/// `{id}` and `{action}` of `/api/v1/missions/{id}/{action}`.
#[derive(Debug, Clone, Deserialize, IntoParams)]
#[into_params(parameter_in = Path)]
pub struct MissionAction {
    /// Mission id (`m-1`).
    #[param(min_length = 1, example = "m-1")]
    pub id: String,
    /// `start`, `pause`, `resume`, `abort` or `skip`.
    #[param(pattern = "^(start|pause|resume|abort|skip)$", example = "start")]
    pub action: String,
}
