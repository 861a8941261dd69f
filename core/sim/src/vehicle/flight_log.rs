//! The flight log (PX4's `logger` with its default `SDLOG_MODE` 0): one ULog per armed
//! flight, from arming to disarming, kept in the vehicle's memory as on PX4's SD card
//! (a reboot keeps them) and served over MAVLink by `log_handler`.
//!
//! Logged, with PX4 v1.16's topic and field names and types (`msg/*.msg`), on the
//! vehicle's boot clock (the clock of `time_boot_ms`), in µs:
//! - `vehicle_local_position` at 20 Hz: the estimate LOCAL_POSITION_NED reports (local
//!   NED of the vehicle's origin, m, m/s), its acceleration (m/s²) and heading (rad);
//! - `vehicle_attitude` at 20 Hz: the attitude quaternion (w, x, y, z, body FRD to NED);
//! - `vehicle_local_position_setpoint` at 10 Hz: the position controller's setpoints
//!   (POSITION_TARGET_LOCAL_NED's).
//!
//! Samples are taken on the simulation step once their interval has passed, so on a
//! 100 Hz step the rates are exact and on the swarm profile's 50 Hz step they are
//! exact on average. Storage is bounded: the newest [`FLIGHT_LOGS_KEPT`] logs, at most
//! [`FLIGHT_LOG_STORAGE_BYTES`] in all (the oldest logs go first; a flight that fills the
//! storage alone stops growing, as PX4's logger stops on a full card).

use super::*;
use crate::ulog::{self, Field, FieldType::*, Format, Sample};
use std::collections::VecDeque;
use std::sync::Arc;
use std::time::{SystemTime, UNIX_EPOCH};

/// Logs a vehicle keeps: the newest ones, the one being written included.
pub const FLIGHT_LOGS_KEPT: usize = 10;
/// Bytes all of a vehicle's logs may take together (about 25 minutes of flight at the
/// rates above; 1000 simulated vehicles take at most 4 GiB).
pub const FLIGHT_LOG_STORAGE_BYTES: usize = 4 << 20;
/// `ver_sw` of the log: PX4's git hash, here "skeinsim" in hex, the 8 bytes
/// AUTOPILOT_VERSION reports as `flight_custom_version`.
const VER_SW: &str = "736b65696e73696d000000000000000000000000";

/// `vehicle_local_position` (PX4 `msg/VehicleLocalPosition.msg`, a subset).
const LOCAL_POSITION: Format = Format {
    name: "vehicle_local_position",
    fields: &[
        Field::scalar(Uint64, "timestamp"),
        Field::scalar(Uint64, "timestamp_sample"),
        Field::scalar(Float, "x"),
        Field::scalar(Float, "y"),
        Field::scalar(Float, "z"),
        Field::scalar(Float, "vx"),
        Field::scalar(Float, "vy"),
        Field::scalar(Float, "vz"),
        Field::scalar(Float, "ax"),
        Field::scalar(Float, "ay"),
        Field::scalar(Float, "az"),
        Field::scalar(Float, "heading"),
        Field::scalar(Bool, "xy_valid"),
        Field::scalar(Bool, "z_valid"),
        Field::scalar(Bool, "v_xy_valid"),
        Field::scalar(Bool, "v_z_valid"),
    ],
};

/// `vehicle_attitude` (PX4 `msg/VehicleAttitude.msg`).
const ATTITUDE: Format = Format {
    name: "vehicle_attitude",
    fields: &[
        Field::scalar(Uint64, "timestamp"),
        Field::scalar(Uint64, "timestamp_sample"),
        Field::array(Float, 4, "q"),
        Field::array(Float, 4, "delta_q_reset"),
        Field::scalar(Uint8, "quat_reset_counter"),
    ],
};

/// `vehicle_local_position_setpoint` (PX4 `msg/VehicleLocalPositionSetpoint.msg`, a
/// subset).
const SETPOINT: Format = Format {
    name: "vehicle_local_position_setpoint",
    fields: &[
        Field::scalar(Uint64, "timestamp"),
        Field::scalar(Float, "x"),
        Field::scalar(Float, "y"),
        Field::scalar(Float, "z"),
        Field::scalar(Float, "vx"),
        Field::scalar(Float, "vy"),
        Field::scalar(Float, "vz"),
        Field::scalar(Float, "yaw"),
    ],
};

/// The logged topics (a topic's index is its ULog `msg_id`) and their intervals, µs.
const TOPICS: [(&Format, u64); 3] = [
    (&LOCAL_POSITION, 50_000),
    (&ATTITUDE, 50_000),
    (&SETPOINT, 100_000),
];

/// One flight's log, as a ground station lists (`LOG_ENTRY`) and downloads it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FlightLog {
    /// When the flight started (arming), seconds since the Unix epoch, UTC
    /// (`LOG_ENTRY.time_utc`).
    pub time_utc: u32,
    /// The ULog file (`LOG_ENTRY.size` is its length, bytes).
    pub bytes: Arc<[u8]>,
}

