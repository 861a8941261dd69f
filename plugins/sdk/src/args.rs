//! Reading commands and configurations (JSON objects) with errors that name the field.
//!
//! ```
//! use skein_plugin_sdk::args::{Args, command_name};
//! let cmd = serde_json::json!({"command": "set_angles", "pitch_deg": "down"});
//! assert_eq!(command_name(&cmd, &["set_angles", "neutral"]).unwrap(), "set_angles");
//! let args = Args::new(&cmd, "command `set_angles`", &["command", "pitch_deg", "yaw_deg"]).unwrap();
//! let err = args.f64("pitch_deg").unwrap_err();
//! assert_eq!(err, "command `set_angles`: field `pitch_deg`: expected a number, got \"down\"");
//! ```

use serde_json::{Map, Value};

/// The `command` field of an operator command, checked against the known commands.
///
/// # Errors
/// Not an object, no `command` string, or an unknown command (the error lists the known
/// ones).
pub fn command_name<'a>(command: &'a Value, known: &[&str]) -> Result<&'a str, String> {
    let obj = command
        .as_object()
        .ok_or_else(|| format!("a command is a JSON object, got {}", short(command)))?;
    let name = match obj.get("command") {
        Some(Value::String(s)) => s.as_str(),
        Some(other) => {
            return Err(format!(
                "field `command`: expected a string, got {}",
                short(other)
            ));
        }
        None => {
            return Err(format!(
                "missing field `command` (one of: {})",
                known.join(", ")
            ));
        }
    };
    if known.contains(&name) {
        Ok(name)
    } else {
        Err(format!(
            "field `command`: unknown command `{name}` (one of: {})",
            known.join(", ")
        ))
    }
}

/// A JSON object's fields, read one by one with errors prefixed by what the object is
/// (`"command `set_angles`"`, `"gimbal config"`).
pub struct Args<'a> {
    what: String,
    map: Option<&'a Map<String, Value>>,
}

fn short(v: &Value) -> String {
    let s = v.to_string();
    if s.chars().count() > 60 {
        format!("{}…", s.chars().take(60).collect::<String>())
    } else {
        s
    }
}

