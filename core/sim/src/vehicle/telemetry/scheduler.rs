//! The telemetry rate scheduler: PX4's onboard stream table with the default rates of both
//! profiles (px4.md), per-vehicle intervals that `MAV_CMD_SET_MESSAGE_INTERVAL` (511) changes
//! at run time, and the emission of every stream that is due.

#![allow(deprecated)]

use super::{AUTOPILOT_VERSION_ID, COMPONENT_METADATA_ID, HOME_POSITION_ID, PROTOCOL_VERSION_ID};
use crate::config::TelemetryProfile;
use crate::vehicle::{Outbox, Vehicle};
use skein_mavlink::MavMessage;
use skein_mavlink::dialect::*;
use std::time::{Duration, Instant};

/// A frame is sent at most this early before its due time (absorbs tick jitter).
const EARLY_TOLERANCE: Duration = Duration::from_millis(2);

/// Every message the simulator streams.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stream {
    Heartbeat,
    Attitude,
    HighresImu,
    AttitudeQuaternion,
    GlobalPositionInt,
    LocalPositionNed,
    Odometry,
    Timesync,
    Altitude,
    DistanceSensor,
    AttitudeTarget,
    PositionTargetLocalNed,
    ServoOutputRaw,
    VfrHud,
    GpsRawInt,
    ExtendedSysState,
    SysStatus,
    EstimatorStatus,
    Ping,
    SystemTime,
    ScaledPressure,
    MissionCurrent,
    LinkNodeStatus,
    BatteryStatus,
    CurrentMode,
    HomePosition,
    Vibration,
}

/// `(stream, message id, name, PX4 onboard rate Hz, swarm-profile rate Hz)`: the px4.md
/// table.
pub const STREAMS: [(Stream, u32, &str, f64, f64); 27] = [
    (Stream::Heartbeat, 0, "HEARTBEAT", 1.0, 1.0),
    (Stream::Attitude, 30, "ATTITUDE", 100.0, 5.0),
    (Stream::HighresImu, 105, "HIGHRES_IMU", 50.0, 0.0),
    (
        Stream::AttitudeQuaternion,
        31,
        "ATTITUDE_QUATERNION",
        50.0,
        0.0,
    ),
    (
        Stream::GlobalPositionInt,
        33,
        "GLOBAL_POSITION_INT",
        50.0,
        10.0,
    ),
    (
        Stream::LocalPositionNed,
        32,
        "LOCAL_POSITION_NED",
        30.0,
        10.0,
    ),
    (Stream::Odometry, 331, "ODOMETRY", 30.0, 0.0),
    (Stream::Timesync, 111, "TIMESYNC", 10.0, 0.0),
    (Stream::Altitude, 141, "ALTITUDE", 10.0, 0.0),
    (Stream::DistanceSensor, 132, "DISTANCE_SENSOR", 10.0, 0.0),
    (Stream::AttitudeTarget, 83, "ATTITUDE_TARGET", 10.0, 0.0),
    (
        Stream::PositionTargetLocalNed,
        85,
        "POSITION_TARGET_LOCAL_NED",
        10.0,
        0.0,
    ),
    (Stream::ServoOutputRaw, 36, "SERVO_OUTPUT_RAW", 10.0, 0.0),
    (Stream::VfrHud, 74, "VFR_HUD", 10.0, 0.0),
    (Stream::GpsRawInt, 24, "GPS_RAW_INT", 8.0, 1.0),
    (
        Stream::ExtendedSysState,
        245,
        "EXTENDED_SYS_STATE",
        5.0,
        1.0,
    ),
    (Stream::SysStatus, 1, "SYS_STATUS", 5.0, 1.0),
    (Stream::EstimatorStatus, 230, "ESTIMATOR_STATUS", 1.0, 0.0),
    (Stream::Ping, 4, "PING", 1.0, 0.0),
    (Stream::SystemTime, 2, "SYSTEM_TIME", 1.0, 0.0),
    (Stream::ScaledPressure, 29, "SCALED_PRESSURE", 1.0, 0.0),
    (Stream::MissionCurrent, 42, "MISSION_CURRENT", 1.0, 0.0),
    (Stream::LinkNodeStatus, 8, "LINK_NODE_STATUS", 1.0, 0.0),
    (Stream::BatteryStatus, 147, "BATTERY_STATUS", 0.5, 0.5),
    (Stream::CurrentMode, 436, "CURRENT_MODE", 0.5, 0.0),
    (Stream::HomePosition, 242, "HOME_POSITION", 0.5, 0.5),
    (Stream::Vibration, 241, "VIBRATION", 0.5, 0.0),
];

/// True for messages the simulator can send (streamed or on request).
pub fn is_known_message(id: u32) -> bool {
    stream_index(id).is_some()
        || matches!(
            id,
            AUTOPILOT_VERSION_ID | PROTOCOL_VERSION_ID | COMPONENT_METADATA_ID
        )
}

fn stream_index(id: u32) -> Option<usize> {
    STREAMS.iter().position(|s| s.1 == id)
}

fn interval_us_for(hz: f64) -> i64 {
    if hz > 0.0 {
        (1e6 / hz).round() as i64
    } else {
        -1
    }
}

#[derive(Debug, Clone, Copy)]
struct StreamState {
    /// Microseconds between frames; <= 0 disabled.
    interval_us: i64,
    default_us: i64,
    next_due: Instant,
}

