//! The receiver's corrections input, as PX4 v1.16 feeds it. `MavlinkReceiver::
//! handle_message_gps_rtcm_data` publishes each `GPS_RTCM_DATA` as it arrives, in order,
//! on uORB `gps_inject_data` (a queue of `ORB_QUEUE_LENGTH` 8: a ninth message published
//! before the GPS driver reads overwrites the oldest); the GPS driver
//! (`GPS::handleInjectDataTopic`, called at the start of every `pollOrRead`, which waits
//! up to 50 ms for the receiver's bytes) writes each one's bytes to the receiver's serial
//! port without reassembling anything. The receiver (u-blox F9P and the like) finds
//! RTCM3 frames in that byte stream (preamble 0xD3, 6 zero bits, a 10-bit length, the
//! payload, CRC-24Q) and drops the frames whose CRC fails: a lost fragment corrupts one
//! RTCM message, which is dropped.
//!
//! Framing and the CRC are rtcm-rs's (`MessageFrame::new`, which says `Incomplete` or
//! `NotValid`; `next_msg_frame` would skip a bad CRC without telling, so the scan is
//! here); base positions (1005/1006) are decoded by rtcm-rs, every other message type is
//! only framed, checked and classified by its number.

use rtcm_rs::rtcm_error::RtcmError;
use rtcm_rs::{Message, MessageFrame};
use serde::Serialize;
use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// `GPS_RTCM_DATA.data` capacity, bytes (MAVLink common).
pub const GPS_RTCM_DATA_LEN: usize = 180;
/// Depth of PX4 v1.16's uORB `gps_inject_data` queue (`GpsInjectData.msg`
/// `ORB_QUEUE_LENGTH`; 16 only from late 2025, PX4 pull request 26042).
pub const INJECT_QUEUE_LENGTH: usize = 8;
/// Longest wait of a queued message for the GPS driver: `pollOrRead`'s `max_timeout`
/// (50 ms) when the receiver is quiet. While it talks the driver comes round sooner, so
/// the simulator is never kinder than PX4.
pub const GPS_DRIVER_CYCLE: Duration = Duration::from_millis(50);
/// RTCM3 frame preamble.
const PREAMBLE: u8 = 0xD3;
/// Header (preamble, reserved bits, length), bytes.
const HEADER_LEN: usize = 3;

/// What happened to the RTK corrections of one vehicle (since start or the last
/// `reset_stats`; kept across reboots, like the other counters).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct RtcmCounts {
    /// `GPS_RTCM_DATA` messages accepted (each a fragment or a whole RTCM stream chunk).
    pub gps_rtcm_data: u64,
    /// `GPS_RTCM_DATA` with `len` over 180: counted and dropped.
    pub gps_rtcm_data_malformed: u64,
    /// `GPS_RTCM_DATA` lost because uORB `gps_inject_data` (8 deep) was full when the
    /// next one arrived: the sender bursts faster than PX4's GPS driver drains.
    pub inject_queue_overruns: u64,
    /// Bytes written to the receiver.
    pub bytes_to_receiver: u64,
    /// RTCM3 frames whose CRC-24Q held (any message type).
    pub frames_ok: u64,
    /// Of those, frames carrying observations (MSM 1071–1137, legacy 1001–1004 and
    /// 1009–1012): what the corrections' age counts from.
    pub observation_frames: u64,
    /// Of those, base station positions (1005, 1006).
    pub base_position_frames: u64,
    /// Frame starts (preamble, zero reserved bits, complete length) whose CRC failed:
    /// the frame is dropped and the receiver resynchronises one byte further.
    pub crc_failures: u64,
    /// Bytes that were not part of a good frame (including those of dropped frames).
    pub garbage_bytes: u64,
}

impl RtcmCounts {
    /// Adds `other`'s counts to these (a run's totals).
    pub fn add(&mut self, other: &RtcmCounts) {
        self.gps_rtcm_data += other.gps_rtcm_data;
        self.gps_rtcm_data_malformed += other.gps_rtcm_data_malformed;
        self.inject_queue_overruns += other.inject_queue_overruns;
        self.bytes_to_receiver += other.bytes_to_receiver;
        self.frames_ok += other.frames_ok;
        self.observation_frames += other.observation_frames;
        self.base_position_frames += other.base_position_frames;
        self.crc_failures += other.crc_failures;
        self.garbage_bytes += other.garbage_bytes;
    }
}

/// What a good frame tells the receiver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Correction {
    /// Observations of the base (MSM or legacy RTK messages).
    Observations,
    /// The base's antenna reference point, ECEF m (1005/1006).
    BasePosition([f64; 3]),
}

