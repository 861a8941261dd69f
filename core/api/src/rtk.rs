//! RTK corrections over the API: `GET /api/v1/rtk` (the source's state, throughput,
//! message types, base station, and what each vehicle of this process was sent), `PUT
//! /api/v1/rtk` (`{"source", "max_bytes_s"?, "stall_timeout_s"?, "send_gga"?}`: use this
//! source from now on; 400 naming the field), `DELETE /api/v1/rtk` (stop sending
//! corrections). See `skein_rtk` for the sources and what is sent.

use crate::ApiState;
use crate::error::ApiError;
use axum::Json;
use axum::body::Bytes;
use axum::extract::State;
use skein_rtk::{RtkConfig, RtkService, RtkStatus};
use std::sync::Arc;

fn service(s: &ApiState) -> Result<&Arc<RtkService>, ApiError> {
    s.rtk
        .as_ref()
        .ok_or_else(|| ApiError::unavailable("this process sends no RTK corrections"))
}

/// RTK corrections: the source and what was sent
///
/// The corrections source's state (`idle`, `connecting`, `streaming`, `stalled`,
/// `failed` with `error`), bytes per second, RTCM message types, CRC failures, the base
/// station (RTCM 1005/1006) and its age, and per vehicle of this process the messages
/// sent (`GPS_RTCM_DATA`), those dropped to keep the rate cap, the corrections' age and
/// the vehicle's fix (`GPS_RAW_INT.fix_type`: 5 RTK float, 6 RTK fixed).
#[utoipa::path(get, path = "/api/v1/rtk",
    responses((status = 200, body = RtkStatus), (status = 503)))]
pub(crate) async fn status(State(s): State<ApiState>) -> Result<Json<RtkStatus>, ApiError> {
    Ok(Json(service(&s)?.status()))
}

/// Set the RTK corrections source
///
/// `source`: `ntrip://[USER[:PASSWORD]@]HOST[:PORT]/MOUNTPOINT[?version=1]` (an NTRIP
/// caster), `tcp://HOST:PORT`, `udp://[ADDRESS]:PORT` or `serial:DEVICE:BAUD`; the
/// password is never shown again. Answers the status, `connecting`: the connection is
/// made (and remade, with backoff) in the background. 400 naming `source`,
/// `max_bytes_s` or `stall_timeout_s`; the current source is then kept.
#[utoipa::path(put, path = "/api/v1/rtk", request_body = RtkConfig,
    responses((status = 200, body = RtkStatus), (status = 400), (status = 503)))]
pub(crate) async fn put(
    State(s): State<ApiState>,
    body: Bytes,
) -> Result<Json<RtkStatus>, ApiError> {
    let rtk = service(&s)?;
    let config: RtkConfig = crate::requests::parse(&body)?;
    rtk.configure(Some(&config))
        .map_err(|e| ApiError::field(e.field, e.error))?;
    Ok(Json(rtk.status()))
}

/// Stop sending RTK corrections
///
/// Closes the source; the vehicles' receivers fall back from RTK as their corrections
/// age. Answers the status, `idle`.
#[utoipa::path(delete, path = "/api/v1/rtk",
    responses((status = 200, body = RtkStatus), (status = 503)))]
pub(crate) async fn delete(State(s): State<ApiState>) -> Result<Json<RtkStatus>, ApiError> {
    let rtk = service(&s)?;
    rtk.configure(None)
        .map_err(|e| ApiError::field(e.field, e.error))?;
    Ok(Json(rtk.status()))
}
