//! `POST /api/v1/plugins/{load,unload,reload}`: plugin libraries at run time.

use super::{non_empty, parse};
use crate::error::ApiError;
use serde::Deserialize;
use utoipa::ToSchema;

/// `POST /api/v1/plugins/load`.
#[derive(Debug, Clone, PartialEq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct LoadRequest {
    /// The library file, relative to the plugin directory (an absolute path must be
    /// inside it); not blank.
    #[schema(min_length = 1, pattern = "\\S")]
    pub file: String,
}

/// `POST /api/v1/plugins/unload`.
#[derive(Debug, Clone, PartialEq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct UnloadRequest {
    /// The plugin's name; not blank.
    #[schema(min_length = 1, pattern = "\\S")]
    pub name: String,
    /// Stop the library's instances first (their slots wait again); default false.
    pub force: Option<bool>,
}

/// `POST /api/v1/plugins/reload`.
#[derive(Debug, Clone, PartialEq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ReloadRequest {
    /// The plugin's name; not blank.
    #[schema(min_length = 1, pattern = "\\S")]
    pub name: String,
}

/// Reads a load body: the file.
///
/// # Errors
/// 400 naming the field (`file` missing, empty, not a string; an unknown field).
pub fn load(body: &[u8]) -> Result<String, ApiError> {
    non_empty("file", parse::<LoadRequest>(body)?.file)
}

/// Reads an unload body: the name and whether to force.
///
/// # Errors
/// 400 naming the field.
pub fn unload(body: &[u8]) -> Result<(String, bool), ApiError> {
    let r: UnloadRequest = parse(body)?;
    Ok((non_empty("name", r.name)?, r.force.unwrap_or(false)))
}

/// Reads a reload body: the name.
///
/// # Errors
/// 400 naming the field.
pub fn reload(body: &[u8]) -> Result<String, ApiError> {
    non_empty("name", parse::<ReloadRequest>(body)?.name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bodies_name_the_field() {
        assert_eq!(load(br#"{"file": "libx.so"}"#).unwrap(), "libx.so");
        let e = load(br#"{"fil": "libx.so"}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("fil"), "{e:?}");
        let e = load(br#"{"file": 3}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("file"), "{e:?}");
        let e = load(br#"{"file": " "}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("file"), "{e:?}");
        let e = reload(b"{}").unwrap_err();
        assert_eq!(e.field.as_deref(), Some("name"), "{e:?}");
        assert_eq!(e.status, axum::http::StatusCode::BAD_REQUEST);
    }

    #[test]
    fn unload_bodies_take_an_optional_force() {
        assert_eq!(
            unload(br#"{"name": "lamp"}"#).unwrap(),
            ("lamp".into(), false)
        );
        assert_eq!(
            unload(br#"{"name": "lamp", "force": true}"#).unwrap(),
            ("lamp".into(), true)
        );
        let e = unload(br#"{"name": "lamp", "force": "yes"}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("force"), "{e:?}");
        let e = unload(br#"{"name": "lamp", "forse": true}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("forse"), "{e:?}");
        assert!(e.error.contains("`force`"), "{e:?}");
        let e = unload(br#"{"force": true}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("name"), "{e:?}");
    }
}
