//! Vehicle and swarm commands: `POST /api/v1/vehicles/{id}/commands` and
//! `POST /api/v1/swarm/commands`, `{"command": NAME, ...}`.
//!
//! The body is a [`Command`], skein's one operator command type (`skein_model::command`:
//! the same type the FSM judges, the swarm protocol carries and the DDS link reads).
//! [`vehicle_command`] reads it with the field at fault named (and the checks of
//! [`Command::check`]); the contract's schemas of the two bodies ([`VehicleCommandRequest`],
//! [`SwarmCommandRequest`]) are [`Command`]'s own, each command one closed object
//! (unknown fields are refused), the swarm's without `clear_hazard`, which concerns one
//! vehicle.

use super::object;
use crate::error::ApiError;
pub use skein_model::command::Command;
use utoipa::openapi::RefOr;
use utoipa::openapi::schema::{AdditionalProperties, Object, Schema};
use utoipa::{PartialSchema, ToSchema};

/// [`Command`]'s schema with every command a closed object of its own fields and the tag
/// (a command with fields is `allOf` its fields' component and the tag in utoipa's
/// rendering; here they are merged, so that `additionalProperties: false` holds), without
/// `clear_hazard` unless `with_clear_hazard`.
fn command_schema(with_clear_hazard: bool) -> RefOr<Schema> {
    let mut components = Vec::new();
    Command::schemas(&mut components);
    let mut schema = Command::schema();
    if let RefOr::T(Schema::OneOf(one_of)) = &mut schema {
        for variant in &mut one_of.items {
            if let Some(mut o) = inlined(variant, &components) {
                o.additional_properties = Some(Box::new(AdditionalProperties::FreeForm(false)));
                *variant = RefOr::T(Schema::Object(o));
            }
        }
        one_of
            .items
            .retain(|variant| with_clear_hazard || command_of(variant) != Some("clear_hazard"));
    }
    schema
}

/// One command's schema as a single object: itself, or its `allOf` parts (a component
/// reference and objects) merged.
fn inlined(variant: &RefOr<Schema>, components: &[(String, RefOr<Schema>)]) -> Option<Object> {
    match variant {
        RefOr::T(Schema::Object(o)) => Some(o.clone()),
        RefOr::T(Schema::AllOf(all)) => {
            let mut merged = Object::new();
            merged.description = all.description.clone();
            for part in &all.items {
                let part = match part {
                    RefOr::Ref(r) => {
                        let name = r.ref_location.rsplit('/').next()?;
                        inlined(&components.iter().find(|(n, _)| n == name)?.1, components)?
                    }
                    other => inlined(other, components)?,
                };
                merged.properties.extend(part.properties);
                merged.required.extend(part.required);
            }
            Some(merged)
        }
        _ => None,
    }
}

/// The `command` of one command's (inlined) schema.
fn command_of(variant: &RefOr<Schema>) -> Option<&str> {
    let RefOr::T(Schema::Object(o)) = variant else {
        return None;
    };
    match o.properties.get("command")? {
        RefOr::T(Schema::Object(c)) => c.enum_values.as_ref()?.first()?.as_str(),
        _ => None,
    }
}

/// The body of `POST /api/v1/vehicles/{id}/commands` in the contract: a [`Command`]
/// (the schema only: [`vehicle_command`] reads the body).
pub struct VehicleCommandRequest;

impl PartialSchema for VehicleCommandRequest {
    fn schema() -> RefOr<Schema> {
        command_schema(true)
    }
}

impl ToSchema for VehicleCommandRequest {}

/// The body of `POST /api/v1/swarm/commands` in the contract: a [`Command`] but
/// `clear_hazard`, which concerns one vehicle (the schema only: [`swarm_command`] reads
/// the body).
pub struct SwarmCommandRequest;

impl PartialSchema for SwarmCommandRequest {
    fn schema() -> RefOr<Schema> {
        command_schema(false)
    }
}

impl ToSchema for SwarmCommandRequest {}