/// True for the RTCM3 message numbers that carry observations: legacy GPS (1001–1004) and
/// GLONASS (1009–1012) RTK observables, and MSM1–7 of every constellation (107x GPS,
/// 108x GLONASS, 109x Galileo, 110x SBAS, 111x QZSS, 112x BeiDou, 113x NavIC, x = 1–7).
pub(crate) fn is_observation(message_number: u16) -> bool {
    matches!(message_number, 1001..=1004 | 1009..=1012)
        || ((1071..=1137).contains(&message_number) && (1..=7).contains(&(message_number % 10)))
}

/// uORB `gps_inject_data` between the MAVLink receiver and the GPS driver.
#[derive(Debug, Default)]
pub(crate) struct InjectQueue {
    queue: VecDeque<Vec<u8>>,
    next_cycle: Option<Instant>,
}

impl InjectQueue {
    /// Publishes one `GPS_RTCM_DATA`'s bytes; a full queue loses its oldest entry.
    pub fn publish(&mut self, data: &[u8], counts: &mut RtcmCounts) {
        if self.queue.len() == INJECT_QUEUE_LENGTH {
            self.queue.pop_front();
            counts.inject_queue_overruns += 1;
        }
        self.queue.push_back(data.to_vec());
    }

    /// The GPS driver's cycle: at `now`, when one is due, every queued message's bytes
    /// in order (at most the queue's depth: `handleInjectDataTopic`'s limit).
    pub fn drain_due(&mut self, now: Instant) -> Vec<Vec<u8>> {
        if self.next_cycle.is_some_and(|t| now < t) {
            return Vec::new();
        }
        self.next_cycle = Some(now + GPS_DRIVER_CYCLE);
        self.queue.drain(..).collect()
    }
}

/// Where a scan of the buffer goes on.
enum Scan {
    /// Look again from this position.
    Next(usize),
    /// Wait for more bytes, keeping those from this position.
    Wait(usize),
}

/// The receiver's RTCM3 framer: bytes in, good frames out; holds at most one
/// incomplete frame (1029 bytes).
#[derive(Debug, Default)]
pub(crate) struct RtcmStream {
    buf: Vec<u8>,
}

impl RtcmStream {
    /// Appends `bytes` and returns what the complete good frames among them tell.
    pub fn push(&mut self, bytes: &[u8], counts: &mut RtcmCounts) -> Vec<Correction> {
        counts.bytes_to_receiver += bytes.len() as u64;
        self.buf.extend_from_slice(bytes);
        let mut found = Vec::new();
        let mut pos = 0;
        let keep = loop {
            match self.scan(pos, counts, &mut found) {
                Scan::Next(next) => pos = next,
                Scan::Wait(keep) => break keep,
            }
        };
        self.buf.drain(..keep);
        found
    }

    /// Looks for a frame from `pos`; every byte passed over is counted once.
    fn scan(&self, pos: usize, counts: &mut RtcmCounts, found: &mut Vec<Correction>) -> Scan {
        let rest = &self.buf[pos..];
        let Some(start) = rest.iter().position(|&b| b == PREAMBLE) else {
            counts.garbage_bytes += rest.len() as u64;
            return Scan::Wait(self.buf.len());
        };
        counts.garbage_bytes += start as u64;
        let at = pos + start;
        let candidate = &self.buf[at..];
        if candidate.len() < HEADER_LEN {
            return Scan::Wait(at);
        }
        if candidate[1] & 0xFC != 0 {
            // Not a frame start: the 6 bits after the preamble are zero in RTCM3.
            counts.garbage_bytes += 1;
            return Scan::Next(at + 1);
        }
        match MessageFrame::new(candidate) {
            Ok(frame) => {
                counts.frames_ok += 1;
                if let Some(c) = classify(&frame, counts) {
                    found.push(c);
                }
                Scan::Next(at + frame.frame_len())
            }
            Err(RtcmError::Incomplete) => Scan::Wait(at),
            Err(_) => {
                counts.crc_failures += 1;
                counts.garbage_bytes += 1;
                Scan::Next(at + 1)
            }
        }
    }
}

/// What a good frame carries for the fix; counts observations and base positions.
fn classify(frame: &MessageFrame, counts: &mut RtcmCounts) -> Option<Correction> {
    let data = frame.data();
    if data.len() < 2 {
        return None;
    }
    let number = (u16::from(data[0]) << 4) | (u16::from(data[1]) >> 4);
    if is_observation(number) {
        counts.observation_frames += 1;
        return Some(Correction::Observations);
    }
    let ecef = match frame.get_message() {
        Message::Msg1005(m) => [
            m.antenna_ref_point_ecef_x_m,
            m.antenna_ref_point_ecef_y_m,
            m.antenna_ref_point_ecef_z_m,
        ],
        Message::Msg1006(m) => [
            m.antenna_ref_point_ecef_x_m,
            m.antenna_ref_point_ecef_y_m,
            m.antenna_ref_point_ecef_z_m,
        ],
        _ => return None,
    };
    counts.base_position_frames += 1;
    Some(Correction::BasePosition(ecef))
}
