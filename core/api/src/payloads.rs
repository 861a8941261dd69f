//! Attaching and detaching payloads at run time, and how payload errors become HTTP
//! answers.
//!
//! - `POST /api/v1/vehicles/{id}/payloads` `{"slot", "kind", "plugin"?, "isolation"?,
//!   "config"?}` → 201 with the payload as `GET …/payloads` lists it, once its driver
//!   exists. 400 naming the field for a malformed body or unknown field, an unknown kind
//!   (`kind`) or plugin (`plugin`), or a config the plugin refused at creation (`config`;
//!   the slot is not kept); 409 naming `slot` for a slot the vehicle has; 404 for an
//!   unknown vehicle.
//! - `DELETE /api/v1/vehicles/{id}/payloads/{slot}` → `{"detached": slot, "kind"}` after
//!   the driver's `shutdown` ran; 404 for an unknown vehicle or slot.
//!
//! Both last until skein restarts: the vehicle model (`skein up --config`) is what a
//! restart starts from.

use crate::error::ApiError;
use crate::requests;
use axum::http::StatusCode;
use serde_json::Value;
use skein_payload::{Isolation, PayloadSpec};
use skein_swarm::payload::PayloadCommandError;

/// The fields of an attach request.
const ATTACH_FIELDS: [&str; 5] = ["slot", "kind", "plugin", "isolation", "config"];

/// Reads an attach request body into a [`PayloadSpec`].
///
/// # Errors
/// 400 naming the field: not a JSON object, an unknown field, `slot` or `kind` missing,
/// empty or not a string, `slot` containing `/`, `plugin` not a string, `isolation` not
/// `"in_process"` or `"process"`, `config` neither an object nor null.
pub fn parse_attach(body: &[u8]) -> Result<PayloadSpec, ApiError> {
    let m = requests::object(body)?;
    if let Some(k) = m.keys().find(|k| !ATTACH_FIELDS.contains(&k.as_str())) {
        return Err(ApiError::field(
            k,
            format!(
                "unknown field `{k}` (expected one of: {})",
                ATTACH_FIELDS.join(", ")
            ),
        ));
    }
    let text = |field: &str, required: bool| -> Result<Option<String>, ApiError> {
        match m.get(field) {
            None | Some(Value::Null) if required => {
                Err(ApiError::field(field, format!("missing field `{field}`")))
            }
            None | Some(Value::Null) => Ok(None),
            Some(Value::String(s)) if s.trim().is_empty() => {
                Err(ApiError::field(field, format!("{field} is empty")))
            }
            Some(Value::String(s)) => Ok(Some(s.clone())),
            Some(other) => Err(ApiError::field(
                field,
                format!("{field} must be a string, got {other}"),
            )),
        }
    };
    let slot = text("slot", true)?.unwrap_or_default();
    if slot.contains('/') {
        return Err(ApiError::field(
            "slot",
            format!("slot `{slot}` contains `/`"),
        ));
    }
    let kind = text("kind", true)?.unwrap_or_default();
    let plugin = text("plugin", false)?;
    let isolation = match text("isolation", false)?.as_deref() {
        None | Some("in_process") => Isolation::InProcess,
        Some("process") => Isolation::Process,
        Some(other) => {
            return Err(ApiError::field(
                "isolation",
                format!("isolation `{other}`: expected `in_process` or `process`"),
            ));
        }
    };
    let config = match m.get("config") {
        None | Some(Value::Null) => Value::Null,
        Some(v @ Value::Object(_)) => v.clone(),
        Some(other) => {
            return Err(ApiError::field(
                "config",
                format!("config must be a JSON object, got {other}"),
            ));
        }
    };
    Ok(PayloadSpec {
        slot,
        kind,
        plugin,
        isolation,
        config,
    })
}