/// The log of the flight in progress.
#[derive(Debug)]
struct Recording {
    time_utc: u32,
    writer: ulog::Writer,
    /// When each topic's next sample is due, µs of the boot clock.
    next_due_us: [u64; TOPICS.len()],
    /// The storage is full: nothing more is written.
    full: bool,
}

/// A vehicle's flight logs (kept across reboots, as on PX4's SD card).
#[derive(Debug, Default)]
pub(crate) struct FlightLogStore {
    /// Finished logs, oldest first.
    finished: VecDeque<FlightLog>,
    recording: Option<Recording>,
}

impl FlightLogStore {
    /// Every log as `LOG_REQUEST_LIST` lists them, oldest first (id 0): the finished
    /// ones, then the one being written (what it holds so far).
    pub(crate) fn list(&self) -> Vec<FlightLog> {
        let mut logs: Vec<FlightLog> = self.finished.iter().cloned().collect();
        if let Some(r) = &self.recording {
            logs.push(FlightLog {
                time_utc: r.time_utc,
                bytes: r.writer.bytes().into(),
            });
        }
        logs
    }

    /// `LOG_ERASE`: every log goes, the one being written too (PX4 unlinks it; the
    /// rest of that flight is lost).
    pub(crate) fn erase(&mut self) {
        self.finished.clear();
        self.recording = None;
    }

    /// Ends the log in progress: it joins the finished ones.
    pub(crate) fn finish(&mut self) {
        if let Some(r) = self.recording.take() {
            self.finished.push_back(FlightLog {
                time_utc: r.time_utc,
                bytes: r.writer.into_bytes().into(),
            });
        }
    }

    /// Starts a log at `time_boot_us` (its header's timestamp) for a flight that started
    /// at `time_utc`, dropping the oldest logs beyond [`FLIGHT_LOGS_KEPT`].
    fn start(&mut self, time_boot_us: u64, time_utc: u32) {
        self.finish();
        while self.finished.len() >= FLIGHT_LOGS_KEPT {
            self.finished.pop_front();
        }
        let mut writer = ulog::Writer::new(time_boot_us);
        writer.info_str("sys_name", "PX4");
        writer.info_str("ver_hw", "PX4_SITL");
        writer.info_str("ver_sw", VER_SW);
        writer.info_u32("ver_sw_release", PX4_FLIGHT_SW_VERSION);
        for (format, _) in TOPICS {
            writer.format(format);
        }
        for (msg_id, (format, _)) in TOPICS.iter().enumerate() {
            writer.subscribe(msg_id as u16, format);
        }
        self.recording = Some(Recording {
            time_utc,
            writer,
            // Due at the first step; the rates run from there.
            next_due_us: [0; TOPICS.len()],
            full: false,
        });
    }

    /// Bytes of every log, the one being written included.
    fn stored_bytes(&self) -> usize {
        let finished: usize = self.finished.iter().map(|l| l.bytes.len()).sum();
        finished + self.recording.as_ref().map_or(0, |r| r.writer.len())
    }

    /// Makes room for `extra` more bytes, dropping the oldest finished logs; false when
    /// the log being written alone would exceed the storage.
    fn make_room(&mut self, extra: usize) -> bool {
        while self.stored_bytes() + extra > FLIGHT_LOG_STORAGE_BYTES {
            if self.finished.pop_front().is_none() {
                return false;
            }
        }
        true
    }

    /// Appends one sample of topic `msg_id` to the log in progress, storage allowing.
    fn write(&mut self, msg_id: usize, sample: &Sample) {
        let len = ulog::MSG_HEADER_LEN + 2 + sample.bytes().len();
        if self.recording.as_ref().is_none_or(|r| r.full) {
            return;
        }
        let room = self.make_room(len);
        if let Some(r) = self.recording.as_mut() {
            if room {
                r.writer.data(msg_id as u16, sample.bytes());
            } else {
                r.full = true;
            }
        }
    }
}

/// Seconds since the Unix epoch now (wall clock), 0 if the clock is before it.
fn unix_time_s() -> u32 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() as u32)
}

impl Vehicle {
    /// At arming: a new log starts.
    pub(super) fn start_flight_log(&mut self, now: Instant) {
        let t = self.time_boot_us(now);
        self.flight_logs.start(t, unix_time_s());
    }

    /// At disarming: the log is finished.
    pub(super) fn finish_flight_log(&mut self) {
        self.flight_logs.finish();
    }

    /// Every step while armed: the samples that are due.
    pub(super) fn record_flight_log(&mut self, now: Instant) {
        let t = self.time_boot_us(now);
        let Some(r) = self.flight_logs.recording.as_mut() else {
            return;
        };
        let mut due = [false; TOPICS.len()];
        for (i, (_, interval_us)) in TOPICS.iter().enumerate() {
            let next = &mut r.next_due_us[i];
            if t >= *next {
                due[i] = true;
                *next += interval_us;
                if *next <= t {
                    // After a stall, start again from now rather than catch up.
                    *next = t + interval_us;
                }
            }
        }
        for (msg_id, _) in due.iter().enumerate().filter(|(_, d)| **d) {
            let sample = match msg_id {
                0 => self.local_position_sample(t),
                1 => self.attitude_sample(t),
                _ => self.setpoint_sample(t),
            };
            debug_assert_eq!(sample.bytes().len(), TOPICS[msg_id].0.data_size());
            self.flight_logs.write(msg_id, &sample);
        }
    }

