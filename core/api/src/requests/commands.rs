//! Vehicle and swarm commands: `POST /api/v1/vehicles/{id}/commands` and
//! `POST /api/v1/swarm/commands`, `{"command": NAME, ...}`.
//!
//! [`CommandRequest`] is the contract (one variant per command, tagged by `command`);
//! [`parse`] reads it with the path of the field at fault, and
//! [`CommandRequest::into_command`] checks what serde cannot (a positive takeoff
//! altitude, read from the schema's own bound; `confirm: true`) and gives the swarm's
//! [`VehicleCommand`], or [`Command::ClearHazard`], which the coordinator handles itself.
//! The swarm's commands are the same but for `clear_hazard` ([`SwarmCommandRequest`]).

use super::schema_bounds::Bounds;
use super::{from_map, object};
use crate::error::ApiError;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use skein_model::geo::Ned;
use skein_swarm::VehicleCommand;
use utoipa::openapi::RefOr;
use utoipa::openapi::schema::{AdditionalProperties, ObjectBuilder, Schema, Type};
use utoipa::{PartialSchema, ToSchema};

/// A command body. Unknown fields are refused with their name ([`parse`]; the contract
/// states it in [`VehicleCommandRequest`] and [`SwarmCommandRequest`]).
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
#[serde(tag = "command", rename_all = "snake_case")]
pub enum CommandRequest {
    /// Arm on the ground.
    Arm,
    /// Disarm on the ground.
    Disarm,
    /// Stop the motors even in flight (MAV_CMD_COMPONENT_ARM_DISARM with 21196): the
    /// caller must say so.
    ForceDisarm {
        /// Must be `true`.
        #[schema(schema_with = must_be_true)]
        confirm: bool,
    },
    /// Arm if needed, enter offboard and climb.
    Takeoff {
        /// Altitude above home, metres, above 0; default: the configured one (10 m).
        #[schema(exclusive_minimum = 0.0)]
        altitude_m: Option<f64>,
    },
    /// Land where it is (MAV_CMD_NAV_LAND).
    Land,
    /// Return to launch (PX4 AUTO.RTL).
    Rtl,
    /// Hold the current position under offboard control.
    Hold,
    /// Fly to a swarm-frame point under offboard control.
    #[serde(rename = "goto")]
    GoTo {
        /// Swarm-frame north, metres.
        north_m: f64,
        /// Swarm-frame east, metres.
        east_m: f64,
        /// Swarm-frame down, metres (negative is up).
        down_m: f64,
    },
    /// Track the formation slot the coordinator gives.
    JoinFormation,
    /// Stop tracking the slot and hold.
    LeaveFormation,
    /// Vehicle commands only: the operator says a lost vehicle is no longer a hazard the
    /// formation must plan around (answered 200 `{"cleared": id}`).
    ClearHazard,
}

/// The schema of `force_disarm`'s `confirm`: `true` and nothing else.
fn must_be_true() -> ObjectBuilder {
    ObjectBuilder::new()
        .schema_type(Type::Boolean)
        .enum_values(Some([true]))
        .description(Some(
            "Must be `true`: the caller knows the motors stop in flight.",
        ))
}

/// The contract's schema of [`CommandRequest`] bodies, as [`parse`] reads them: each
/// variant an object of its own fields only (unknown fields are refused by name), without
/// `clear_hazard` unless `with_clear_hazard`.
fn command_schema(with_clear_hazard: bool) -> RefOr<Schema> {
    let mut schema = CommandRequest::schema();
    if let RefOr::T(Schema::OneOf(one_of)) = &mut schema {
        one_of
            .items
            .retain(|variant| with_clear_hazard || command_of(variant) != Some("clear_hazard"));
        for variant in &mut one_of.items {
            if let RefOr::T(Schema::Object(o)) = variant {
                o.additional_properties = Some(Box::new(AdditionalProperties::FreeForm(false)));
            }
        }
    }
    schema
}

/// The `command` of one variant's schema.
fn command_of(variant: &RefOr<Schema>) -> Option<&str> {
    let RefOr::T(Schema::Object(o)) = variant else {
        return None;
    };
    match o.properties.get("command")? {
        RefOr::T(Schema::Object(c)) => c.enum_values.as_ref()?.first()?.as_str(),
        _ => None,
    }
}

/// The body of `POST /api/v1/vehicles/{id}/commands` in the contract: a
/// [`CommandRequest`] (the schema only: [`vehicle_command`] parses the body).
pub struct VehicleCommandRequest;

impl PartialSchema for VehicleCommandRequest {
    fn schema() -> RefOr<Schema> {
        command_schema(true)
    }
}

impl ToSchema for VehicleCommandRequest {}

/// The body of `POST /api/v1/swarm/commands` in the contract: a [`CommandRequest`] but
/// `clear_hazard`, which concerns one vehicle (the schema only: [`swarm_command`] parses
/// the body).
pub struct SwarmCommandRequest;