/// Reads and checks a vehicle command body (`clear_hazard` included).
///
/// # Errors
/// 400 naming `command` (missing, not a string, unknown) or the field at fault, `confirm`
/// for a `force_disarm` without `"confirm": true`, `altitude_m` for a takeoff altitude
/// not above home.
pub fn vehicle_command(body: &[u8]) -> Result<Command, ApiError> {
    Command::from_object(object(body)?).map_err(|e| ApiError::field(&e.field, e.error))
}

/// Reads and checks a swarm command body: every command but `clear_hazard`.
///
/// # Errors
/// See [`vehicle_command`]; 400 naming `command` for `clear_hazard`, which concerns one
/// vehicle.
pub fn swarm_command(body: &[u8]) -> Result<Command, ApiError> {
    match vehicle_command(body)? {
        Command::ClearHazard => Err(ApiError::field(
            "command",
            "clear_hazard concerns one vehicle: POST /api/v1/vehicles/{id}/commands",
        )),
        command => Ok(command),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skein_model::command::{CommandKind, ForceDisarm, GoTo, Takeoff};
    use skein_model::geo::Ned;
    use strum::IntoEnumIterator;

    fn field_of(r: Result<impl std::fmt::Debug, ApiError>) -> String {
        r.unwrap_err().field.unwrap_or_default()
    }

    #[test]
    fn commands_parse() {
        assert_eq!(
            vehicle_command(br#"{"command":"takeoff","altitude_m":10}"#).unwrap(),
            Command::Takeoff(Takeoff {
                altitude_m: Some(10.0)
            })
        );
        assert_eq!(
            vehicle_command(br#"{"command":"takeoff"}"#).unwrap(),
            Command::Takeoff(Takeoff { altitude_m: None })
        );
        assert_eq!(
            vehicle_command(br#"{"command":"goto","north_m":1,"east_m":2,"down_m":-10}"#).unwrap(),
            Command::GoTo(GoTo::from(Ned::new(1.0, 2.0, -10.0)))
        );
        assert_eq!(
            vehicle_command(br#"{"command":"force_disarm","confirm":true}"#).unwrap(),
            Command::ForceDisarm(ForceDisarm { confirm: true })
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
    fn the_contract_lists_every_command_as_a_closed_object() {
        for (schema, with_clear_hazard) in [
            (VehicleCommandRequest::schema(), true),
            (SwarmCommandRequest::schema(), false),
        ] {
            let RefOr::T(Schema::OneOf(one_of)) = schema else {
                panic!("not a oneOf");
            };
            let names: Vec<&str> = one_of.items.iter().filter_map(command_of).collect();
            let want: Vec<&str> = CommandKind::iter()
                .map(CommandKind::name)
                .filter(|n| with_clear_hazard || *n != "clear_hazard")
                .collect();
            assert_eq!(names, want);
            for item in &one_of.items {
                let text = serde_json::to_string(item).unwrap();
                let RefOr::T(Schema::Object(o)) = item else {
                    panic!("{text} is not one object");
                };
                assert!(
                    matches!(
                        o.additional_properties.as_deref(),
                        Some(AdditionalProperties::FreeForm(false))
                    ),
                    "{text}"
                );
            }
        }
        // The fields of a command with fields are in its object, with their bounds.
        let v = serde_json::to_value(VehicleCommandRequest::schema()).unwrap();
        let takeoff = v["oneOf"]
            .as_array()
            .unwrap()
            .iter()
            .find(|o| o["properties"]["command"]["enum"][0] == "takeoff")
            .unwrap();
        assert_eq!(
            takeoff["properties"]["altitude_m"]["exclusiveMinimum"], 0.0,
            "{takeoff}"
        );
        let goto = v["oneOf"]
            .as_array()
            .unwrap()
            .iter()
            .find(|o| o["properties"]["command"]["enum"][0] == "goto")
            .unwrap();
        let required: Vec<&str> = goto["required"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|r| r.as_str())
            .collect();
        for f in ["command", "north_m", "east_m", "down_m"] {
            assert!(required.contains(&f), "{goto}");
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
