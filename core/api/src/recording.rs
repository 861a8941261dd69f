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
use serde::Serialize;
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

/// The running recording, or null
#[utoipa::path(get, path = "/api/v1/recording",
    responses((status = 200, body = RecordingStatus), (status = 503)))]
pub(crate) async fn status(State(s): State<ApiState>) -> Result<Json<RecordingStatus>, ApiError> {
    Ok(Json(RecordingStatus {
        recording: recorder(&s)?.status(),
    }))
}

/// Start recording to MCAP in the recordings directory
#[utoipa::path(post, path = "/api/v1/recording/start",
    request_body = Option<RecordingStartRequest>,
    responses((status = 201, body = RecordingFile), (status = 400), (status = 409),
        (status = 500), (status = 503)))]
pub(crate) async fn start(
    State(s): State<ApiState>,
    body: Bytes,
) -> Result<(StatusCode, Json<RecordingInfo>), ApiError> {
    let req: RecordingStartRequest = crate::requests::parse_or_empty(&body)?;
    let info = recorder(&s)?.start(req.name.as_deref(), None)?;
    Ok((StatusCode::CREATED, Json(info)))
}

/// Stop the recording and finish its file
#[utoipa::path(post, path = "/api/v1/recording/stop",
    responses((status = 200, body = RecordingDone), (status = 409), (status = 500),
        (status = 503)))]
pub(crate) async fn stop(
    State(s): State<ApiState>,
) -> Result<Json<skein_record::RecordingSummary>, ApiError> {
    Ok(Json(recorder(&s)?.stop().await?))
}
