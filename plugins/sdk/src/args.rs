//! Reading a plugin's configuration and operator commands with serde, with errors that
//! name the field.
//!
//! A plugin declares its configuration as a struct (`deny_unknown_fields`, so a typo is
//! refused) and its commands as an enum with one variant per `command` name (plain,
//! externally tagged: serde's default; `rename_all = "snake_case"`; unit variants for
//! commands without fields, struct variants for the others). [`config`] and [`command`]
//! read them; every error starts with the path of the field at fault, `field: message`
//! (`pitch_deg: invalid type: string "down", expected f64`), which skein's API turns into
//! the `field` of its 400 answer. Checks serde cannot express (ranges, one field or the
//! other) follow in the plugin, with [`in_range`] and [`field_error`] for the same form.
//!
//! The SDK re-exports serde, so a plugin derives with `#[serde(crate =
//! "skein_plugin_sdk::serde")]` and links nothing else:
//!
//! ```
//! use skein_plugin_sdk::serde::Deserialize;
//! use skein_plugin_sdk::{args, serde_json::json};
//!
//! #[derive(Deserialize)]
//! #[serde(crate = "skein_plugin_sdk::serde", rename_all = "snake_case", deny_unknown_fields)]
//! enum Command {
//!     SetAngles { pitch_deg: Option<f64>, yaw_deg: Option<f64> },
//!     Neutral,
//! }
//!
//! let c: Command = args::command(json!({"command": "set_angles", "pitch_deg": -30})).unwrap();
//! assert!(matches!(c, Command::SetAngles { pitch_deg: Some(p), yaw_deg: None } if p == -30.0));
//! assert!(matches!(args::command(json!({"command": "neutral"})).unwrap(), Command::Neutral));
//!
//! let e = args::command::<Command>(json!({"command": "set_angles", "pitch_deg": "down"}));
//! assert_eq!(e.err().unwrap(), "pitch_deg: invalid type: string \"down\", expected f64");
//! let e = args::command::<Command>(json!({"command": "fly"})).err().unwrap();
//! assert_eq!(e, "command: unknown command `fly`, expected `set_angles` or `neutral`");
//! ```

use serde::Deserialize;
use serde::de::DeserializeOwned;
use serde_json::{Map, Value};
use std::fmt::Display;

/// The `mode` setting of a payload that drives a real device or simulates one (the gimbal,
/// the radio): `"auto"` (the default: simulated on a simulated vehicle, see
/// [`crate::Context::simulated`]), `"simulated"`, or `"mavlink"` (the real device, over the
/// vehicle's MAVLink link).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DeviceMode {
    /// Simulated when the vehicle is.
    #[default]
    Auto,
    /// Always simulated.
    Simulated,
    /// Always the real device.
    Mavlink,
}

impl DeviceMode {
    /// True when the payload simulates its device, on a vehicle that is simulated
    /// (`vehicle_simulated`) or not.
    pub fn simulated(self, vehicle_simulated: bool) -> bool {
        match self {
            DeviceMode::Auto => vehicle_simulated,
            DeviceMode::Simulated => true,
            DeviceMode::Mavlink => false,
        }
    }
}

/// Reads a configuration (`PayloadSpec.config`; `null`, when the slot has none, reads as
/// `{}`, so a struct whose fields all have defaults accepts it).
///
/// # Errors
/// `field: message` for anything `T` refuses: an unknown field, a missing one, a wrong
/// type or value.
pub fn config<T: DeserializeOwned>(config: Value) -> Result<T, String> {
    let config = match config {
        Value::Null => Value::Object(Map::new()),
        other => other,
    };
    serde_path_to_error::deserialize(config).map_err(|e| describe(&e, None))
}

/// Reads an operator command `{"command": NAME, ...fields}` into `C`, an enum with one
/// variant per command (see the module docs): `NAME` picks the variant, the other fields
/// fill it.
///
/// # Errors
/// `command: message` when `command` is missing, not a string or not one of `C`'s
/// variants (`command: unknown command `fly`, expected ...`); `field: message` for a
/// field the command does not take, lacks or cannot read.
pub fn command<C: DeserializeOwned>(command: Value) -> Result<C, String> {
    let Value::Object(mut fields) = command else {
        return Err(format!(
            "a command is a JSON object, got {}",
            short(&command)
        ));
    };
    let name = match fields.remove("command") {
        Some(Value::String(name)) => name,
        None | Some(Value::Null) => return Err(field_error("command", "missing field `command`")),
        Some(other) => {
            return Err(field_error(
                "command",
                format!("expected a string, got {}", short(&other)),
            ));
        }
    };
    // serde's external form of a command without fields is its bare name.
    let unit = || serde_json::from_value::<C>(Value::String(name.clone()));
    if let Some(c) = fields.is_empty().then(unit).and_then(Result::ok) {
        return Ok(c);
    }
    let first_field = fields.keys().next().cloned();
    let tagged = Value::Object(Map::from_iter([(name.clone(), Value::Object(fields))]));
    match serde_path_to_error::deserialize(tagged) {
        Ok(c) => Ok(c),
        Err(e) => match first_field {
            Some(field) if unit().is_ok() => Err(field_error(
                &field,
                format!("unknown field `{field}`: command `{name}` takes no fields"),
            )),
            _ => Err(describe(&e, Some(&name))),
        },
    }
}

