//! The operator's commands, one type for every layer: the API's command body, the swarm
//! protocol between coordinator and vehicles, the DDS `skein_msgs/Command`, and, as its
//! [`CommandKind`], the vehicle FSM's input ([`crate::fsm`]).
//!
//! On every wire a command is a JSON object tagged by `command`, with its own fields
//! beside the tag: `{"command": "takeoff", "altitude_m": 10.0}`, `{"command": "goto",
//! "north_m": 5.0, "east_m": 0.0, "down_m": -10.0}`. [`Command::from_object`] reads one
//! with errors naming the field at fault (the tag first, then the command's own fields,
//! unknown fields refused by name) and checks what the types cannot say (`confirm` is
//! `true`, numbers are finite). Adding a command is a variant here (with its fields'
//! struct if it has any), its arm in [`Command::from_object`], and its row in the FSM's
//! transition table; the API's contract, the protocol and the DDS conversion follow.

use crate::geo::Ned;
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};
use std::str::FromStr;
use strum::IntoEnumIterator;
use utoipa::ToSchema;

/// An operator command (see the module docs). Serialised with a `command` tag in snake
/// case, the fields of a command beside it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema, strum::EnumDiscriminants)]
#[serde(tag = "command", rename_all = "snake_case")]
#[strum_discriminants(
    name(CommandKind),
    vis(pub),
    doc = "What a [`Command`] asks for, without its parameters: the FSM's input and the command's name (`takeoff`, `force_disarm`, `goto` …).",
    derive(
        Hash,
        PartialOrd,
        Ord,
        Serialize,
        Deserialize,
        strum::EnumIter,
        strum::EnumString,
        strum::IntoStaticStr
    ),
    serde(rename_all = "snake_case"),
    strum(serialize_all = "snake_case")
)]
pub enum Command {
    /// Arm on the ground (`MAV_CMD_COMPONENT_ARM_DISARM`, param1 = 1).
    Arm,
    /// Disarm on the ground.
    Disarm,
    /// Stop the motors even in flight (`MAV_CMD_COMPONENT_ARM_DISARM` with PX4's 21196):
    /// the caller must say so.
    ForceDisarm(ForceDisarm),
    /// Arm if needed, enter offboard and climb.
    Takeoff(Takeoff),
    /// Land where it is (`MAV_CMD_NAV_LAND`, PX4 AUTO.LAND).
    Land,
    /// Return to launch (PX4 AUTO.RTL).
    Rtl,
    /// Hold the current position under offboard control.
    Hold,
    /// Fly to a swarm-frame point under offboard control.
    #[serde(rename = "goto")]
    #[strum_discriminants(serde(rename = "goto"))]
    #[strum_discriminants(strum(serialize = "goto"))]
    GoTo(GoTo),
    /// Track the formation slot the coordinator gives.
    JoinFormation,
    /// Stop tracking the slot and hold.
    LeaveFormation,
    /// The operator says a lost vehicle is no longer a hazard the formation must plan
    /// around: the coordinator's, for one vehicle (the vehicle's FSM refuses it).
    ClearHazard,
}

/// The fields of `force_disarm`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ForceDisarm {
    /// Must be `true`: the caller knows the motors stop in flight.
    #[serde(default)]
    #[schema(schema_with = must_be_true)]
    pub confirm: bool,
}

/// The schema of `force_disarm`'s `confirm`: `true` and nothing else.
fn must_be_true() -> utoipa::openapi::schema::ObjectBuilder {
    utoipa::openapi::schema::ObjectBuilder::new()
        .schema_type(utoipa::openapi::schema::Type::Boolean)
        .enum_values(Some([true]))
        .description(Some(
            "Must be `true`: the caller knows the motors stop in flight.",
        ))
}

/// A takeoff altitude must be above this, metres above home (its schema says the same:
/// a test holds the two equal).
pub const TAKEOFF_ALTITUDE_ABOVE_M: f64 = 0.0;

/// The fields of `takeoff`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Takeoff {
    /// Altitude above home, metres, above [`TAKEOFF_ALTITUDE_ABOVE_M`] (0); `None`: the
    /// configured one (10 m by default). The vehicle refuses one above the geofence's
    /// ceiling.
    #[serde(default)]
    #[schema(exclusive_minimum = 0.0)]
    pub altitude_m: Option<f64>,
}

/// The fields of `goto`: a point in the swarm frame, NED metres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct GoTo {
    /// Swarm-frame north, metres.
    pub north_m: f64,
    /// Swarm-frame east, metres.
    pub east_m: f64,
    /// Swarm-frame down, metres (negative is up).
    pub down_m: f64,
}

impl GoTo {
    /// The point, swarm-frame NED.
    pub fn target(&self) -> Ned {
        Ned::new(self.north_m, self.east_m, self.down_m)
    }
}

