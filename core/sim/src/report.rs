//! What the simulator reports: its telemetry table, each vehicle's ground truth
//! ([`SimTruth`]), per-vehicle counters ([`SimVehicleStats`]) and the run's summary
//! ([`SimSummary`]), as the stats socket and `GET /api/v1/sim/truth` serve them.

use crate::histogram::{IntervalBucket, IntervalSummary};
use crate::vehicle::Vehicle;
use crate::vehicle::gnss::{GnssTruth, RtcmCounts};
use crate::vehicle::telemetry;
use serde::Serialize;
use skein_mavlink::DecodeCounts;
use skein_model::geo::{GeoPoint, Ned};
use skein_model::px4::{LandedState, Px4Mode};
use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::time::Instant;

/// One message of the telemetry table: id, name and default rates.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TelemetryStreamInfo {
    /// MAVLink message id.
    pub message_id: u32,
    /// MAVLink message name.
    pub name: &'static str,
    /// Default rate in the [`TelemetryProfile::Px4Onboard`] profile, Hz.
    pub px4_rate_hz: f64,
    /// Default rate in the [`TelemetryProfile::Swarm`] profile, Hz (0 = not sent).
    pub swarm_rate_hz: f64,
}

/// The telemetry the simulator streams (px4.md's table) with the default rates of both
/// profiles.
pub fn telemetry_streams() -> Vec<TelemetryStreamInfo> {
    telemetry::STREAMS
        .iter()
        .map(
            |&(_, message_id, name, px4_rate_hz, swarm_rate_hz)| TelemetryStreamInfo {
                message_id,
                name,
                px4_rate_hz,
                swarm_rate_hz,
            },
        )
        .collect()
}

/// A vehicle's identity and actual endpoints.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct SimVehicleInfo {
    /// MAVLink system id.
    pub sysid: u8,
    /// Address the vehicle's socket is bound to (the real port when 0 was asked).
    pub bound: SocketAddr,
    /// Address it sends to until a client has talked to it.
    pub target: SocketAddr,
}

/// Ground truth of one vehicle.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SimTruth {
    /// MAVLink system id.
    pub sysid: u8,
    /// True geodetic position.
    pub position: GeoPoint,
    /// True position in the vehicle's own local NED frame (origin at its spawn point), m.
    pub local_ned_m: Ned,
    /// True velocity, NED, m/s.
    pub velocity_ned_m_s: Ned,
    /// Heading, degrees in [0, 360).
    pub heading_deg: f64,
    /// Armed.
    pub armed: bool,
    /// PX4 mode.
    pub mode: Px4Mode,
    /// PX4 mode name (`"HOLD"`, `"OFFBOARD"` …).
    pub mode_name: &'static str,
    /// `HEARTBEAT.custom_mode`.
    pub custom_mode: u32,
    /// Landed state as reported in EXTENDED_SYS_STATE.
    pub landed_state: LandedState,
    /// A failsafe picked the current mode.
    pub failsafe: bool,
    /// Battery remaining, percent.
    pub battery_percent: f64,
    /// Battery voltage, V.
    pub battery_voltage_v: f64,
    /// Home position (set where the vehicle armed, or at its first fix).
    pub home: GeoPoint,
    /// Geodetic origin of the vehicle's local NED frame (its spawn point).
    pub local_origin: GeoPoint,
    /// Seconds since the vehicle (re)booted.
    pub uptime_s: f64,
    /// The GNSS receiver: fix type, corrections' age, position error.
    pub gnss: GnssTruth,
}

