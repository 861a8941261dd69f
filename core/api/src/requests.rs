//! Parsing and validation of request bodies, with errors that name the field.
//!
//! Bodies are parsed from JSON by hand rather than by `serde` derive so that every
//! problem (missing field, wrong type, unknown value, unknown field) becomes a 400 whose
//! `field` says which one.

use crate::error::ApiError;
use serde_json::{Map, Value};
use skein_model::formation::Shape;
use skein_model::geo::Ned;
use skein_model::supervision::FaultKind;
use skein_swarm::formation::{FormationFrame, LeaderMotion};
use skein_swarm::{FormationSpec, VehicleCommand};

/// Parses a body into a JSON object.
pub fn object(body: &[u8]) -> Result<Map<String, Value>, ApiError> {
    if body.is_empty() {
        return Err(ApiError::bad_request("empty body: expected a JSON object"));
    }
    match serde_json::from_slice::<Value>(body) {
        Ok(Value::Object(m)) => Ok(m),
        Ok(_) => Err(ApiError::bad_request("expected a JSON object")),
        Err(e) => Err(ApiError::bad_request(format!("invalid JSON: {e}"))),
    }
}

fn reject_unknown(m: &Map<String, Value>, allowed: &[&str]) -> Result<(), ApiError> {
    if let Some(k) = m.keys().find(|k| !allowed.contains(&k.as_str())) {
        return Err(ApiError::field(
            k,
            format!(
                "unknown field `{k}` (expected one of: {})",
                allowed.join(", ")
            ),
        ));
    }
    Ok(())
}

fn number(m: &Map<String, Value>, field: &str) -> Result<Option<f64>, ApiError> {
    match m.get(field) {
        None | Some(Value::Null) => Ok(None),
        Some(Value::Number(n)) => n
            .as_f64()
            .filter(|v| v.is_finite())
            .map(Some)
            .ok_or_else(|| ApiError::field(field, format!("{field} must be a finite number"))),
        Some(other) => Err(ApiError::field(
            field,
            format!("{field} must be a number, got {other}"),
        )),
    }
}

fn required_number(m: &Map<String, Value>, field: &str, what: &str) -> Result<f64, ApiError> {
    number(m, field)?
        .ok_or_else(|| ApiError::field(field, format!("missing field `{field}` ({what})")))
}

fn string<'a>(m: &'a Map<String, Value>, field: &str) -> Result<Option<&'a str>, ApiError> {
    match m.get(field) {
        None | Some(Value::Null) => Ok(None),
        Some(Value::String(s)) => Ok(Some(s)),
        Some(other) => Err(ApiError::field(
            field,
            format!("{field} must be a string, got {other}"),
        )),
    }
}

/// Every command name the API accepts.
pub const COMMANDS: [&str; 10] = [
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
];

/// True for `{"command": "clear_hazard"}`: the operator says a lost vehicle is no
/// longer a hazard (a formation-level command, not one for the vehicle's FSM).
///
/// # Errors
/// A body that is not a JSON object, or `clear_hazard` with other fields.
pub fn is_clear_hazard(body: &[u8]) -> Result<bool, ApiError> {
    let m = object(body)?;
    if string(&m, "command")? != Some("clear_hazard") {
        return Ok(false);
    }
    reject_unknown(&m, &["command"])?;
    Ok(true)
}

