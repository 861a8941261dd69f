//! What `GET /api/v1/rtk` shows: the corrections source's state and throughput, the
//! message types and base station seen, what each vehicle was sent and its fix, and the
//! relay between processes ([`crate::relay::RelayStatus`]).

use serde::{Deserialize, Serialize};
use skein_model::geo::GeoPoint;
use std::collections::BTreeMap;

/// Where the corrections source stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum SourceState {
    /// No source configured: nothing is sent.
    Idle,
    /// Opening the connection (or the port), or waiting for the first RTCM frame.
    Connecting,
    /// RTCM frames arriving and being sent to the vehicles.
    Streaming,
    /// Connected, but no RTCM frame for the stall timeout; reconnecting (`error` says
    /// how long).
    Stalled,
    /// The connection failed or was refused; reconnecting with backoff (`error` says why).
    Failed,
}

/// The reference station in the stream (RTCM 1005 / 1006).
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct BaseStatus {
    /// Reference station id (DF003).
    pub station_id: u16,
    /// Antenna reference point, WGS84 (the altitude is the ellipsoid height, metres).
    pub position: GeoPoint,
    /// Seconds since the last 1005 / 1006 with it.
    pub age_s: f64,
}

/// Corrections sent to one vehicle, and its fix.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct VehicleCorrections {
    /// Vehicle id.
    pub id: String,
    /// RTCM messages sent (as `GPS_RTCM_DATA`).
    pub messages: u64,
    /// RTCM bytes sent.
    pub bytes: u64,
    /// Messages dropped whole to keep the vehicle's rate cap.
    pub dropped_over_cap: u64,
    /// Messages the link could not send (no route yet, full queue).
    pub dropped_send: u64,
    /// Seconds since the last message went to it; `null` before the first.
    pub correction_age_s: Option<f64>,
    /// The vehicle's `GPS_RAW_INT.fix_type` (5 RTK float, 6 RTK fixed); `null` before one.
    pub fix_type: Option<u8>,
}

/// The corrections service's state (`GET /api/v1/rtk`).
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct RtkStatus {
    /// The source, its password shown as `***`; `null` when none is configured.
    pub source: Option<String>,
    /// Where the source stands.
    pub state: SourceState,
    /// Why it failed or stalled (the last error while reconnecting).
    pub error: Option<String>,
    /// Seconds in the current state.
    pub state_age_s: f64,
    /// Connections opened to this source (the first included).
    pub connects: u64,
    /// Bytes received from the source.
    pub bytes_total: u64,
    /// Bytes received per second over the last 5 s.
    pub bytes_per_s: f64,
    /// Good RTCM3 frames.
    pub frames: u64,
    /// Candidate frames whose CRC-24Q failed (dropped).
    pub crc_failures: u64,
    /// Bytes that were not part of a frame (dropped).
    pub garbage_bytes: u64,
    /// Frames over 720 bytes, which `GPS_RTCM_DATA` cannot carry (dropped).
    pub too_large: u64,
    /// Good frames by RTCM message number (`"1005"`, `"1077"`, ...).
    pub message_types: BTreeMap<String, u64>,
    /// Seconds since the last good frame; `null` before the first.
    pub last_frame_age_s: Option<f64>,
    /// The reference station, once a 1005 / 1006 arrived.
    pub base: Option<BaseStatus>,
    /// Where skein last told an NTRIP caster the fleet is (NMEA `GGA`, for network RTK);
    /// `null` when it did not.
    pub gga_position: Option<GeoPoint>,
    /// The rate cap of corrections to each vehicle, bytes/s (MAVLink framing included).
    pub max_bytes_s: f64,
    /// Seconds without a frame after which the source is stalled and reconnected.
    pub stall_timeout_s: f64,
    /// What each vehicle of this process was sent.
    pub vehicles: Vec<VehicleCorrections>,
    /// The relay of corrections between the processes of a distributed swarm: what this
    /// process does with `/skein/rtcm` and what it counted; `null` without DDS.
    pub relay: Option<crate::relay::RelayStatus>,
}