impl From<Ned> for GoTo {
    fn from(p: Ned) -> Self {
        GoTo {
            north_m: p.north_m,
            east_m: p.east_m,
            down_m: p.down_m,
        }
    }
}

/// A command that could not be read: the field at fault (`command` for the tag, else the
/// field's path) and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CommandError {
    /// The field at fault.
    pub field: String,
    /// What is wrong, for the operator.
    pub error: String,
}

impl std::fmt::Display for CommandError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.field, self.error)
    }
}

impl std::error::Error for CommandError {}

fn error(field: &str, error: impl Into<String>) -> CommandError {
    CommandError {
        field: field.to_string(),
        error: error.into(),
    }
}

/// A field's name as errors give it: an empty key is named as JSON writes it (`""`), so
/// that no error names no field.
fn field_name(key: &str) -> String {
    if key.is_empty() {
        "\"\"".to_string()
    } else {
        key.to_string()
    }
}

/// A command's own fields, read with the path of the one at fault (serde names a missing
/// field in its message, at the path of the object that lacks it).
fn fields<T: serde::de::DeserializeOwned>(m: Map<String, Value>) -> Result<T, CommandError> {
    serde_path_to_error::deserialize(Value::Object(m)).map_err(|e| {
        let path = e.path().to_string();
        let inner = e.into_inner().to_string();
        let missing = inner
            .strip_prefix("missing field `")
            .and_then(|rest| rest.split('`').next());
        let field = match (path.as_str(), missing) {
            (".", Some(name)) => name.to_string(),
            (".", None) => "command".to_string(),
            (p, _) => field_name(p),
        };
        error(&field, format!("{field}: {inner}"))
    })
}

/// A command without fields: none may be given.
fn no_fields(m: &Map<String, Value>, name: &str) -> Result<(), CommandError> {
    match m.keys().next() {
        None => Ok(()),
        Some(k) => {
            let field = field_name(k);
            Err(error(
                &field,
                format!("{field}: unknown field: {name} takes no fields"),
            ))
        }
    }
}

fn finite(field: &str, x: f64) -> Result<(), CommandError> {
    if x.is_finite() {
        Ok(())
    } else {
        Err(error(field, format!("{x} is not a finite number")))
    }
}

impl CommandKind {
    /// The command's name on every wire (`"takeoff"`, `"force_disarm"`, `"goto"` …).
    pub fn name(self) -> &'static str {
        self.into()
    }

    /// Every command's name, comma-separated (for messages).
    pub fn names() -> String {
        CommandKind::iter()
            .map(CommandKind::name)
            .collect::<Vec<_>>()
            .join(", ")
    }
}

impl std::fmt::Display for CommandKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl Command {
    /// What it asks for, without parameters.
    pub fn kind(&self) -> CommandKind {
        self.into()
    }