/// Parses `{"command": "takeoff", "altitude_m": 10}` and friends.
pub fn command(body: &[u8]) -> Result<VehicleCommand, ApiError> {
    let m = object(body)?;
    let name = string(&m, "command")?.ok_or_else(|| {
        ApiError::field(
            "command",
            format!("missing field `command` (one of: {})", COMMANDS.join(", ")),
        )
    })?;
    let (cmd, allowed): (VehicleCommand, &[&str]) = match name {
        "arm" => (VehicleCommand::Arm, &["command"]),
        "disarm" => (VehicleCommand::Disarm { force: false }, &["command"]),
        "force_disarm" => {
            // Stops the motors even in the air: the caller must say so explicitly.
            if m.get("confirm") != Some(&Value::Bool(true)) {
                return Err(ApiError::field(
                    "confirm",
                    "force_disarm stops the motors even in flight: send \"confirm\": true",
                ));
            }
            (
                VehicleCommand::Disarm { force: true },
                &["command", "confirm"],
            )
        }
        "takeoff" => (
            VehicleCommand::Takeoff {
                altitude_m: match number(&m, "altitude_m")? {
                    Some(a) if a <= 0.0 => {
                        return Err(ApiError::field(
                            "altitude_m",
                            format!("altitude_m must be above 0 m, got {a}"),
                        ));
                    }
                    a => a,
                },
            },
            &["command", "altitude_m"],
        ),
        "land" => (VehicleCommand::Land, &["command"]),
        "rtl" => (VehicleCommand::Rtl, &["command"]),
        "hold" => (VehicleCommand::Hold, &["command"]),
        "goto" => (
            VehicleCommand::GoTo {
                target: Ned::new(
                    required_number(&m, "north_m", "swarm-frame north, metres")?,
                    required_number(&m, "east_m", "swarm-frame east, metres")?,
                    required_number(&m, "down_m", "swarm-frame down, metres (negative is up)")?,
                ),
            },
            &["command", "north_m", "east_m", "down_m"],
        ),
        "join_formation" => (VehicleCommand::JoinFormation, &["command"]),
        "leave_formation" => (VehicleCommand::LeaveFormation, &["command"]),
        other => {
            return Err(ApiError::field(
                "command",
                format!(
                    "unknown command `{other}` (one of: {})",
                    COMMANDS.join(", ")
                ),
            ));
        }
    };
    reject_unknown(&m, allowed)?;
    Ok(cmd)
}

/// Parses `{"value": 7.5}` (a parameter write).
pub fn param_value(body: &[u8]) -> Result<f64, ApiError> {
    let m = object(body)?;
    reject_unknown(&m, &["value"])?;
    required_number(&m, "value", "the parameter's new value")
}

/// Parses `{"target": "coordinator/uav-1/px4link", "kind": "panic"}` (`POST
/// /api/v1/faults`).
pub fn fault(body: &[u8]) -> Result<(String, FaultKind), ApiError> {
    let m = object(body)?;
    reject_unknown(&m, &["target", "kind"])?;
    let target = string(&m, "target")?
        .ok_or_else(|| {
            ApiError::field(
                "target",
                "missing field `target` (an actor path such as coordinator/uav-1/px4link; see GET /api/v1/supervision)",
            )
        })?
        .to_string();
    let names: Vec<&str> = FaultKind::ALL.iter().map(|k| k.name()).collect();
    let kind = string(&m, "kind")?.ok_or_else(|| {
        ApiError::field(
            "kind",
            format!("missing field `kind` (one of: {})", names.join(", ")),
        )
    })?;
    let kind = FaultKind::from_name(kind).ok_or_else(|| {
        ApiError::field(
            "kind",
            format!("unknown fault kind `{kind}` (one of: {})", names.join(", ")),
        )
    })?;
    Ok((target, kind))
}

