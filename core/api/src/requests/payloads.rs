//! `POST /api/v1/vehicles/{id}/payloads`: attach a payload at run time.

use super::{non_empty, parse};
use crate::error::ApiError;
use serde::Deserialize;
use serde_json::{Map, Value};
use skein_payload::{Isolation, PayloadSpec};
use utoipa::ToSchema;

/// An attach request.
#[derive(Debug, Clone, PartialEq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct AttachRequest {
    /// Slot name, unique on the vehicle, without `/`, not blank.
    #[schema(min_length = 1, pattern = "^[^/]*[^\\s/][^/]*$")]
    pub slot: String,
    /// The payload kind a loaded plugin (or the built-in provider) provides; not blank.
    #[schema(min_length = 1, pattern = "\\S")]
    pub kind: String,
    /// The plugin to take it from, not blank; default: any that provides `kind`.
    #[schema(pattern = "\\S")]
    pub plugin: Option<String>,
    /// Hosting; default `in_process`.
    pub isolation: Option<Isolation>,
    /// The plugin's configuration (a JSON object, passed at creation).
    #[schema(value_type = Option<Object>)]
    pub config: Option<Map<String, Value>>,
}

impl AttachRequest {
    /// The payload spec the vehicle attaches.
    ///
    /// # Errors
    /// 400 naming `slot` (empty or containing `/`), `kind` or `plugin` (empty).
    pub fn into_spec(self) -> Result<PayloadSpec, ApiError> {
        let slot = non_empty("slot", self.slot)?;
        if slot.contains('/') {
            return Err(ApiError::field(
                "slot",
                format!("slot `{slot}` contains `/`"),
            ));
        }
        Ok(PayloadSpec {
            slot,
            kind: non_empty("kind", self.kind)?,
            plugin: self.plugin.map(|p| non_empty("plugin", p)).transpose()?,
            isolation: self.isolation.unwrap_or_default(),
            config: self.config.map_or(Value::Null, Value::Object),
        })
    }
}

/// Reads an attach request body into a [`PayloadSpec`].
///
/// # Errors
/// 400 naming the field: not a JSON object, an unknown field, `slot` or `kind` missing,
/// empty or not a string, `slot` containing `/`, `plugin` not a string, `isolation` not
/// `"in_process"` or `"process"`, `config` neither an object nor null.
pub fn parse_attach(body: &[u8]) -> Result<PayloadSpec, ApiError> {
    parse::<AttachRequest>(body)?.into_spec()
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::http::StatusCode;
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
}