impl<'a> Args<'a> {
    /// Checks that `value` is an object (or `null`, read as empty) whose fields are all in
    /// `allowed`.
    ///
    /// # Errors
    /// Not an object, or a field not in `allowed` (a typo: the error names it and lists the
    /// allowed ones).
    pub fn new(
        value: &'a Value,
        what: impl Into<String>,
        allowed: &[&str],
    ) -> Result<Args<'a>, String> {
        let what = what.into();
        let map = match value {
            Value::Null => None,
            Value::Object(m) => Some(m),
            other => {
                return Err(format!(
                    "{what}: expected a JSON object, got {}",
                    short(other)
                ));
            }
        };
        if let Some(m) = map {
            for key in m.keys() {
                if !allowed.contains(&key.as_str()) {
                    return Err(format!(
                        "{what}: unknown field `{key}` (expected one of: {})",
                        allowed.join(", ")
                    ));
                }
            }
        }
        Ok(Args { what, map })
    }

    /// The raw value of a field, if present and not `null`.
    pub fn get(&self, name: &str) -> Option<&'a Value> {
        self.map?.get(name).filter(|v| !v.is_null())
    }

    /// True when the field is present (and not `null`).
    pub fn has(&self, name: &str) -> bool {
        self.get(name).is_some()
    }

    /// An error about a field, in this object's style.
    pub fn error(&self, name: &str, message: impl std::fmt::Display) -> String {
        format!("{}: field `{name}`: {message}", self.what)
    }

    fn missing(&self, name: &str) -> String {
        format!("{}: missing field `{name}`", self.what)
    }

    /// An optional number.
    ///
    /// # Errors
    /// Present but not a number.
    pub fn opt_f64(&self, name: &str) -> Result<Option<f64>, String> {
        match self.get(name) {
            None => Ok(None),
            Some(v) => v
                .as_f64()
                .map(Some)
                .ok_or_else(|| self.error(name, format!("expected a number, got {}", short(v)))),
        }
    }

    /// A required number.
    ///
    /// # Errors
    /// Missing or not a number.
    pub fn f64(&self, name: &str) -> Result<f64, String> {
        self.opt_f64(name)?.ok_or_else(|| self.missing(name))
    }

    /// A number with a default, checked to lie in `[min, max]`.
    ///
    /// # Errors
    /// Not a number, or out of range (the error gives the range and unit-bearing name).
    pub fn f64_in(&self, name: &str, default: f64, min: f64, max: f64) -> Result<f64, String> {
        let v = self.opt_f64(name)?.unwrap_or(default);
        self.check_range(name, v, min, max)
    }

    /// A required number checked to lie in `[min, max]`.
    ///
    /// # Errors
    /// Missing, not a number, or out of range.
    pub fn f64_required_in(&self, name: &str, min: f64, max: f64) -> Result<f64, String> {
        let v = self.f64(name)?;
        self.check_range(name, v, min, max)
    }

    fn check_range(&self, name: &str, v: f64, min: f64, max: f64) -> Result<f64, String> {
        if v.is_finite() && v >= min && v <= max {
            Ok(v)
        } else {
            Err(self.error(name, format!("{v} is outside [{min}, {max}]")))
        }
    }

    /// An optional string.
    ///
    /// # Errors
    /// Present but not a string.
    pub fn opt_str(&self, name: &str) -> Result<Option<&'a str>, String> {
        match self.get(name) {
            None => Ok(None),
            Some(Value::String(s)) => Ok(Some(s.as_str())),
            Some(v) => Err(self.error(name, format!("expected a string, got {}", short(v)))),
        }
    }

    /// A required string.
    ///
    /// # Errors
    /// Missing or not a string.
    pub fn str(&self, name: &str) -> Result<&'a str, String> {
        self.opt_str(name)?.ok_or_else(|| self.missing(name))
    }

    /// An optional string that must be one of `choices`.
    ///
    /// # Errors
    /// Not a string, or not one of the choices (listed).
    pub fn opt_choice(&self, name: &str, choices: &[&str]) -> Result<Option<&'a str>, String> {
        match self.opt_str(name)? {
            None => Ok(None),
            Some(s) if choices.contains(&s) => Ok(Some(s)),
            Some(s) => {
                Err(self.error(name, format!("`{s}` is not one of: {}", choices.join(", "))))
            }
        }
    }

    /// An optional boolean.
    ///
    /// # Errors
    /// Present but not a boolean.
    pub fn opt_bool(&self, name: &str) -> Result<Option<bool>, String> {
        match self.get(name) {
            None => Ok(None),
            Some(Value::Bool(b)) => Ok(Some(*b)),
            Some(v) => Err(self.error(name, format!("expected true or false, got {}", short(v)))),
        }
    }

    /// An optional non-negative integer.
    ///
    /// # Errors
    /// Present but not a non-negative integer.
    pub fn opt_u64(&self, name: &str) -> Result<Option<u64>, String> {
        match self.get(name) {
            None => Ok(None),
            Some(v) => v.as_u64().map(Some).ok_or_else(|| {
                self.error(
                    name,
                    format!("expected a non-negative integer, got {}", short(v)),
                )
            }),
        }
    }

    /// An optional nested object, as its own [`Args`] with `allowed` fields.
    ///
    /// # Errors
    /// Present but not an object, or with an unknown field.
    pub fn opt_object(&self, name: &str, allowed: &[&str]) -> Result<Option<Args<'a>>, String> {
        match self.get(name) {
            None => Ok(None),
            Some(v) => Args::new(v, format!("{}: field `{name}`", self.what), allowed).map(Some),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn unknown_fields_are_named() {
        let v = json!({"command": "x", "pich_deg": 3});
        let e = Args::new(&v, "command `x`", &["command", "pitch_deg"])
            .err()
            .unwrap();
        assert_eq!(
            e,
            "command `x`: unknown field `pich_deg` (expected one of: command, pitch_deg)"
        );
    }

    #[test]
    fn missing_and_mistyped_fields_are_named() {
        let v = json!({"a": "no", "b": 5});
        let args = Args::new(&v, "cfg", &["a", "b", "c"]).unwrap();
        assert_eq!(args.f64("c").unwrap_err(), "cfg: missing field `c`");
        assert_eq!(
            args.f64("a").unwrap_err(),
            "cfg: field `a`: expected a number, got \"no\""
        );
        assert_eq!(
            args.f64_in("b", 0.0, 0.0, 4.0).unwrap_err(),
            "cfg: field `b`: 5 is outside [0, 4]"
        );
        assert_eq!(args.f64_in("c", 2.0, 0.0, 4.0).unwrap(), 2.0);
        assert_eq!(
            args.str("b").unwrap_err(),
            "cfg: field `b`: expected a string, got 5"
        );
    }

    #[test]
    fn null_config_is_empty() {
        let v = Value::Null;
        let args = Args::new(&v, "cfg", &["x"]).unwrap();
        assert_eq!(args.opt_f64("x").unwrap(), None);
    }

    #[test]
    fn commands_are_checked() {
        assert_eq!(
            command_name(&json!({"command": "fly"}), &["a", "b"]).unwrap_err(),
            "field `command`: unknown command `fly` (one of: a, b)"
        );
        assert_eq!(
            command_name(&json!({}), &["a"]).unwrap_err(),
            "missing field `command` (one of: a)"
        );
        assert!(command_name(&json!([1]), &["a"]).is_err());
    }

    #[test]
    fn choices() {
        let v = json!({"frame": "moon"});
        let args = Args::new(&v, "cmd", &["frame"]).unwrap();
        assert_eq!(
            args.opt_choice("frame", &["vehicle", "earth"]).unwrap_err(),
            "cmd: field `frame`: `moon` is not one of: vehicle, earth"
        );
    }
}