    /// `vehicle_local_position` now: the estimate, as LOCAL_POSITION_NED reports it.
    fn local_position_sample(&self, t_us: u64) -> Sample {
        let (p, v, a) = (self.est_pos(), self.est_vel(), self.acc_filt);
        let mut s = Sample::new();
        s.u64(t_us).u64(t_us);
        for x in [p, v, a] {
            s.f32(x.north_m).f32(x.east_m).f32(x.down_m);
        }
        s.f32(wrap_pi(self.yaw_rad));
        for _ in 0..4 {
            s.bool(self.has_fix);
        }
        s
    }

    /// `vehicle_attitude` now (no estimator reset: `delta_q_reset` the identity).
    fn attitude_sample(&self, t_us: u64) -> Sample {
        let q = telemetry::quaternion(self.roll_rad, self.pitch_rad, self.yaw_rad);
        let mut s = Sample::new();
        s.u64(t_us)
            .u64(t_us)
            .f32s(&q)
            .f32s(&[1.0, 0.0, 0.0, 0.0])
            .u8(0);
        s
    }

    /// `vehicle_local_position_setpoint` now: the position controller's setpoints.
    fn setpoint_sample(&self, t_us: u64) -> Sample {
        let (p, v) = (self.ctrl_pos_sp, self.ctrl_vel_sp);
        let mut s = Sample::new();
        s.u64(t_us);
        for x in [p, v] {
            s.f32(x.north_m).f32(x.east_m).f32(x.down_m);
        }
        s.f32(wrap_pi(self.ctrl_yaw_sp));
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_are_px4_layouts() {
        assert_eq!(
            LOCAL_POSITION.definition(),
            "vehicle_local_position:uint64_t timestamp;uint64_t timestamp_sample;float x;\
             float y;float z;float vx;float vy;float vz;float ax;float ay;float az;\
             float heading;bool xy_valid;bool z_valid;bool v_xy_valid;bool v_z_valid;\
             uint8_t[4] _padding0;"
        );
        assert_eq!(
            ATTITUDE.definition(),
            "vehicle_attitude:uint64_t timestamp;uint64_t timestamp_sample;float[4] q;\
             float[4] delta_q_reset;uint8_t quat_reset_counter;uint8_t[7] _padding0;"
        );
        assert_eq!(
            SETPOINT.definition(),
            "vehicle_local_position_setpoint:uint64_t timestamp;float x;float y;float z;\
             float vx;float vy;float vz;float yaw;uint8_t[4] _padding0;"
        );
        // Biggest types first, as PX4's generator orders them: no padding between fields.
        for (f, _) in TOPICS {
            let sizes: Vec<usize> = f.fields.iter().map(|x| x.ty.size()).collect();
            assert!(sizes.windows(2).all(|w| w[0] >= w[1]), "{}", f.name);
        }
    }

    fn store_with_logs(n: usize, bytes: usize) -> FlightLogStore {
        let mut s = FlightLogStore::default();
        for i in 0..n {
            s.finished.push_back(FlightLog {
                time_utc: i as u32,
                bytes: vec![0u8; bytes].into(),
            });
        }
        s
    }

    #[test]
    fn keeps_the_newest_logs() {
        let mut s = store_with_logs(FLIGHT_LOGS_KEPT, 100);
        s.start(0, 99);
        let list = s.list();
        assert_eq!(list.len(), FLIGHT_LOGS_KEPT);
        assert_eq!(list[0].time_utc, 1, "the oldest went");
        assert_eq!(
            list[FLIGHT_LOGS_KEPT - 1].time_utc,
            99,
            "the one being written"
        );
        s.finish();
        assert!(s.recording.is_none());
        assert_eq!(s.list().len(), FLIGHT_LOGS_KEPT);
        s.erase();
        assert!(s.list().is_empty());
    }

    #[test]
    fn storage_drops_oldest_then_stops_the_flight_log() {
        let mut s = store_with_logs(2, FLIGHT_LOG_STORAGE_BYTES / 2 - 10);
        s.start(0, 7);
        let header_len = s.stored_bytes() - 2 * (FLIGHT_LOG_STORAGE_BYTES / 2 - 10);
        let mut sample = Sample::new();
        sample.u64(1);
        s.write(2, &sample);
        assert_eq!(s.list().len(), 2, "the oldest log made room");
        let mut written = 0;
        while !s.recording.as_ref().is_some_and(|r| r.full) {
            s.write(2, &sample);
            written += 1;
            assert!(written < 1_000_000, "never full");
        }
        assert!(s.stored_bytes() <= FLIGHT_LOG_STORAGE_BYTES);
        assert!(s.finished.is_empty(), "every finished log made room first");
        let len = s.list()[0].bytes.len();
        s.write(2, &sample);
        assert_eq!(
            s.list()[0].bytes.len(),
            len,
            "a full storage takes nothing more"
        );
        assert!(len > header_len);
    }
}
