//! RTCM3 frames found in a byte stream (RTCM 10403.x transport layer: preamble `0xD3`,
//! 6 reserved zero bits, a 10-bit length, the message, CRC-24Q), checked with the
//! `rtcm-rs` crate; what is not a frame is counted and dropped. Also what a crew wants
//! to see of the stream: the message types and the base station's position (message
//! 1005 or 1006, the reference station's antenna in ECEF).

use rtcm_rs::{Message, MessageFrame};
use skein_model::geo::GeoPoint;
use std::collections::BTreeMap;

/// The longest RTCM3 frame: 3 header bytes, 1023 message bytes, 3 CRC bytes.
pub const MAX_FRAME_BYTES: usize = 1029;

/// The RTCM3 preamble.
const PREAMBLE: u8 = 0xD3;

/// What the framer saw so far.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FramerCounts {
    /// Good frames.
    pub frames: u64,
    /// Candidate frames (preamble, reserved bits zero, length) whose CRC-24Q failed.
    pub crc_failures: u64,
    /// Bytes that were not part of a good frame (noise between frames, the preambles of
    /// failed candidates).
    pub garbage_bytes: u64,
    /// Good frames by message number (1005, 1077, ...).
    pub message_types: BTreeMap<u16, u64>,
}

/// A reference station's position, from message 1005 or 1006.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BaseStation {
    /// The reference station id (DF003).
    pub station_id: u16,
    /// The antenna reference point (DF025-DF027 converted to WGS84; the altitude is the
    /// ellipsoid height, metres).
    pub position: GeoPoint,
}

/// One good frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// The whole frame (header, message, CRC): what the GNSS receiver is given.
    pub bytes: Vec<u8>,
    /// Its message number, when it has one (a frame shorter than 2 message bytes has none).
    pub message_type: Option<u16>,
    /// The base station it describes, for 1005 and 1006.
    pub base: Option<BaseStation>,
}

/// Finds RTCM3 frames in a byte stream (see the module docs).
#[derive(Debug, Default)]
pub struct RtcmFramer {
    buf: Vec<u8>,
    counts: FramerCounts,
}

impl RtcmFramer {
    /// Takes `bytes` of the stream; returns the frames they completed, in order.
    pub fn push(&mut self, bytes: &[u8]) -> Vec<Frame> {
        self.buf.extend_from_slice(bytes);
        let mut frames = Vec::new();
        let mut start = 0;
        loop {
            let rest = &self.buf[start..];
            let Some(at) = rest.iter().position(|b| *b == PREAMBLE) else {
                self.counts.garbage_bytes += rest.len() as u64;
                start = self.buf.len();
                break;
            };
            self.counts.garbage_bytes += at as u64;
            start += at;
            let rest = &self.buf[start..];
            if rest.len() < 3 {
                break;
            }
            if rest[1] & 0xFC != 0 {
                // Reserved bits set: not a frame.
                self.counts.garbage_bytes += 1;
                start += 1;
                continue;
            }
            let len = (usize::from(rest[1] & 0x03) << 8 | usize::from(rest[2])) + 6;
            if rest.len() < len {
                break;
            }
            match MessageFrame::new(&rest[..len]) {
                Ok(f) => {
                    frames.push(frame(&mut self.counts, &f));
                    start += len;
                }
                Err(_) => {
                    // Resynchronise from the next byte: a good frame may start inside.
                    self.counts.crc_failures += 1;
                    self.counts.garbage_bytes += 1;
                    start += 1;
                }
            }
        }
        self.buf.drain(..start);
        frames
    }
}

/// A good frame, counted into `counts`.
fn frame(counts: &mut FramerCounts, f: &MessageFrame) -> Frame {
    counts.frames += 1;
    let message_type = f.message_number();
    if let Some(t) = message_type {
        *counts.message_types.entry(t).or_default() += 1;
    }
    let base = match f.get_message() {
        Message::Msg1005(m) => Some(base(
            m.reference_station_id,
            [
                m.antenna_ref_point_ecef_x_m,
                m.antenna_ref_point_ecef_y_m,
                m.antenna_ref_point_ecef_z_m,
            ],
        )),
        Message::Msg1006(m) => Some(base(
            m.reference_station_id,
            [
                m.antenna_ref_point_ecef_x_m,
                m.antenna_ref_point_ecef_y_m,
                m.antenna_ref_point_ecef_z_m,
            ],
        )),
        _ => None,
    };
    Frame {
        bytes: f.frame_data().to_vec(),
        message_type,
        base,
    }
}

impl RtcmFramer {
    /// What was seen so far.
    pub fn counts(&self) -> &FramerCounts {
        &self.counts
    }

    /// Forgets a partial frame (the stream was reconnected: what follows does not
    /// continue it). Counts the forgotten bytes as garbage.
    pub fn reset(&mut self) {
        self.counts.garbage_bytes += self.buf.len() as u64;
        self.buf.clear();
    }
}

fn base(station_id: u16, ecef_m: [f64; 3]) -> BaseStation {
    BaseStation {
        station_id,
        position: GeoPoint::from_ecef(ecef_m),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{frame_1005, frame_of};

    #[test]
    fn frames_are_found_in_noise_and_split_reads() {
        let zurich = GeoPoint::new(47.397_742, 8.545_594, 535.0);
        let mut wire = b"garbage".to_vec();
        wire.extend(frame_1005(7, zurich));
        wire.extend([0xD3, 0xFF, 0x00]); // reserved bits set: not a frame
        wire.extend(frame_of(1077, 300));
        let mut corrupt = frame_of(1074, 100);
        corrupt[50] ^= 0x40;
        wire.extend(&corrupt);
        wire.extend(frame_of(1230, 10));
        for chunk in [1, 7, 64, wire.len()] {
            let mut f = RtcmFramer::default();
            let frames: Vec<Frame> = wire.chunks(chunk).flat_map(|c| f.push(c)).collect();
            let types: Vec<_> = frames.iter().map(|f| f.message_type).collect();
            assert_eq!(
                types,
                [Some(1005), Some(1077), Some(1230)],
                "reads of {chunk}"
            );
            let b = frames[0].base.expect("1005 gives the base");
            assert_eq!(b.station_id, 7);
            assert!((b.position.lat_deg - zurich.lat_deg).abs() < 1e-7);
            assert!((b.position.lon_deg - zurich.lon_deg).abs() < 1e-7);
            assert!((b.position.alt_amsl_m - zurich.alt_amsl_m).abs() < 0.01);
            let c = f.counts();
            assert_eq!(c.frames, 3);
            assert!(c.crc_failures >= 1, "{c:?}");
            assert!(c.garbage_bytes >= 7 + 3 + corrupt.len() as u64, "{c:?}");
            assert_eq!(c.message_types.get(&1077), Some(&1));
        }
    }
}
