//! API errors: a status code and `{"error": "...", "field": "..."}`
//! ([`crate::responses::ErrorBody`]), and how the errors of the swarm, the plugin host and
//! the recorder become one: each has a `From` impl here, so a handler writes `?` and the
//! status and field of every answer are decided in this one place.

use axum::Json;
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use skein_plugin_host::HostError;
use skein_record::RecordError;
use skein_swarm::FaultError;
use skein_swarm::coordinator::messages::FieldError;
use skein_swarm::coordinator::observe::ObserveRefusal;
use skein_swarm::payload::PayloadCommandError;

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

    /// 404 for a vehicle id the swarm does not have.
    pub fn no_vehicle(id: &str) -> Self {
        ApiError::not_found(format!("no vehicle `{id}`"))
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

/// A formation request or leader motion the coordinator refused: 400 naming the field,
/// except `formation` (a leader motion without a formation to move), which is 409.
impl From<FieldError> for ApiError {
    fn from(e: FieldError) -> Self {
        if e.field == "formation" {
            ApiError::conflict(e.error, Some("formation"))
        } else {
            ApiError::field(&e.field, e.error)
        }
    }
}

/// A payload request with no answer from the payload: 404, 503 (it failed or hung
/// handling the command, or stopped running meanwhile; a payload known not to be running
/// is refused before, see [`crate::payloads::require_running`]), 400 (a plugin's refusal
/// names the field as `"field: message"` by convention), 400 or 409 naming the field.
impl From<PayloadCommandError> for ApiError {
    fn from(e: PayloadCommandError) -> Self {
        match e {
            PayloadCommandError::NotFound(why) => ApiError::not_found(why),
            PayloadCommandError::Unavailable(why) => ApiError::unavailable(why),
            PayloadCommandError::Refused(why) => {
                let field = why
                    .split_once(':')
                    .map(|(f, _)| f.trim())
                    // A field path as the plugins' serde errors give it
                    // (`ground_station.north_m`, `waypoints[2]`).
                    .filter(|f| {
                        !f.is_empty()
                            && f.chars()
                                .all(|c| c.is_ascii_alphanumeric() || "_.[]".contains(c))
                    })
                    .map(str::to_string);
                ApiError {
                    status: StatusCode::BAD_REQUEST,
                    error: why,
                    field,
                }
            }
            PayloadCommandError::Invalid { field, error } => ApiError::field(&field, error),
            PayloadCommandError::Conflict { field, error } => {
                ApiError::conflict(error, Some(&field))
            }
        }
    }
}

/// The plugin host's refusal, with its own status ([`HostError::http_status`]: 404, 409,
/// 403, 422) and the body field it concerns (`name` or `file`).
impl From<HostError> for ApiError {
    fn from(e: HostError) -> Self {
        let field = match e {
            HostError::NotFound { .. } | HostError::InUse { .. } => "name",
            HostError::Load { .. }
            | HostError::NotAPlugin { .. }
            | HostError::Incompatible { .. }
            | HostError::Forbidden { .. }
            | HostError::AlreadyLoaded { .. } => "file",
        };
        ApiError {
            status: StatusCode::from_u16(e.http_status()).unwrap_or(StatusCode::BAD_REQUEST),
            error: e.to_string(),
            field: Some(field.to_string()),
        }
    }
}

/// The recorder's refusal: 409 while one runs or when none does, 400 naming `name`, 500
/// when the file cannot be written.
impl From<RecordError> for ApiError {
    fn from(e: RecordError) -> Self {
        match e {
            RecordError::AlreadyRecording(_) | RecordError::NotRecording => {
                ApiError::conflict(e.to_string(), None)
            }
            RecordError::BadName(_) => ApiError::field("name", e.to_string()),
            RecordError::Io(_) => {
                ApiError::status(StatusCode::INTERNAL_SERVER_ERROR, e.to_string())
            }
        }
    }
}

/// A fault that could not be injected: 403 without `--enable-fault-injection`, 404
/// naming `target` for an unknown actor, 503 for one that did not answer.
impl From<FaultError> for ApiError {
    fn from(e: FaultError) -> Self {
        match e {
            FaultError::Disabled => ApiError::status(
                StatusCode::FORBIDDEN,
                "fault injection is disabled: start skein with --enable-fault-injection",
            ),
            FaultError::UnknownTarget(why) => ApiError {
                status: StatusCode::NOT_FOUND,
                error: why,
                field: Some("target".into()),
            },
            FaultError::Unreachable(why) => ApiError::unavailable(why),
        }
    }
}

/// A track the gimbals cannot observe: 404 for an unknown track, 409 for a lost one
/// (both naming `id`), 400 naming `vehicles` for a vehicle without a gimbal.
impl From<ObserveRefusal> for ApiError {
    fn from(refusal: ObserveRefusal) -> Self {
        let status = match refusal {
            ObserveRefusal::UnknownTarget(_) => StatusCode::NOT_FOUND,
            ObserveRefusal::TrackLost(_) | ObserveRefusal::NoStations(_) => StatusCode::CONFLICT,
            ObserveRefusal::BadVehicle(_) | ObserveRefusal::BadStandoff(_) => {
                StatusCode::BAD_REQUEST
            }
        };
        ApiError {
            status,
            error: refusal.message().to_string(),
            field: Some(refusal.field().to_string()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn status_and_field(e: impl Into<ApiError>) -> (StatusCode, Option<String>) {
        let e = e.into();
        (e.status, e.field)
    }

    #[test]
    fn payload_errors_map_to_statuses_and_fields() {
        let conflict = PayloadCommandError::Conflict {
            field: "slot".into(),
            error: "exists".into(),
        };
        assert_eq!(
            status_and_field(conflict),
            (StatusCode::CONFLICT, Some("slot".into()))
        );
        let invalid = PayloadCommandError::Invalid {
            field: "config".into(),
            error: "lamp config: unknown field `x`".into(),
        };
        assert_eq!(
            status_and_field(invalid),
            (StatusCode::BAD_REQUEST, Some("config".into()))
        );
        let refused = PayloadCommandError::Refused("on: must be a boolean".into());
        assert_eq!(status_and_field(refused).1.as_deref(), Some("on"));
        let nested = PayloadCommandError::Refused("ground_station.north_m: expected f64".into());
        assert_eq!(
            status_and_field(nested).1.as_deref(),
            Some("ground_station.north_m")
        );
        let prose = PayloadCommandError::Refused("the gimbal says: no".into());
        assert_eq!(status_and_field(prose).1, None);
        let waiting = PayloadCommandError::Unavailable("waiting".into());
        assert_eq!(status_and_field(waiting).0, StatusCode::SERVICE_UNAVAILABLE);
    }

    #[test]
    fn host_errors_map_to_statuses_and_fields() {
        let e = ApiError::from(HostError::InUse {
            name: "gimbal".into(),
            instances: vec!["uav-2/gimbal".into()],
        });
        assert_eq!(e.status, StatusCode::CONFLICT);
        assert_eq!(e.field.as_deref(), Some("name"));
        assert!(e.error.contains("uav-2/gimbal"), "{}", e.error);
        let e = ApiError::from(HostError::Incompatible {
            file: "/p/libx.so".into(),
            difference: "ABI version mismatch: 999 vs 1".into(),
        });
        assert_eq!(e.status, StatusCode::UNPROCESSABLE_ENTITY);
        assert_eq!(e.field.as_deref(), Some("file"));
        assert!(e.error.contains("/p/libx.so") && e.error.contains("ABI"));
        let e = ApiError::from(HostError::Forbidden {
            file: "/etc/x.so".into(),
            reason: "outside".into(),
        });
        assert_eq!(e.status, StatusCode::FORBIDDEN);
        assert_eq!(e.field.as_deref(), Some("file"));
    }

    #[test]
    fn a_leader_motion_without_a_formation_is_a_conflict_other_refusals_name_the_field() {
        let refusal = |field: &str| FieldError {
            field: field.into(),
            error: "no".into(),
        };
        assert_eq!(
            status_and_field(refusal("formation")),
            (StatusCode::CONFLICT, Some("formation".into()))
        );
        assert_eq!(
            status_and_field(refusal("speed_m_s")),
            (StatusCode::BAD_REQUEST, Some("speed_m_s".into()))
        );
    }

    #[test]
    fn fault_recording_and_observe_refusals_keep_their_statuses() {
        assert_eq!(
            status_and_field(FaultError::Disabled).0,
            StatusCode::FORBIDDEN
        );
        assert_eq!(
            status_and_field(FaultError::UnknownTarget("x".into())),
            (StatusCode::NOT_FOUND, Some("target".into()))
        );
        assert_eq!(
            status_and_field(RecordError::NotRecording).0,
            StatusCode::CONFLICT
        );
        assert_eq!(
            status_and_field(RecordError::BadName("..".into())),
            (StatusCode::BAD_REQUEST, Some("name".into()))
        );
        assert_eq!(
            status_and_field(ObserveRefusal::TrackLost("track-1 is lost".into())),
            (StatusCode::CONFLICT, Some("id".into()))
        );
    }
}