/// `value` when it is finite and within `[min, max]`.
///
/// # Errors
/// `field: value is outside [min, max]`.
pub fn in_range(field: &str, value: f64, min: f64, max: f64) -> Result<f64, String> {
    if value.is_finite() && (min..=max).contains(&value) {
        Ok(value)
    } else {
        Err(field_error(
            field,
            format!("{value} is outside [{min}, {max}]"),
        ))
    }
}

/// An error about one field in the form skein's API reads the field from:
/// `field: message`.
pub fn field_error(field: &str, message: impl Display) -> String {
    format!("{field}: {message}")
}

/// `path: message` for a deserialisation error. The command's variant (`name`) is the
/// first segment of a command's paths and is dropped; serde reports a missing field at
/// the object that lacks it, so its name is added to the path (an unknown field's path
/// already ends with it); an unknown variant is an unknown `command`.
fn describe(e: &serde_path_to_error::Error<serde_json::Error>, name: Option<&str>) -> String {
    let inner = e.inner().to_string();
    let mut segments = e.path().iter().map(|s| s.to_string()).collect::<Vec<_>>();
    if name.is_some() && !segments.is_empty() {
        segments.remove(0);
    }
    if let Some(missing) = inner
        .strip_prefix("missing field `")
        .and_then(|rest| rest.split('`').next())
    {
        segments.push(missing.to_string());
    }
    if name.is_some() && segments.is_empty() {
        let inner = match inner.strip_prefix("unknown variant") {
            Some(rest) => format!("unknown command{rest}"),
            None => inner,
        };
        return field_error("command", inner);
    }
    if segments.is_empty() {
        return inner;
    }
    // Sequence indices follow their field without a dot (`offsets[2].x`).
    let mut path = String::new();
    for s in segments {
        if !path.is_empty() && !s.starts_with('[') {
            path.push('.');
        }
        path.push_str(&s);
    }
    field_error(&path, inner)
}

