//! `PUT /api/v1/vehicles/{id}/params/{name}`: a PX4 parameter's new value.

use super::parse;
use crate::error::ApiError;
use serde::Deserialize;
use utoipa::ToSchema;

/// A parameter write (PARAM_SET).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ParamValueRequest {
    /// The new value (sent as the parameter's type: an `int32` parameter takes the value
    /// rounded).
    pub value: f64,
}

/// Reads a parameter write body: the value.
///
/// # Errors
/// 400 naming `value` (missing, not a number) or an unknown field.
pub fn param_value(body: &[u8]) -> Result<f64, ApiError> {
    Ok(parse::<ParamValueRequest>(body)?.value)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_parse_and_errors_name_the_field() {
        assert_eq!(param_value(br#"{"value": 5}"#).unwrap(), 5.0);
        let field = |b: &[u8]| param_value(b).unwrap_err().field.unwrap_or_default();
        assert_eq!(field(br#"{"value": "x"}"#), "value");
        assert_eq!(field(br#"{}"#), "value");
        assert_eq!(field(br#"{"value": 1, "type": "int32"}"#), "type");
    }
}
