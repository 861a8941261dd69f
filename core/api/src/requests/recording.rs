//! `POST /api/v1/recording/start`.

use serde::Deserialize;
use utoipa::ToSchema;

/// Where to record (an empty body: a name from the time).
#[derive(Debug, Clone, PartialEq, Default, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct RecordingStartRequest {
    /// File name without extension, in the recordings directory (`[recording] dir`):
    /// 1–64 of letters, digits, `_`, `-`, `.`, not starting with `.`. Default
    /// `skein-<unix seconds>`.
    #[schema(pattern = "^[A-Za-z0-9_-][A-Za-z0-9_.-]{0,63}$")]
    pub name: Option<String>,
}