/// Counters of one vehicle (since start or the last [`Simulator::reset_stats`]) and its
/// ground truth.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SimVehicleStats {
    /// MAVLink system id.
    pub sysid: u8,
    /// Bound socket address.
    pub bound: SocketAddr,
    /// Configured target address.
    pub target: SocketAddr,
    /// The client address the vehicle locked onto, if any.
    pub peer: Option<SocketAddr>,
    /// Link currently cut by [`Simulator::set_silent`] / `silence`.
    pub silent: bool,
    /// Removed by [`Simulator::kill`].
    pub killed: bool,
    /// SET_POSITION_TARGET_* messages accepted.
    pub setpoints_received: u64,
    /// Largest gap between two consecutive setpoints, ms.
    pub setpoint_max_gap_ms: f64,
    /// Largest gap between two consecutive setpoints while in OFFBOARD, ms.
    pub setpoint_max_gap_offboard_ms: f64,
    /// Intervals between consecutive setpoints as received (after the simulated link),
    /// ms: count, mean, p50/p99/p99.9 (bucket upper edges) and exact max.
    pub setpoint_intervals: IntervalSummary,
    /// Offboard-loss failsafes taken (COM_OF_LOSS_T expired in OFFBOARD).
    pub offboard_loss_failsafes: u64,
    /// GCS-link-loss failsafes taken (NAV_DLL_ACT).
    pub gcs_loss_failsafes: u64,
    /// Geofence breaches that took `GF_ACTION`.
    pub geofence_breaches: u64,
    /// Fence mission items stored (`MAV_MISSION_TYPE_FENCE`).
    pub fence_items: usize,
    /// Rally points stored (`MAV_MISSION_TYPE_RALLY`).
    pub rally_items: usize,
    /// COMMAND_LONG / COMMAND_INT addressed to the vehicle.
    pub commands_received: u64,
    /// Valid MAVLink frames received.
    pub frames_received: u64,
    /// Malformed input dropped (bad CRC, unknown message, parse errors, truncation,
    /// datagrams without a valid frame).
    pub malformed_frames: u64,
    /// Datagrams received (not counting those dropped while silent).
    pub datagrams_received: u64,
    /// Datagrams dropped because the link was cut.
    pub datagrams_dropped_silent: u64,
    /// Configured loss fraction of the simulated link (0..=1, each direction), see
    /// [`Simulator::set_link_quality`].
    pub link_loss_fraction: f64,
    /// Configured one-way latency of the simulated link, ms (each direction).
    pub link_latency_ms: f64,
    /// Datagrams the simulated link dropped, both directions.
    pub datagrams_dropped_link: u64,
    /// Of those, datagrams to the vehicle.
    pub datagrams_dropped_link_inbound: u64,
    /// Measured loss: datagrams dropped by the simulated link / datagrams that crossed
    /// it, both directions (0 before any traffic).
    pub link_loss_effective: f64,
    /// Measured mean one-way delay of the datagrams the simulated link delayed, ms (0
    /// before any).
    pub link_latency_effective_ms: f64,
    /// Datagrams waiting in the simulated link's delay lines now.
    pub link_in_flight: usize,
    /// Datagrams sent.
    pub datagrams_sent: u64,
    /// MAVLink frames sent.
    pub frames_sent: u64,
    /// Bytes sent.
    pub bytes_sent: u64,
    /// Datagrams dropped because the socket buffer was full.
    pub send_drops: u64,
    /// Texts sent as STATUSTEXT (a text longer than 50 characters is several frames).
    pub statustexts_sent: u64,
    /// STATUSTEXTs not sent because no GCS heartbeat arrived in the last 2.5 s.
    pub statustexts_suppressed: u64,
    /// The RTK corrections' path to the GNSS receiver: GPS_RTCM_DATA accepted, malformed
    /// and lost in PX4's inject queue, RTCM3 frames good, with observations, with a base
    /// position, failing their CRC, garbage bytes.
    pub rtcm: RtcmCounts,
    /// A GCS heartbeat arrived in the last 1.5 s.
    pub gcs_connected: bool,
    /// MAVLink 2 signing: frames accepted signed, dropped (unsigned, bad signature,
    /// replayed, too old) and sent signed.
    pub signing: skein_mavlink::signing::SigningCounts,
    /// A signing key is installed (from the configuration or `SETUP_SIGNING`).
    pub signing_key_installed: bool,
    /// An onboard-controller heartbeat arrived in the last 1.5 s.
    pub onboard_controller_connected: bool,
    /// Detailed decoder counters.
    pub decode: DecodeCounts,
    /// Ground truth.
    pub truth: SimTruth,
}