impl PartialSchema for SwarmCommandRequest {
    fn schema() -> RefOr<Schema> {
        command_schema(false)
    }
}

impl ToSchema for SwarmCommandRequest {}

/// What a command body asks for.
#[derive(Debug, Clone, PartialEq)]
pub enum Command {
    /// A command for the vehicle's state machine.
    Vehicle(VehicleCommand),
    /// `clear_hazard`: a formation-level command the coordinator handles.
    ClearHazard,
}

/// Every command name the API accepts.
pub const COMMANDS: [&str; 11] = [
    "arm",
    "disarm",
    "force_disarm",
    "takeoff",
    "land",
    "rtl",
    "hold",
    "goto",
    "join_formation",
    "leave_formation",
    "clear_hazard",
];

/// The fields of a command without parameters: none.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct NoFields {}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ForceDisarmFields {
    confirm: Option<bool>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TakeoffFields {
    altitude_m: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GoToFields {
    north_m: f64,
    east_m: f64,
    down_m: f64,
}

/// Parses a command body. The tag is read first, then the command's own fields (an
/// internally tagged enum would lose the path of a field inside it).
///
/// # Errors
/// 400 naming `command` (missing, not a string, unknown) or the field path at fault.
pub fn parse(body: &[u8]) -> Result<CommandRequest, ApiError> {
    let mut m = object(body)?;
    let name = match m.remove("command") {
        None | Some(Value::Null) => {
            return Err(ApiError::field(
                "command",
                format!("missing field `command` (one of: {})", COMMANDS.join(", ")),
            ));
        }
        Some(Value::String(s)) => s,
        Some(other) => {
            return Err(ApiError::field(
                "command",
                format!("command must be a string, got {other}"),
            ));
        }
    };
    let none = |m| from_map::<NoFields>(m).map(|_| ());
    Ok(match name.as_str() {
        "arm" => none(m).map(|()| CommandRequest::Arm)?,
        "disarm" => none(m).map(|()| CommandRequest::Disarm)?,
        "force_disarm" => {
            let f: ForceDisarmFields = from_map(m)?;
            CommandRequest::ForceDisarm {
                confirm: f.confirm.unwrap_or(false),
            }
        }
        "takeoff" => {
            let f: TakeoffFields = from_map(m)?;
            CommandRequest::Takeoff {
                altitude_m: f.altitude_m,
            }
        }
        "land" => none(m).map(|()| CommandRequest::Land)?,
        "rtl" => none(m).map(|()| CommandRequest::Rtl)?,
        "hold" => none(m).map(|()| CommandRequest::Hold)?,
        "goto" => {
            let f: GoToFields = from_map(m)?;
            CommandRequest::GoTo {
                north_m: f.north_m,
                east_m: f.east_m,
                down_m: f.down_m,
            }
        }
        "join_formation" => none(m).map(|()| CommandRequest::JoinFormation)?,
        "leave_formation" => none(m).map(|()| CommandRequest::LeaveFormation)?,
        "clear_hazard" => none(m).map(|()| CommandRequest::ClearHazard)?,
        other => {
            return Err(ApiError::field(
                "command",
                format!(
                    "unknown command `{other}` (one of: {})",
                    COMMANDS.join(", ")
                ),
            ));
        }
    })
}

impl CommandRequest {
    /// The command it asks for, after the checks serde cannot make.
    ///
    /// # Errors
    /// 400 naming `confirm` for a `force_disarm` without `"confirm": true`, `altitude_m`
    /// for a takeoff altitude not above 0.
    pub fn into_command(self) -> Result<Command, ApiError> {
        Ok(Command::Vehicle(match self {
            CommandRequest::Arm => VehicleCommand::Arm,
            CommandRequest::Disarm => VehicleCommand::Disarm { force: false },
            CommandRequest::ForceDisarm { confirm } => {
                if !confirm {
                    return Err(ApiError::field(
                        "confirm",
                        "force_disarm stops the motors even in flight: send \"confirm\": true",
                    ));
                }
                VehicleCommand::Disarm { force: true }
            }
            CommandRequest::Takeoff { altitude_m } => {
                if let Some(a) = altitude_m {
                    Bounds::of_variant::<CommandRequest>("command", "takeoff", "altitude_m")
                        .check("altitude_m", a, "m")?;
                }
                VehicleCommand::Takeoff { altitude_m }
            }
            CommandRequest::Land => VehicleCommand::Land,
            CommandRequest::Rtl => VehicleCommand::Rtl,
            CommandRequest::Hold => VehicleCommand::Hold,
            CommandRequest::GoTo {
                north_m,
                east_m,
                down_m,
            } => VehicleCommand::GoTo {
                target: Ned::new(north_m, east_m, down_m),
            },
            CommandRequest::JoinFormation => VehicleCommand::JoinFormation,
            CommandRequest::LeaveFormation => VehicleCommand::LeaveFormation,
            CommandRequest::ClearHazard => return Ok(Command::ClearHazard),
        }))
    }
}

/// Parses and checks a vehicle command body (`clear_hazard` included).
///
/// # Errors
/// See [`parse`] and [`CommandRequest::into_command`].
pub fn vehicle_command(body: &[u8]) -> Result<Command, ApiError> {
    parse(body)?.into_command()
}

/// Parses and checks a swarm command body: every command but `clear_hazard`.
///
/// # Errors
/// See [`parse`] and [`CommandRequest::into_command`]; 400 naming `command` for
/// `clear_hazard`, which concerns one vehicle.
pub fn swarm_command(body: &[u8]) -> Result<VehicleCommand, ApiError> {
    match vehicle_command(body)? {
        Command::Vehicle(c) => Ok(c),
        Command::ClearHazard => Err(ApiError::field(
            "command",
            "clear_hazard concerns one vehicle: POST /api/v1/vehicles/{id}/commands",
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn field_of(r: Result<impl std::fmt::Debug, ApiError>) -> String {
        r.unwrap_err().field.unwrap_or_default()
    }

    fn vehicle(body: &str) -> VehicleCommand {
        match vehicle_command(body.as_bytes()).unwrap() {
            Command::Vehicle(c) => c,
            Command::ClearHazard => panic!("clear_hazard"),
        }
    }

    #[test]
    fn commands_parse() {
        assert_eq!(
            vehicle(r#"{"command":"takeoff","altitude_m":10}"#),
            VehicleCommand::Takeoff {
                altitude_m: Some(10.0)
            }
        );
        assert_eq!(
            vehicle(r#"{"command":"takeoff"}"#),
            VehicleCommand::Takeoff { altitude_m: None }
        );
        assert_eq!(
            vehicle(r#"{"command":"goto","north_m":1,"east_m":2,"down_m":-10}"#),
            VehicleCommand::GoTo {
                target: Ned::new(1.0, 2.0, -10.0)
            }
        );
        assert_eq!(
            vehicle(r#"{"command":"force_disarm","confirm":true}"#),
            VehicleCommand::Disarm { force: true }
        );
        assert_eq!(
            vehicle_command(br#"{"command":"clear_hazard"}"#).unwrap(),
            Command::ClearHazard
        );
        assert_eq!(
            field_of(swarm_command(br#"{"command":"clear_hazard"}"#)),
            "command"
        );
    }

    #[test]
    fn every_variant_of_the_contract_parses_back() {
        // The contract type serialises as the body it documents: each must parse to
        // itself (the parser's names and fields match the enum's).
        let all = [
            CommandRequest::Arm,
            CommandRequest::Disarm,
            CommandRequest::ForceDisarm { confirm: true },
            CommandRequest::Takeoff {
                altitude_m: Some(12.0),
            },
            CommandRequest::Land,
            CommandRequest::Rtl,
            CommandRequest::Hold,
            CommandRequest::GoTo {
                north_m: 1.0,
                east_m: -2.0,
                down_m: -10.0,
            },
            CommandRequest::JoinFormation,
            CommandRequest::LeaveFormation,
            CommandRequest::ClearHazard,
        ];
        assert_eq!(all.len(), COMMANDS.len());
        for c in all {
            let body = serde_json::to_vec(&c).unwrap();
            assert_eq!(parse(&body).unwrap(), c);
            let name = serde_json::to_value(&c).unwrap()["command"].clone();
            assert!(COMMANDS.contains(&name.as_str().unwrap()), "{name}");
        }
    }

    #[test]
    fn command_errors_name_the_field() {
        assert_eq!(field_of(vehicle_command(br#"{}"#)), "command");
        assert_eq!(
            field_of(vehicle_command(br#"{"command":"fly"}"#)),
            "command"
        );
        assert_eq!(field_of(vehicle_command(br#"{"command":7}"#)), "command");
        assert_eq!(
            field_of(vehicle_command(
                br#"{"command":"takeoff","altitude_m":"high"}"#
            )),
            "altitude_m"
        );
        assert_eq!(
            field_of(vehicle_command(br#"{"command":"takeoff","altitude_m":-3}"#)),
            "altitude_m"
        );
        assert_eq!(
            field_of(vehicle_command(br#"{"command":"goto","north_m":1}"#)),
            "east_m"
        );
        assert_eq!(
            field_of(vehicle_command(br#"{"command":"arm","force":true}"#)),
            "force"
        );
        assert_eq!(
            field_of(vehicle_command(br#"{"command":"clear_hazard","x":1}"#)),
            "x"
        );
        assert_eq!(
            field_of(vehicle_command(br#"{"command":"force_disarm"}"#)),
            "confirm"
        );
        assert_eq!(
            field_of(vehicle_command(
                br#"{"command":"force_disarm","confirm":"yes"}"#
            )),
            "confirm"
        );
        assert!(
            vehicle_command(b"not json")
                .unwrap_err()
                .error
                .contains("invalid JSON")
        );
    }
}
