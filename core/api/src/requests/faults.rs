//! `POST /api/v1/faults`: break an actor on purpose (with `--enable-fault-injection`).

use super::parse;
use crate::error::ApiError;
use serde::Deserialize;
use skein_model::supervision::FaultKind;
use utoipa::ToSchema;

/// A fault to inject.
#[derive(Debug, Clone, PartialEq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct FaultRequest {
    /// The actor's path (`coordinator/uav-1/px4link`; `GET /api/v1/supervision` lists
    /// them).
    pub target: String,
    /// What to do to it.
    pub kind: FaultKind,
}

/// Reads a fault body: the target and the kind.
///
/// # Errors
/// 400 naming the field (`target` or `kind` missing, an unknown kind, an unknown field).
pub fn fault(body: &[u8]) -> Result<(String, FaultKind), ApiError> {
    let r: FaultRequest = parse(body)?;
    Ok((r.target, r.kind))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn field_of(r: Result<impl std::fmt::Debug, ApiError>) -> String {
        r.unwrap_err().field.unwrap_or_default()
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
}
