//! Flight recording over the API (operator): `GET /api/v1/recording` (the running
//! recording or `null`), `POST /api/v1/recording/start` (`{"name"?}`: 201 with the file;
//! 409 while one runs; 400 `name`), `POST /api/v1/recording/stop` (the summary: file,
//! messages, channels, bytes, duration; 409 when none runs). See `skein_record` for what
//! a recording holds.

use crate::ApiState;
use crate::error::ApiError;
use crate::requests::recording::RecordingStartRequest;
use axum::Json;
use axum::body::Bytes;
use axum::extract::State;
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use skein_record::RecordError;
use skein_record::recorder::RecordingInfo;
use utoipa::ToSchema;

/// `GET /api/v1/recording`.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct RecordingStatus {
    /// The running recording, `null` when none runs.
    #[schema(value_type = Option<RecordingFile>)]
    pub recording: Option<RecordingInfo>,
}

/// A running recording (schema of `skein_record::recorder::RecordingInfo`).
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct RecordingFile {
    /// The MCAP file.
    pub path: String,
    /// Seconds since it started.
    pub elapsed_s: f64,
}

/// A finished recording (schema of `skein_record::RecordingSummary`).
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct RecordingDone {
    /// The MCAP file.
    pub path: String,
    /// Messages written.
    pub messages: u64,
    /// Channels (topics) written.
    pub channels: usize,
    /// File size, bytes.
    pub bytes: u64,
    /// From the first to the last message, s.
    pub duration_s: f64,
}

fn recorder(s: &ApiState) -> Result<&skein_record::Recorder, ApiError> {
    s.recorder
        .as_deref()
        .ok_or_else(|| ApiError::unavailable("this skein has no recorder"))
}

fn refusal(e: RecordError) -> ApiError {
    match e {
        RecordError::AlreadyRecording(_) | RecordError::NotRecording => {
            ApiError::conflict(e.to_string(), None)
        }
        RecordError::BadName(_) => ApiError::field("name", e.to_string()),
        RecordError::Io(_) => ApiError::status(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()),
    }
}

/// `GET /api/v1/recording`.
pub async fn status(State(s): State<ApiState>) -> Result<Response, ApiError> {
    Ok(Json(RecordingStatus {
        recording: recorder(&s)?.status(),
    })
    .into_response())
}

/// `POST /api/v1/recording/start`.
pub async fn start(State(s): State<ApiState>, body: Bytes) -> Result<Response, ApiError> {
    let req: RecordingStartRequest = crate::requests::parse_or_empty(&body)?;
    let info = recorder(&s)?
        .start(req.name.as_deref(), None)
        .map_err(refusal)?;
    Ok((StatusCode::CREATED, Json(info)).into_response())
}

/// `POST /api/v1/recording/stop`.
pub async fn stop(State(s): State<ApiState>) -> Result<Response, ApiError> {
    let summary = recorder(&s)?.stop().await.map_err(refusal)?;
    Ok(Json(summary).into_response())
}
