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