/// Per-vehicle stream scheduler.
#[derive(Debug, Clone)]
pub struct Streams {
    states: [StreamState; STREAMS.len()],
}

impl Streams {
    /// Default rates of `profile`, every stream due at `now`.
    pub fn new(profile: TelemetryProfile, now: Instant) -> Streams {
        let mut states = [StreamState {
            interval_us: -1,
            default_us: -1,
            next_due: now,
        }; STREAMS.len()];
        for (state, (_, _, _, px4_hz, swarm_hz)) in states.iter_mut().zip(STREAMS.iter()) {
            let hz = match profile {
                TelemetryProfile::Px4Onboard => *px4_hz,
                TelemetryProfile::Swarm => *swarm_hz,
            };
            state.default_us = interval_us_for(hz);
            state.interval_us = state.default_us;
        }
        Streams { states }
    }

    /// `MAV_CMD_SET_MESSAGE_INTERVAL`: `interval_us` > 0 sets, 0 restores the default,
    /// -1 disables. False for messages that cannot be streamed.
    pub fn set_interval(&mut self, message_id: u32, interval_us: f32, now: Instant) -> bool {
        let Some(i) = stream_index(message_id) else {
            return false;
        };
        if !interval_us.is_finite() {
            return false;
        }
        let s = &mut self.states[i];
        s.interval_us = if interval_us > 0.0 {
            interval_us.round() as i64
        } else if interval_us == 0.0 {
            s.default_us
        } else {
            -1
        };
        s.next_due = now;
        true
    }

    /// The interval reported by `MESSAGE_INTERVAL`: > 0 µs, -1 disabled, 0 unknown.
    pub fn interval_report_us(&self, message_id: u32) -> i32 {
        match stream_index(message_id) {
            Some(i) => {
                let us = self.states[i].interval_us;
                if us > 0 { us as i32 } else { -1 }
            }
            None => 0,
        }
    }

    /// Makes a stream due right now (PX4 sends HOME_POSITION at once when home changes).
    pub fn force(&mut self, stream: Stream, now: Instant) {
        if let Some(i) = STREAMS.iter().position(|s| s.0 == stream) {
            self.states[i].next_due = now;
        }
    }
}

impl Vehicle {
    /// Emits every stream due at `now` into `out`.
    pub(crate) fn emit_due_streams(&mut self, now: Instant, out: &mut Outbox) {
        for (i, &(stream, ..)) in STREAMS.iter().enumerate() {
            let st = self.streams.states[i];
            if st.interval_us <= 0 || now + EARLY_TOLERANCE < st.next_due {
                continue;
            }
            self.build_stream(stream, now, out);
            let interval = Duration::from_micros(st.interval_us as u64);
            let mut next = st.next_due + interval;
            if next + interval < now {
                next = now; // far behind (stalled runtime): do not burst
            }
            self.streams.states[i].next_due = next;
        }
    }

    /// True when message `id` can be sent now (on request).
    pub(crate) fn can_send_message(&self, now: Instant, id: u32) -> bool {
        match id {
            AUTOPILOT_VERSION_ID | PROTOCOL_VERSION_ID | COMPONENT_METADATA_ID => true,
            HOME_POSITION_ID => self.has_fix,
            33 => self.ekf_ok(now),
            _ => stream_index(id).is_some(),
        }
    }

    /// Sends message `id` once (MAV_CMD_REQUEST_MESSAGE).
    pub(crate) fn send_message_now(&mut self, now: Instant, id: u32, out: &mut Outbox) {
        match id {
            AUTOPILOT_VERSION_ID => out.push(&self.autopilot_version()),
            COMPONENT_METADATA_ID => out.push(&self.component_metadata(now)),
            PROTOCOL_VERSION_ID => out.push(&MavMessage::PROTOCOL_VERSION(PROTOCOL_VERSION_DATA {
                version: 200,
                min_version: 100,
                max_version: 200,
                spec_version_hash: [0; 8],
                library_version_hash: [0; 8],
            })),
            _ => {
                if let Some(i) = stream_index(id) {
                    self.build_stream(STREAMS[i].0, now, out);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vehicle::telemetry::PX4_FLIGHT_SW_VERSION;

    #[test]
    fn every_stream_has_a_distinct_id_and_known_rate() {
        for (i, a) in STREAMS.iter().enumerate() {
            for b in &STREAMS[i + 1..] {
                assert_ne!(a.1, b.1);
            }
            assert!(a.3 > 0.0);
        }
        assert_eq!(PX4_FLIGHT_SW_VERSION, 0x0110_00FF);
    }

    #[test]
    fn interval_changes() {
        let now = Instant::now();
        let mut s = Streams::new(TelemetryProfile::Px4Onboard, now);
        assert_eq!(s.interval_report_us(30), 10_000);
        assert!(s.set_interval(30, 200_000.0, now));
        assert_eq!(s.interval_report_us(30), 200_000);
        assert!(s.set_interval(30, -1.0, now));
        assert_eq!(s.interval_report_us(30), -1);
        assert!(s.set_interval(30, 0.0, now));
        assert_eq!(s.interval_report_us(30), 10_000);
        assert!(!s.set_interval(9999, 1000.0, now));
    }
}
