//! How far a vehicle's autopilot holds skein's geofence: what skein uploaded through the
//! MAVLink mission protocol (`MAV_MISSION_TYPE_FENCE` and `MAV_MISSION_TYPE_RALLY`), read
//! back and compared, and whether the vehicle is outside the fence now. Shown per vehicle
//! as `fence` in `GET /api/v1/vehicles`.

use serde::{Deserialize, Serialize};

/// Where a vehicle's copy of the fence stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum FenceSyncState {
    /// Not uploaded yet (no link, no swarm origin, or an upload in progress).
    Pending,
    /// Uploaded, read back equal, `GF_ACTION` (and `GF_MAX_VER_DIST`) set.
    Synced,
    /// Uploaded, but what the vehicle returns is not what was sent.
    Differs,
    /// The upload, the read-back or a parameter failed (`reason` says which and why).
    Failed,
}

impl FenceSyncState {
    /// The API name (`"synced"`).
    pub fn name(self) -> &'static str {
        match self {
            FenceSyncState::Pending => "pending",
            FenceSyncState::Synced => "synced",
            FenceSyncState::Differs => "differs",
            FenceSyncState::Failed => "failed",
        }
    }
}

/// One vehicle's fence: its autopilot's copy, and skein's own breach check.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct FenceStatus {
    /// Where the autopilot's copy stands.
    pub state: FenceSyncState,
    /// Why it differs or failed (`"uav-2 refused the fence upload: MAV_MISSION_NO_SPACE"`),
    /// or what it waits for while pending.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// Version of skein's fence this is about (1 = the configured fence; each accepted
    /// `PUT /api/v1/geofence` adds one).
    pub version: u64,
    /// Fence mission items the vehicle holds (a polygon's vertices count one each).
    pub fence_items: usize,
    /// Rally points the vehicle holds.
    pub rally_items: usize,
    /// True while the vehicle, airborne, is outside skein's fence.
    #[serde(default)]
    pub breached: bool,
}

impl FenceStatus {
    /// Nothing uploaded yet, for fence `version`, waiting for `why`.
    pub fn pending(version: u64, why: impl Into<String>) -> Self {
        FenceStatus {
            state: FenceSyncState::Pending,
            reason: Some(why.into()),
            version,
            fence_items: 0,
            rally_items: 0,
            breached: false,
        }
    }
}