/// Parses a `PUT /api/v1/formation` body.
pub fn formation(body: &[u8]) -> Result<FormationSpec, ApiError> {
    let m = object(body)?;
    reject_unknown(
        &m,
        &[
            "shape",
            "spacing_m",
            "leader",
            "heading_deg",
            "altitude_m",
            "frame",
            "offsets",
            "standoff_m",
        ],
    )?;
    let names: Vec<&str> = Shape::ALL.iter().map(|s| s.name()).collect();
    let shape_name = string(&m, "shape")?.ok_or_else(|| {
        ApiError::field(
            "shape",
            format!("missing field `shape` (one of: {})", names.join(", ")),
        )
    })?;
    let shape = Shape::from_name(shape_name).ok_or_else(|| {
        ApiError::field(
            "shape",
            format!(
                "unknown shape `{shape_name}` (one of: {})",
                names.join(", ")
            ),
        )
    })?;
    let spacing_m = if shape == Shape::Custom {
        number(&m, "spacing_m")?.unwrap_or(0.0)
    } else {
        required_number(&m, "spacing_m", "distance between slots, metres")?
    };
    if shape != Shape::Custom && spacing_m <= 0.0 {
        return Err(ApiError::field(
            "spacing_m",
            format!("spacing_m must be above 0 m, got {spacing_m}"),
        ));
    }
    let frame = match string(&m, "frame")? {
        None | Some("world") => FormationFrame::World,
        Some("leader") => FormationFrame::Leader,
        Some(other) => {
            return Err(ApiError::field(
                "frame",
                format!("unknown frame `{other}` (world, leader)"),
            ));
        }
    };
    let offsets = match m.get("offsets") {
        None | Some(Value::Null) => vec![],
        Some(Value::Array(items)) => items
            .iter()
            .enumerate()
            .map(|(i, o)| {
                let field = format!("offsets[{i}]");
                let Value::Object(o) = o else {
                    return Err(ApiError::field(
                        &field,
                        format!("{field} must be an object {{forward_m, right_m, down_m}}"),
                    ));
                };
                reject_unknown(o, &["forward_m", "right_m", "down_m"])?;
                let get = |k: &str| -> Result<f64, ApiError> {
                    number(o, k)
                        .map_err(|e| ApiError::field(&field, e.error))?
                        .ok_or_else(|| ApiError::field(&field, format!("{field}: missing `{k}`")))
                };
                Ok(Ned::new(
                    get("forward_m")?,
                    get("right_m")?,
                    number(o, "down_m")?.unwrap_or(0.0),
                ))
            })
            .collect::<Result<Vec<_>, _>>()?,
        Some(other) => {
            return Err(ApiError::field(
                "offsets",
                format!("offsets must be a list of {{forward_m, right_m, down_m}}, got {other}"),
            ));
        }
    };
    Ok(FormationSpec {
        shape,
        spacing_m,
        leader: string(&m, "leader")?.map(str::to_string),
        heading_deg: number(&m, "heading_deg")?.unwrap_or(0.0),
        altitude_m: number(&m, "altitude_m")?,
        frame,
        offsets,
        standoff_m: number(&m, "standoff_m")?,
    })
}

/// Default speed of leader motions, m/s.
pub const DEFAULT_LEADER_SPEED_M_S: f64 = 5.0;

fn point(m: &Map<String, Value>, what: &str) -> Result<Ned, ApiError> {
    Ok(Ned::new(
        required_number(m, "north_m", &format!("{what}, swarm-frame north, metres"))?,
        required_number(m, "east_m", &format!("{what}, swarm-frame east, metres"))?,
        // Missing altitude: keep the formation's (the coordinator fills NaN in).
        number(m, "down_m")?.unwrap_or(f64::NAN),
    ))
}

fn speed(m: &Map<String, Value>) -> Result<f64, ApiError> {
    Ok(number(m, "speed_m_s")?.unwrap_or(DEFAULT_LEADER_SPEED_M_S))
}