/// A value for an error message, cut at 60 characters.
fn short(v: &Value) -> String {
    let s = v.to_string();
    if s.chars().count() > 60 {
        format!("{}…", s.chars().take(60).collect::<String>())
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;
    use serde_json::json;

    #[derive(Debug, PartialEq, Deserialize)]
    #[serde(rename_all = "snake_case", deny_unknown_fields)]
    enum Cmd {
        Ping,
        Set { value: f64 },
        Frame { frame: Option<Frame> },
        Tune(Tuning),
    }

    #[derive(Debug, PartialEq, Deserialize)]
    #[serde(rename_all = "snake_case")]
    enum Frame {
        Vehicle,
        Earth,
    }

    #[derive(Debug, PartialEq, Default, Deserialize)]
    #[serde(default, deny_unknown_fields)]
    struct Tuning {
        gain: Option<f64>,
        points: Vec<Point>,
    }

    #[derive(Debug, PartialEq, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Point {
        north_m: f64,
    }

    fn cmd(v: Value) -> Result<Cmd, String> {
        command(v)
    }

    #[test]
    fn each_kind_of_variant_reads_from_the_tagged_object() {
        assert_eq!(cmd(json!({"command": "ping"})), Ok(Cmd::Ping));
        assert_eq!(
            cmd(json!({"command": "set", "value": 2.5})),
            Ok(Cmd::Set { value: 2.5 })
        );
        assert_eq!(
            cmd(json!({"command": "frame"})),
            Ok(Cmd::Frame { frame: None })
        );
        assert_eq!(
            cmd(json!({"command": "frame", "frame": "earth"})),
            Ok(Cmd::Frame {
                frame: Some(Frame::Earth)
            })
        );
        assert_eq!(
            cmd(json!({"command": "tune", "gain": 3})),
            Ok(Cmd::Tune(Tuning {
                gain: Some(3.0),
                points: vec![]
            }))
        );
        assert_eq!(
            cmd(json!({"command": "tune"})),
            Ok(Cmd::Tune(Tuning::default()))
        );
    }

    #[test]
    fn the_command_field_is_named_when_missing_mistyped_or_unknown() {
        assert_eq!(
            cmd(json!({"value": 1})).unwrap_err(),
            "command: missing field `command`"
        );
        assert_eq!(
            cmd(json!({"command": 7})).unwrap_err(),
            "command: expected a string, got 7"
        );
        assert_eq!(
            cmd(json!({"command": "fly"})).unwrap_err(),
            "command: unknown command `fly`, expected one of `ping`, `set`, `frame`, `tune`"
        );
        assert_eq!(
            cmd(json!({"command": "fly", "value": 1})).unwrap_err(),
            "command: unknown command `fly`, expected one of `ping`, `set`, `frame`, `tune`"
        );
        assert_eq!(
            cmd(json!([1])).unwrap_err(),
            "a command is a JSON object, got [1]"
        );
    }

    #[test]
    fn a_field_at_fault_leads_the_error() {
        assert_eq!(
            cmd(json!({"command": "set"})).unwrap_err(),
            "value: missing field `value`"
        );
        assert_eq!(
            cmd(json!({"command": "set", "value": "high"})).unwrap_err(),
            "value: invalid type: string \"high\", expected f64"
        );
        assert_eq!(
            cmd(json!({"command": "set", "value": 1, "valeu": 2})).unwrap_err(),
            "valeu: unknown field `valeu`, expected `value`"
        );
        assert_eq!(
            cmd(json!({"command": "frame", "frame": "moon"})).unwrap_err(),
            "frame: unknown variant `moon`, expected `vehicle` or `earth`"
        );
        assert_eq!(
            cmd(json!({"command": "ping", "loud": true})).unwrap_err(),
            "loud: unknown field `loud`: command `ping` takes no fields"
        );
        assert_eq!(
            cmd(json!({"command": "tune", "gian": 1})).unwrap_err(),
            "gian: unknown field `gian`, expected `gain` or `points`"
        );
        assert_eq!(
            cmd(json!({"command": "tune", "points": [{"north_m": 1}, {"north": 2}]})).unwrap_err(),
            "points[1].north: unknown field `north`, expected `north_m`"
        );
    }

    #[test]
    fn configs_read_null_as_empty_and_name_the_field() {
        assert_eq!(config::<Tuning>(Value::Null), Ok(Tuning::default()));
        assert_eq!(
            config::<Tuning>(json!({"gain": 2})).unwrap().gain,
            Some(2.0)
        );
        assert_eq!(
            config::<Tuning>(json!({"gian": 2})).unwrap_err(),
            "gian: unknown field `gian`, expected `gain` or `points`"
        );
        assert_eq!(
            config::<Tuning>(json!({"points": [{}]})).unwrap_err(),
            "points[0].north_m: missing field `north_m`"
        );
        assert!(config::<Tuning>(json!("fast")).is_err());
    }

    #[test]
    fn device_modes_resolve_auto_by_the_vehicle() {
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Cfg {
            #[serde(default)]
            mode: DeviceMode,
        }
        let mode = |v: Value| config::<Cfg>(v).map(|c| c.mode);
        assert_eq!(mode(Value::Null), Ok(DeviceMode::Auto));
        assert!(DeviceMode::Auto.simulated(true) && !DeviceMode::Auto.simulated(false));
        assert_eq!(mode(json!({"mode": "mavlink"})), Ok(DeviceMode::Mavlink));
        assert!(!DeviceMode::Mavlink.simulated(true) && DeviceMode::Simulated.simulated(false));
        assert_eq!(
            mode(json!({"mode": "real"})).unwrap_err(),
            "mode: unknown variant `real`, expected one of `auto`, `simulated`, `mavlink`"
        );
    }

    #[test]
    fn ranges_name_the_field_and_refuse_what_is_not_finite() {
        assert_eq!(in_range("zoom", 2.0, 1.0, 12.0), Ok(2.0));
        assert_eq!(
            in_range("zoom", 13.0, 1.0, 12.0).unwrap_err(),
            "zoom: 13 is outside [1, 12]"
        );
        assert!(in_range("zoom", f64::NAN, 1.0, 12.0).is_err());
        assert_eq!(
            field_error("sysid", "0 is not a system id"),
            "sysid: 0 is not a system id"
        );
    }
}