/// The HTTP answer for a payload request that got no answer from the payload: 404, 503,
/// 400 (a plugin's refusal names the field as `"field: message"` by convention), 400 or
/// 409 naming the field.
pub fn payload_error(e: PayloadCommandError) -> ApiError {
    match e {
        PayloadCommandError::NotFound(why) => ApiError::not_found(why),
        PayloadCommandError::Unavailable(why) => ApiError::unavailable(why),
        PayloadCommandError::Refused(why) => {
            let field = why
                .split_once(':')
                .map(|(f, _)| f.trim())
                .filter(|f| {
                    !f.is_empty() && f.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
                })
                .map(str::to_string);
            ApiError {
                status: StatusCode::BAD_REQUEST,
                error: why,
                field,
            }
        }
        PayloadCommandError::Invalid { field, error } => ApiError::field(&field, error),
        PayloadCommandError::Conflict { field, error } => ApiError::conflict(error, Some(&field)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn field_of(body: Value) -> (StatusCode, Option<String>) {
        let e = parse_attach(body.to_string().as_bytes()).unwrap_err();
        (e.status, e.field)
    }

    #[test]
    fn attach_bodies_are_read_or_refused_naming_the_field() {
        let s = parse_attach(br#"{"slot": "lamp", "kind": "lamp"}"#).unwrap();
        assert_eq!((s.slot.as_str(), s.kind.as_str()), ("lamp", "lamp"));
        assert_eq!(
            (s.plugin, s.isolation, s.config),
            (None, Isolation::InProcess, Value::Null)
        );
        let s = parse_attach(
            json!({"slot": "l", "kind": "lamp", "plugin": "lamps", "isolation": "process",
                   "config": {"on": true}})
            .to_string()
            .as_bytes(),
        )
        .unwrap();
        assert_eq!(s.plugin.as_deref(), Some("lamps"));
        assert_eq!(s.isolation, Isolation::Process);
        assert_eq!(s.config, json!({"on": true}));

        let bad = StatusCode::BAD_REQUEST;
        let f = |s: &str| (bad, Some(s.to_string()));
        assert_eq!(
            field_of(json!({"slot": "l", "kind": "k", "colour": 1})),
            f("colour")
        );
        assert_eq!(field_of(json!({"kind": "k"})), f("slot"));
        assert_eq!(field_of(json!({"slot": "", "kind": "k"})), f("slot"));
        assert_eq!(field_of(json!({"slot": "a/b", "kind": "k"})), f("slot"));
        assert_eq!(field_of(json!({"slot": "l"})), f("kind"));
        assert_eq!(field_of(json!({"slot": "l", "kind": 3})), f("kind"));
        assert_eq!(
            field_of(json!({"slot": "l", "kind": "k", "plugin": 1})),
            f("plugin")
        );
        assert_eq!(
            field_of(json!({"slot": "l", "kind": "k", "isolation": "thread"})),
            f("isolation")
        );
        assert_eq!(
            field_of(json!({"slot": "l", "kind": "k", "config": [1]})),
            f("config")
        );
        assert!(parse_attach(b"[]").unwrap_err().field.is_none());
    }

    #[test]
    fn payload_errors_map_to_statuses_and_fields() {
        let e = payload_error(PayloadCommandError::Conflict {
            field: "slot".into(),
            error: "exists".into(),
        });
        assert_eq!(
            (e.status, e.field.as_deref()),
            (StatusCode::CONFLICT, Some("slot"))
        );
        let e = payload_error(PayloadCommandError::Invalid {
            field: "config".into(),
            error: "lamp config: unknown field `x`".into(),
        });
        assert_eq!(
            (e.status, e.field.as_deref()),
            (StatusCode::BAD_REQUEST, Some("config"))
        );
        let e = payload_error(PayloadCommandError::Refused("on: must be a boolean".into()));
        assert_eq!(e.field.as_deref(), Some("on"));
        let e = payload_error(PayloadCommandError::Unavailable("waiting".into()));
        assert_eq!(e.status, StatusCode::SERVICE_UNAVAILABLE);
    }
}
