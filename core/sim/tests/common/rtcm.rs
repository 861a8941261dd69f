//! RTK corrections as a caster sends them, for the GNSS tests: RTCM3 frames (a base
//! position 1005 made by rtcm-rs's encoder; a GPS MSM7 1077 laid out bit by bit, framed
//! with its CRC-24Q, which rtcm-rs checks) and a [`Caster`] that sends one epoch of them
//! per call as GPS_RTCM_DATA, fragmented by [`skein_sim::client::gps_rtcm_data`].

use rtcm_rs::msg::Msg1005T;
use rtcm_rs::{Message, MessageBuilder, MessageFrame};
use skein_mavlink::MavMessage;
use skein_model::geo::GeoPoint;
use skein_sim::client;

/// CRC-24Q (RTCM 10403, polynomial 0x1864CFB) of `bytes`.
pub fn crc24q(bytes: &[u8]) -> u32 {
    let mut crc: u32 = 0;
    for &b in bytes {
        crc ^= u32::from(b) << 16;
        for _ in 0..8 {
            crc <<= 1;
            if crc & 0x100_0000 != 0 {
                crc ^= 0x186_4CFB;
            }
        }
    }
    crc & 0xFF_FFFF
}

/// An RTCM3 frame of `payload`: preamble, 6 zero bits, 10-bit length, payload, CRC-24Q.
pub fn rtcm_frame(payload: &[u8]) -> Vec<u8> {
    assert!(payload.len() < 1024, "RTCM3 payloads are under 1024 bytes");
    let mut f = vec![0xD3, (payload.len() >> 8) as u8, payload.len() as u8];
    f.extend_from_slice(payload);
    let crc = crc24q(&f);
    f.extend_from_slice(&[(crc >> 16) as u8, (crc >> 8) as u8, crc as u8]);
    f
}

/// The message number of a good frame, as rtcm-rs reads it (panics on a bad frame).
pub fn frame_number(frame: &[u8]) -> u16 {
    MessageFrame::new(frame)
        .ok()
        .and_then(|f| f.message_number())
        .expect("a good RTCM3 frame")
}

/// MSB-first bit writer.
#[derive(Default)]
struct Bits {
    bytes: Vec<u8>,
    bits: usize,
}

impl Bits {
    fn put(&mut self, value: u64, width: usize) {
        for i in (0..width).rev() {
            if self.bits.is_multiple_of(8) {
                self.bytes.push(0);
            }
            if (value >> i) & 1 == 1 {
                let last = self.bytes.len() - 1;
                self.bytes[last] |= 0x80 >> (self.bits % 8);
            }
            self.bits += 1;
        }
    }
}

/// The payload of a GPS MSM7 (1077) of `epoch_ms` from station `station`: `sats`
/// satellites (PRN 1..) times `sigs` signals (1C, 2W, 5Q ...), every cell present, with
/// plausible values (only the frame and its number matter to a receiver's framer).
pub fn msm7_payload(station: u16, epoch_ms: u32, sats: usize, sigs: usize) -> Vec<u8> {
    assert!(sats * sigs <= 64 && sats <= 64 && sigs <= 32);
    let mut b = Bits::default();
    b.put(1077, 12);
    b.put(u64::from(station), 12);
    b.put(u64::from(epoch_ms % 604_800_000), 30);
    b.put(0, 1); // last message of the epoch
    b.put(0, 3); // IODS
    b.put(0, 7); // reserved
    b.put(0, 2); // clock steering
    b.put(0, 2); // external clock
    b.put(0, 1); // smoothing
    b.put(0, 3); // smoothing interval
    b.put(u64::MAX << (64 - sats), 64); // satellite mask
    let sig_ids = [2, 16, 22, 3, 17, 23, 4, 18];
    let sig_mask = sig_ids[..sigs]
        .iter()
        .fold(0u64, |m, &id| m | 1 << (32 - id));
    b.put(sig_mask, 32);
    b.put((1u64 << (sats * sigs)) - 1, sats * sigs); // cell mask
    let v = |k: usize, width: usize| ((k as u64 * 2_654_435_761) >> 7) & ((1 << width) - 1);
    for k in 0..sats {
        b.put(70 + (k as u64 % 10), 8); // rough range, integer ms
    }
    for _ in 0..sats {
        b.put(0, 4); // extended satellite info
    }
    for k in 0..sats {
        b.put(v(k, 10), 10); // rough range modulo 1 ms
    }
    for k in 0..sats {
        b.put(v(k + 7, 14), 14); // rough phase range rate
    }
    let cells = sats * sigs;
    let widths = [20, 24, 10, 1, 10, 15]; // pseudorange, phase range, lock, half, CNR, rate
    for (j, &width) in widths.iter().enumerate() {
        for k in 0..cells {
            b.put(v(k * 6 + j, width), width);
        }
    }
    b.bytes
}

/// A 1005 (base station antenna reference point) at `ecef_m`, by rtcm-rs's encoder.
pub fn base_position_1005(station: u16, ecef_m: [f64; 3]) -> Vec<u8> {
    let msg = Message::Msg1005(Msg1005T {
        reference_station_id: station,
        gps_flag: 1,
        glonass_flag: 1,
        galileo_flag: 1,
        antenna_ref_point_ecef_x_m: ecef_m[0],
        antenna_ref_point_ecef_y_m: ecef_m[1],
        antenna_ref_point_ecef_z_m: ecef_m[2],
        ..Default::default()
    });
    MessageBuilder::new()
        .build_message(&msg)
        .expect("encode 1005")
        .to_vec()
}

/// One base station's corrections: each epoch a 1005 and a GPS MSM7 of 12 satellites × 3
/// signals (a 446-byte frame: 3 GPS_RTCM_DATA fragments).
pub struct Caster {
    /// The base's antenna, ECEF m.
    pub base_ecef_m: [f64; 3],
    /// Epochs sent.
    pub epochs: u32,
    sequence: u8,
}

impl Caster {
    /// A caster for a base standing at `base`.
    pub fn at(base: GeoPoint) -> Caster {
        Caster {
            base_ecef_m: base.to_ecef(),
            epochs: 0,
            sequence: 0,
        }
    }

    /// The next epoch's frames: the 1005, then the MSM7.
    pub fn epoch_frames(&mut self) -> [Vec<u8>; 2] {
        self.epochs += 1;
        let epoch_ms = self.epochs * 1000;
        [
            base_position_1005(7, self.base_ecef_m),
            rtcm_frame(&msm7_payload(7, epoch_ms, 12, 3)),
        ]
    }

    /// `frames` as GPS_RTCM_DATA, each frame its own sequence (fragmented as needed).
    pub fn messages(&mut self, frames: &[Vec<u8>]) -> Vec<Vec<MavMessage>> {
        frames
            .iter()
            .map(|f| {
                self.sequence = self.sequence.wrapping_add(1);
                client::gps_rtcm_data(f, self.sequence).expect("fits one sequence")
            })
            .collect()
    }

    /// The next epoch as GPS_RTCM_DATA messages, in order.
    pub fn epoch(&mut self) -> Vec<MavMessage> {
        let frames = self.epoch_frames();
        self.messages(&frames).into_iter().flatten().collect()
    }
}
