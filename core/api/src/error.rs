//! API errors: a status code and `{"error": "...", "field": "..."}`
//! ([`crate::responses::ErrorBody`]).

use axum::Json;
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};

/// An error answered as JSON with a 4xx (or 5xx) status.
#[derive(Debug, Clone, PartialEq)]
pub struct ApiError {
    /// HTTP status.
    pub status: StatusCode,
    /// What went wrong, for a human.
    pub error: String,
    /// The request field at fault, when there is one.
    pub field: Option<String>,
}

impl ApiError {
    /// 400 naming `field`.
    pub fn field(field: &str, error: impl Into<String>) -> Self {
        ApiError {
            status: StatusCode::BAD_REQUEST,
            error: error.into(),
            field: Some(field.to_string()),
        }
    }

    /// 400 without a field (unparsable body).
    pub fn bad_request(error: impl Into<String>) -> Self {
        ApiError {
            status: StatusCode::BAD_REQUEST,
            error: error.into(),
            field: None,
        }
    }

    /// 404.
    pub fn not_found(error: impl Into<String>) -> Self {
        ApiError {
            status: StatusCode::NOT_FOUND,
            error: error.into(),
            field: None,
        }
    }

    /// 409: the vehicle's state forbids the command.
    pub fn conflict(error: impl Into<String>, field: Option<&str>) -> Self {
        ApiError {
            status: StatusCode::CONFLICT,
            error: error.into(),
            field: field.map(str::to_string),
        }
    }

    /// An error with any status.
    pub fn status(status: StatusCode, error: impl Into<String>) -> Self {
        ApiError {
            status,
            error: error.into(),
            field: None,
        }
    }

    /// 503: the coordinator did not answer.
    pub fn unavailable(error: impl Into<String>) -> Self {
        ApiError {
            status: StatusCode::SERVICE_UNAVAILABLE,
            error: error.into(),
            field: None,
        }
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let body = crate::responses::ErrorBody {
            error: self.error,
            field: self.field,
            required_role: None,
        };
        (self.status, Json(body)).into_response()
    }
}