/// Parses the leader commands: `POST /api/v1/formation/leader/{goto,waypoints,orbit,hold}`.
pub fn leader_motion(kind: &str, body: &[u8]) -> Result<LeaderMotion, ApiError> {
    let m = if body.is_empty() {
        Map::new()
    } else {
        object(body)?
    };
    Ok(match kind {
        "goto" => {
            reject_unknown(&m, &["north_m", "east_m", "down_m", "speed_m_s"])?;
            LeaderMotion::GoTo {
                target: point(&m, "the point")?,
                speed_m_s: speed(&m)?,
            }
        }
        "waypoints" => {
            reject_unknown(&m, &["waypoints", "speed_m_s", "repeat"])?;
            let Some(Value::Array(items)) = m.get("waypoints") else {
                return Err(ApiError::field(
                    "waypoints",
                    "missing field `waypoints` (a list of {north_m, east_m, down_m})",
                ));
            };
            let points = items
                .iter()
                .enumerate()
                .map(|(i, w)| match w {
                    Value::Object(w) => point(w, &format!("waypoints[{i}]"))
                        .map_err(|e| ApiError::field(&format!("waypoints[{i}]"), e.error)),
                    _ => Err(ApiError::field(
                        &format!("waypoints[{i}]"),
                        "each waypoint is an object {north_m, east_m, down_m}",
                    )),
                })
                .collect::<Result<Vec<_>, _>>()?;
            LeaderMotion::Waypoints {
                points,
                speed_m_s: speed(&m)?,
                next: 0,
                repeat: matches!(m.get("repeat"), Some(Value::Bool(true))),
            }
        }
        "orbit" => {
            reject_unknown(
                &m,
                &[
                    "north_m",
                    "east_m",
                    "down_m",
                    "radius_m",
                    "speed_m_s",
                    "clockwise",
                ],
            )?;
            LeaderMotion::Orbit {
                centre: point(&m, "the centre")?,
                radius_m: required_number(&m, "radius_m", "orbit radius, metres")?,
                speed_m_s: speed(&m)?,
                clockwise: !matches!(m.get("clockwise"), Some(Value::Bool(false))),
            }
        }
        "hold" => {
            reject_unknown(&m, &[])?;
            LeaderMotion::Hold
        }
        other => {
            return Err(ApiError::not_found(format!(
                "no leader command `{other}` (goto, waypoints, orbit, hold)"
            )));
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn field_of(r: Result<impl std::fmt::Debug, ApiError>) -> String {
        r.unwrap_err().field.unwrap_or_default()
    }

    #[test]
    fn commands_parse() {
        assert_eq!(
            command(br#"{"command":"takeoff","altitude_m":10}"#).unwrap(),
            VehicleCommand::Takeoff {
                altitude_m: Some(10.0)
            }
        );
        assert_eq!(
            command(br#"{"command":"takeoff"}"#).unwrap(),
            VehicleCommand::Takeoff { altitude_m: None }
        );
        assert_eq!(
            command(br#"{"command":"goto","north_m":1,"east_m":2,"down_m":-10}"#).unwrap(),
            VehicleCommand::GoTo {
                target: Ned::new(1.0, 2.0, -10.0)
            }
        );
    }

    #[test]
    fn command_errors_name_the_field() {
        assert_eq!(field_of(command(br#"{}"#)), "command");
        assert_eq!(field_of(command(br#"{"command":"fly"}"#)), "command");
        assert_eq!(
            field_of(command(br#"{"command":"takeoff","altitude_m":"high"}"#)),
            "altitude_m"
        );
        assert_eq!(
            field_of(command(br#"{"command":"takeoff","altitude_m":-3}"#)),
            "altitude_m"
        );
        assert_eq!(
            field_of(command(br#"{"command":"goto","north_m":1}"#)),
            "east_m"
        );
        assert_eq!(
            field_of(command(br#"{"command":"arm","force":true}"#)),
            "force"
        );
        assert_eq!(
            field_of(command(br#"{"command":"force_disarm"}"#)),
            "confirm"
        );
        assert_eq!(
            command(br#"{"command":"force_disarm","confirm":true}"#).unwrap(),
            VehicleCommand::Disarm { force: true }
        );
        assert_eq!(param_value(br#"{"value": 5}"#).unwrap(), 5.0);
        assert_eq!(field_of(param_value(br#"{"value": "x"}"#)), "value");
        assert_eq!(field_of(param_value(br#"{}"#)), "value");
        assert!(
            command(b"not json")
                .unwrap_err()
                .error
                .contains("invalid JSON")
        );
    }

    #[test]
    fn leader_motions_parse_and_errors_name_the_field() {
        let g = leader_motion("goto", br#"{"north_m":10,"east_m":5,"speed_m_s":3}"#).unwrap();
        let LeaderMotion::GoTo { target, speed_m_s } = g else {
            panic!()
        };
        assert_eq!((target.north_m, target.east_m, speed_m_s), (10.0, 5.0, 3.0));
        assert!(target.down_m.is_nan(), "altitude left to the formation");
        assert_eq!(
            field_of(leader_motion("goto", br#"{"north_m":10}"#)),
            "east_m"
        );
        let w = leader_motion("waypoints", br#"{"waypoints":[{"north_m":1,"east_m":2},{"north_m":3,"east_m":4,"down_m":-12}],"repeat":true}"#).unwrap();
        assert!(
            matches!(w, LeaderMotion::Waypoints { ref points, repeat: true, .. } if points.len() == 2)
        );
        assert_eq!(
            field_of(leader_motion(
                "waypoints",
                br#"{"waypoints":[{"north_m":1}]}"#
            )),
            "waypoints[0]"
        );
        assert_eq!(field_of(leader_motion("waypoints", br#"{}"#)), "waypoints");
        let o = leader_motion(
            "orbit",
            br#"{"north_m":0,"east_m":0,"radius_m":20,"clockwise":false}"#,
        )
        .unwrap();
        assert!(
            matches!(o, LeaderMotion::Orbit { radius_m, clockwise: false, .. } if radius_m == 20.0)
        );
        assert_eq!(
            field_of(leader_motion("orbit", br#"{"north_m":0,"east_m":0}"#)),
            "radius_m"
        );
        assert_eq!(leader_motion("hold", b"").unwrap(), LeaderMotion::Hold);
        assert_eq!(
            leader_motion("spin", b"").unwrap_err().status,
            axum::http::StatusCode::NOT_FOUND
        );
    }

    #[test]
    fn faults_parse_and_errors_name_the_field() {
        assert_eq!(
            fault(br#"{"target":"coordinator/uav-1","kind":"hang"}"#).unwrap(),
            ("coordinator/uav-1".to_string(), FaultKind::Hang)
        );
        assert_eq!(field_of(fault(br#"{"kind":"panic"}"#)), "target");
        assert_eq!(field_of(fault(br#"{"target":"coordinator"}"#)), "kind");
        assert_eq!(
            field_of(fault(br#"{"target":"coordinator","kind":"explode"}"#)),
            "kind"
        );
    }

    #[test]
    fn formation_parses_and_errors_name_the_field() {
        let f = formation(br#"{"shape":"line","spacing_m":5,"leader":"uav-1"}"#).unwrap();
        assert_eq!(f.shape, Shape::Line);
        assert_eq!(f.spacing_m, 5.0);
        assert_eq!(f.leader.as_deref(), Some("uav-1"));
        assert_eq!(field_of(formation(br#"{"spacing_m":5}"#)), "shape");
        let f =
            formation(br#"{"shape":"wedge","spacing_m":4,"leader":"virtual","frame":"leader"}"#)
                .unwrap();
        assert_eq!(
            (f.shape, f.frame, f.leader.as_deref()),
            (Shape::Wedge, FormationFrame::Leader, Some("virtual"))
        );
        let f =
            formation(br#"{"shape":"custom","offsets":[{"forward_m":-4,"right_m":3}]}"#).unwrap();
        assert_eq!(f.offsets, vec![Ned::new(-4.0, 3.0, 0.0)]);
        assert_eq!(
            field_of(formation(
                br#"{"shape":"custom","offsets":[{"forward_m":-4}]}"#
            )),
            "offsets[0]"
        );
        assert_eq!(
            field_of(formation(
                br#"{"shape":"line","spacing_m":5,"frame":"body"}"#
            )),
            "frame"
        );
        let e = formation(br#"{"shape":"hexagon","spacing_m":5}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("shape"));
        assert!(e.error.contains("hexagon"));
        assert_eq!(field_of(formation(br#"{"shape":"line"}"#)), "spacing_m");
        assert_eq!(
            field_of(formation(br#"{"shape":"line","spacing_m":-1}"#)),
            "spacing_m"
        );
        assert_eq!(
            field_of(formation(br#"{"shape":"line","spacing_m":5,"spacing":3}"#)),
            "spacing"
        );
    }
}
