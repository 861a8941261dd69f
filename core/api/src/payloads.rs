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
use axum::http::StatusCode;
use skein_swarm::payload::PayloadCommandError;

pub use crate::requests::payloads::parse_attach;

/// The HTTP answer for a payload request that got no answer from the payload: 404; 409
/// naming `slot` when the payload (or its vehicle) is not running, a state of the
/// resource, not a fault of the server (failed, disabled, restarting, waiting for a
/// plugin; the message says which); 400 (a plugin's refusal names the field as
/// `"field: message"` by convention); 400 or 409 naming the field.
pub fn payload_error(e: PayloadCommandError) -> ApiError {
    match e {
        PayloadCommandError::NotFound(why) => ApiError::not_found(why),
        PayloadCommandError::Unavailable(why) => ApiError::conflict(why, Some("slot")),
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
        assert_eq!(
            (e.status, e.field.as_deref()),
            (StatusCode::CONFLICT, Some("slot"))
        );
    }
}