/// Totals over every vehicle, see [`Simulator::summary`].
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct SimSummary {
    /// Vehicles simulated.
    pub vehicles: usize,
    /// Vehicles removed by [`Simulator::kill`].
    pub killed: usize,
    /// Vehicles armed now.
    pub armed: usize,
    /// Vehicles per PX4 mode name now (`{"OFFBOARD": 1000}`).
    pub modes: BTreeMap<&'static str, usize>,
    /// Vehicles that heard a GCS heartbeat in the last 1.5 s.
    pub gcs_connected: usize,
    /// SET_POSITION_TARGET_* messages accepted.
    pub setpoints_received: u64,
    /// Valid MAVLink frames received.
    pub frames_received: u64,
    /// COMMAND_LONG / COMMAND_INT received.
    pub commands_received: u64,
    /// Offboard-loss failsafes taken.
    pub offboard_loss_failsafes: u64,
    /// GCS-link-loss failsafes taken.
    pub gcs_loss_failsafes: u64,
    /// Geofence breaches that took `GF_ACTION`.
    pub geofence_breaches: u64,
    /// The RTK corrections of every vehicle together.
    pub rtcm: RtcmCounts,
    /// Malformed input dropped.
    pub malformed_frames: u64,
    /// Datagrams received.
    pub datagrams_received: u64,
    /// Datagrams sent.
    pub datagrams_sent: u64,
    /// Datagrams dropped because a socket buffer was full.
    pub send_drops: u64,
    /// Datagrams the simulated links dropped.
    pub datagrams_dropped_link: u64,
    /// Intervals between consecutive setpoints of each vehicle, all vehicles together, ms.
    pub setpoint_intervals: IntervalSummary,
    /// The non-empty buckets of that histogram (0.1 ms wide below 100 ms, 1 ms wide up to
    /// 1 s, then one overflow bucket ending at the maximum).
    pub setpoint_interval_buckets: Vec<IntervalBucket>,
}

pub(crate) fn decode_delta(now: DecodeCounts, base: DecodeCounts) -> DecodeCounts {
    DecodeCounts {
        frames_ok: now.frames_ok - base.frames_ok,
        mavlink1_frames: now.mavlink1_frames - base.mavlink1_frames,
        bad_crc: now.bad_crc - base.bad_crc,
        unknown_message: now.unknown_message - base.unknown_message,
        parse_errors: now.parse_errors - base.parse_errors,
        truncated: now.truncated - base.truncated,
        bad_flags: now.bad_flags - base.bad_flags,
        garbage_bytes: now.garbage_bytes - base.garbage_bytes,
        datagrams: now.datagrams - base.datagrams,
        rejected_datagrams: now.rejected_datagrams - base.rejected_datagrams,
    }
}

pub(crate) fn truth_of(v: &Vehicle, now: Instant) -> SimTruth {
    SimTruth {
        sysid: v.sysid,
        position: v.geo_of(v.pos),
        local_ned_m: v.pos,
        velocity_ned_m_s: v.vel,
        heading_deg: skein_model::geo::wrap_deg_360(v.yaw_rad.to_degrees()),
        armed: v.armed,
        mode: v.mode,
        mode_name: v.mode.name(),
        custom_mode: v.mode.custom_mode(),
        landed_state: v.landed_state(),
        failsafe: v.failsafe,
        battery_percent: v.battery.remaining * 100.0,
        battery_voltage_v: v.battery.voltage_v,
        home: v.home,
        local_origin: v.origin.origin,
        uptime_s: now.saturating_duration_since(v.boot).as_secs_f64(),
        gnss: gnss_truth(v, now),
    }
}

/// The receiver's fix type as GPS_RAW_INT reports it now, the corrections' age and the
/// receiver's error.
fn gnss_truth(v: &Vehicle, now: Instant) -> GnssTruth {
    let fix_type = if v.ekf_ok(now) {
        v.gnss.fix().fix_type()
    } else {
        skein_mavlink::dialect::GpsFixType::GPS_FIX_TYPE_NO_FIX
    };
    let e = v.gnss.error();
    GnssTruth {
        fix_type: fix_type as u8,
        corrections_age_s: v.gnss.corrections_age(now).map(|d| d.as_secs_f64()),
        error_ned_m: [e.north_m, e.east_m, e.down_m],
    }
}
