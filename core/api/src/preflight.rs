//! The fleet's pre-flight checks: `GET /api/v1/preflight` (see
//! [`skein_model::preflight`]), from the vehicles' snapshots as `GET /api/v1/vehicles`
//! shows them.

use crate::ApiState;
use crate::error::ApiError;
use axum::Json;
use axum::extract::State;
use serde::Serialize;
use skein_model::preflight::{VehiclePreflight, preflight};

/// Every vehicle's checks.
#[derive(Debug, Serialize, utoipa::ToSchema)]
pub(crate) struct FleetPreflight {
    /// Every vehicle is ready (no check fails); false with no vehicle.
    ready: bool,
    /// Each vehicle's checks, sorted by id.
    vehicles: Vec<VehiclePreflight>,
}

/// The fleet's pre-flight checks
///
/// Per vehicle: its link, its state, PX4's own arming checks (`SYS_STATUS`
/// `PREARM_CHECK`) with PX4's latest warnings, its home, GNSS fix, battery (below PX4's
/// `BAT_LOW_THR` default, 15 %, fails), its autopilot's geofence and, where sent or
/// reported, Remote ID; each `ok`, `warn` or `fail` with what was seen.
#[utoipa::path(get, path = "/api/v1/preflight",
    responses((status = 200, body = FleetPreflight)))]
pub(crate) async fn fleet_preflight(
    State(s): State<ApiState>,
) -> Result<Json<FleetPreflight>, ApiError> {
    let vehicles: Vec<VehiclePreflight> = s.reads.vehicles().iter().map(preflight).collect();
    Ok(Json(FleetPreflight {
        ready: !vehicles.is_empty() && vehicles.iter().all(|v| v.ready),
        vehicles,
    }))
}