    /// Its name (`"takeoff"`).
    pub fn name(&self) -> &'static str {
        self.kind().name()
    }

    /// Reads a command from its JSON object: the `command` tag first, then the command's
    /// own fields (unknown ones refused by name), then [`Command::check`].
    ///
    /// # Errors
    /// Naming `command` (missing, not a string, unknown), or the field at fault.
    pub fn from_object(mut m: Map<String, Value>) -> Result<Command, CommandError> {
        let name = match m.remove("command") {
            None | Some(Value::Null) => {
                return Err(error(
                    "command",
                    format!("missing field `command` (one of: {})", CommandKind::names()),
                ));
            }
            Some(Value::String(s)) => s,
            Some(other) => {
                return Err(error(
                    "command",
                    format!("command must be a string, got {other}"),
                ));
            }
        };
        let kind = CommandKind::from_str(&name).map_err(|_| {
            error(
                "command",
                format!(
                    "unknown command `{name}` (one of: {})",
                    CommandKind::names()
                ),
            )
        })?;
        let unit = |c: Command| no_fields(&m, &name).map(|()| c);
        let command = match kind {
            CommandKind::Arm => unit(Command::Arm)?,
            CommandKind::Disarm => unit(Command::Disarm)?,
            CommandKind::ForceDisarm => Command::ForceDisarm(fields(m)?),
            CommandKind::Takeoff => Command::Takeoff(fields(m)?),
            CommandKind::Land => unit(Command::Land)?,
            CommandKind::Rtl => unit(Command::Rtl)?,
            CommandKind::Hold => unit(Command::Hold)?,
            CommandKind::GoTo => Command::GoTo(fields(m)?),
            CommandKind::JoinFormation => unit(Command::JoinFormation)?,
            CommandKind::LeaveFormation => unit(Command::LeaveFormation)?,
            CommandKind::ClearHazard => unit(Command::ClearHazard)?,
        };
        command.check()?;
        Ok(command)
    }

    /// What the types cannot say: `force_disarm` needs `"confirm": true`, a takeoff
    /// altitude is above home, a go-to point is finite. (Bounds that depend on the swarm,
    /// such as the geofence's ceiling, are the vehicle's to check.)
    ///
    /// # Errors
    /// Naming the field at fault.
    pub fn check(&self) -> Result<(), CommandError> {
        match self {
            Command::ForceDisarm(ForceDisarm { confirm: false }) => Err(error(
                "confirm",
                "force_disarm stops the motors even in flight: send \"confirm\": true",
            )),
            Command::Takeoff(Takeoff {
                altitude_m: Some(a),
            }) => {
                finite("altitude_m", *a)?;
                if *a > TAKEOFF_ALTITUDE_ABOVE_M {
                    Ok(())
                } else {
                    Err(error(
                        "altitude_m",
                        format!("altitude_m: {a} m is not above home"),
                    ))
                }
            }
            Command::GoTo(g) => {
                finite("north_m", g.north_m)?;
                finite("east_m", g.east_m)?;
                finite("down_m", g.down_m)
            }
            _ => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn read(v: Value) -> Result<Command, CommandError> {
        match v {
            Value::Object(m) => Command::from_object(m),
            _ => panic!("not an object"),
        }
    }

    fn field(v: Value) -> String {
        read(v).unwrap_err().field
    }

    #[test]
    fn every_command_reads_back_what_it_writes() {
        let all = [
            Command::Arm,
            Command::Disarm,
            Command::ForceDisarm(ForceDisarm { confirm: true }),
            Command::Takeoff(Takeoff {
                altitude_m: Some(12.0),
            }),
            Command::Takeoff(Takeoff { altitude_m: None }),
            Command::Land,
            Command::Rtl,
            Command::Hold,
            Command::GoTo(GoTo::from(Ned::new(1.0, -2.0, -10.0))),
            Command::JoinFormation,
            Command::LeaveFormation,
            Command::ClearHazard,
        ];
        let kinds: std::collections::BTreeSet<CommandKind> =
            all.iter().map(Command::kind).collect();
        assert_eq!(kinds.len(), CommandKind::iter().count(), "every kind once");
        for c in all {
            let v = serde_json::to_value(&c).unwrap();
            assert_eq!(v["command"], c.name(), "{v}");
            assert_eq!(read(v.clone()).unwrap(), c, "{v}");
            // serde's own reading agrees (the protocol's carriers use it).
            assert_eq!(serde_json::from_value::<Command>(v).unwrap(), c);
        }
    }

    #[test]
    fn the_schema_declares_the_takeoff_floor_the_check_applies() {
        use utoipa::PartialSchema;
        let s = serde_json::to_value(Takeoff::schema()).unwrap();
        assert_eq!(
            s["properties"]["altitude_m"]["exclusiveMinimum"].as_f64(),
            Some(TAKEOFF_ALTITUDE_ABOVE_M),
            "{s}"
        );
    }

    #[test]
    fn names_are_the_wire_names() {
        assert_eq!(CommandKind::GoTo.name(), "goto");
        assert_eq!(CommandKind::ForceDisarm.name(), "force_disarm");
        assert_eq!(
            CommandKind::from_str("join_formation"),
            Ok(CommandKind::JoinFormation)
        );
        assert_eq!(
            serde_json::to_value(CommandKind::ClearHazard).unwrap(),
            json!("clear_hazard")
        );
    }

    #[test]
    fn errors_name_the_field_at_fault() {
        assert_eq!(field(json!({})), "command");
        assert_eq!(field(json!({"command": "fly"})), "command");
        assert_eq!(field(json!({"command": 7})), "command");
        assert_eq!(
            field(json!({"command": "takeoff", "altitude_m": "high"})),
            "altitude_m"
        );
        assert_eq!(field(json!({"command": "goto", "north_m": 1})), "east_m");
        assert_eq!(field(json!({"command": "arm", "force": true})), "force");
        assert_eq!(field(json!({"command": "takeoff", "speed": 2})), "speed");
        assert_eq!(
            field(json!({"command": "takeoff", "altitude_m": 0})),
            "altitude_m"
        );
        assert_eq!(field(json!({"command": "force_disarm"})), "confirm");
        assert_eq!(
            field(json!({"command": "force_disarm", "confirm": "yes"})),
            "confirm"
        );
        assert_eq!(field(json!({"command": "hold", "": 1})), "\"\"");
        assert_eq!(field(json!({"command": "goto", "": 1})), "\"\"");
        let unknown = read(json!({"command": "fly"})).unwrap_err().error;
        assert!(
            unknown.contains("join_formation") && unknown.contains("goto"),
            "{unknown}"
        );
    }
}
