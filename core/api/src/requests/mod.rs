//! Request bodies as typed serde structs: what the API accepts, parsed with the path of
//! the field at fault, and documented by the same types in the OpenAPI contract
//! ([`crate::openapi`]).
//!
//! Every body type refuses unknown fields (`deny_unknown_fields`). [`parse`] turns any
//! problem into a 400 `{"error", "field"}` whose `field` is the path of the culprit
//! (`offsets[2].right_m`, `waypoints[0].east_m`), found by `serde_path_to_error`. The
//! checks serde cannot express (ranges, non-empty names, `confirm: true`) follow in each
//! type's conversion into the domain type of `skein_swarm` / `skein_model`; numeric ranges
//! are read from the type's own schema ([`schema_bounds`]), and names that must not be
//! blank say so in theirs (`pattern: \S`), so the contract states what is checked.
//!
//! One module per concept: [`commands`] (vehicle and swarm commands), [`formation`],
//! [`leader`] (leader motion), [`payloads`] (attach), [`plugins`], [`faults`],
//! [`px4_param_write`], [`recording`], [`tracks`].

pub mod commands;
pub mod faults;
pub mod formation;
pub mod leader;
pub mod payloads;
pub mod plugins;
pub mod px4_param_write;
pub mod recording;
pub mod schema_bounds;
pub mod tracks;

pub use commands::Command;

use crate::error::ApiError;
use serde::de::DeserializeOwned;
use serde_json::{Map, Value};

/// Parses a body into a JSON object.
///
/// # Errors
/// 400 without a field: an empty body, invalid JSON, or JSON that is not an object.
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

/// Parses a JSON object body into `T`.
///
/// # Errors
/// 400 without a field for a body that is not a JSON object ([`object`]); 400 naming the
/// field path for anything `T` refuses (missing, unknown, wrong type, unknown value).
pub fn parse<T: DeserializeOwned>(body: &[u8]) -> Result<T, ApiError> {
    from_map(object(body)?)
}

/// Like [`parse`], with an empty body read as `{}` (bodies whose every field is optional).
///
/// # Errors
/// As [`parse`].
pub fn parse_or_empty<T: DeserializeOwned>(body: &[u8]) -> Result<T, ApiError> {
    if body.is_empty() {
        return from_map(Map::new());
    }
    parse(body)
}

/// Deserialises `T` from an object already parsed.
///
/// # Errors
/// 400 naming the field path (see [`parse`]).
pub fn from_map<T: DeserializeOwned>(m: Map<String, Value>) -> Result<T, ApiError> {
    serde_path_to_error::deserialize(Value::Object(m)).map_err(|e| field_error(&e))
}

/// The 400 for a deserialisation error: serde reports a missing field at the object that
/// lacks it, so the field's own name is added to the path (an unknown field's path
/// already ends with it).
fn field_error(e: &serde_path_to_error::Error<serde_json::Error>) -> ApiError {
    let inner = e.inner().to_string();
    let mut segments: Vec<String> = Vec::new();
    let path = e.path().to_string();
    if path.is_empty() {
        // A key that is the empty string (`{"": 1}`): name it as JSON writes it.
        segments.push("\"\"".to_string());
    } else if path != "." {
        segments.push(path);
    }
    let named = inner
        .strip_prefix("missing field `")
        .and_then(|rest| rest.split('`').next());
    if let Some(name) = named {
        segments.push(name.to_string());
    }
    if segments.is_empty() {
        return ApiError::bad_request(inner);
    }
    let field = segments.join(".");
    ApiError::field(&field, format!("{field}: {inner}"))
}

/// 400 naming `field` unless `value` is a non-empty, non-blank string.
///
/// # Errors
/// 400 naming `field` for an empty or blank `value`.
pub fn non_empty(field: &str, value: String) -> Result<String, ApiError> {
    if value.trim().is_empty() {
        return Err(ApiError::field(field, format!("{field} is empty")));
    }
    Ok(value)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Found by the api_requests fuzz target: an unknown key that is the empty string
    /// was answered with an empty `field`.
    #[test]
    fn an_empty_key_is_named() {
        #[derive(Debug, serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        #[allow(dead_code)]
        struct Body {
            name: Option<String>,
        }
        let e = parse::<Body>(br#"{"": 5}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("\"\""), "{e:?}");
    }
    use serde::Deserialize;

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Inner {
        right_m: f64,
    }

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Outer {
        offsets: Vec<Inner>,
    }

    fn field(body: &str) -> Option<String> {
        parse::<Outer>(body.as_bytes()).unwrap_err().field
    }

    #[test]
    fn errors_name_the_field_path() {
        assert_eq!(
            field(r#"{"offsets":[{"right_m":1},{"right_m":"x"}]}"#).as_deref(),
            Some("offsets[1].right_m")
        );
        assert_eq!(
            field(r#"{"offsets":[{"right_m":1},{}]}"#).as_deref(),
            Some("offsets[1].right_m")
        );
        assert_eq!(
            field(r#"{"offsets":[{"right_m":1,"left_m":2}]}"#).as_deref(),
            Some("offsets[0].left_m")
        );
        assert_eq!(field(r#"{}"#).as_deref(), Some("offsets"));
        assert_eq!(field(r#"{"offsets":3}"#).as_deref(), Some("offsets"));
        let e = parse::<Outer>(br#"{"offsets":[{"right_m":"x"}]}"#).unwrap_err();
        assert_eq!(e.status, axum::http::StatusCode::BAD_REQUEST);
        assert!(
            e.error.starts_with("offsets[0].right_m: invalid type"),
            "{e:?}"
        );
        assert!(parse::<Outer>(b"").unwrap_err().field.is_none());
        assert!(parse::<Outer>(b"[1]").unwrap_err().field.is_none());
        assert!(
            parse::<Outer>(b"{nope")
                .unwrap_err()
                .error
                .contains("invalid JSON")
        );
    }
}
