//! RTCM3 frames for tests and rehearsals: a base station's position (1005), and frames of
//! any message number and length with a good CRC-24Q (their contents zero), as a caster
//! would send them. Not used by the service itself.

use rtcm_rs::msg::Msg1005T;
use rtcm_rs::{Message, MessageBuilder};
use skein_model::geo::GeoPoint;

/// A valid 1005 frame for station `id` at `p`.
pub fn frame_1005(id: u16, p: GeoPoint) -> Vec<u8> {
    let [x, y, z] = p.to_ecef();
    let msg = Message::Msg1005(Msg1005T {
        reference_station_id: id,
        reserved_24_6: 0,
        gps_flag: 1,
        glonass_flag: 0,
        galileo_flag: 1,
        reference_station_ind: 0,
        antenna_ref_point_ecef_x_m: x,
        single_receiver_osc_ind: 0,
        reserved_73_1: 0,
        antenna_ref_point_ecef_y_m: y,
        quarter_cycle_ind: 0,
        antenna_ref_point_ecef_z_m: z,
    });
    MessageBuilder::new()
        .build_message(&msg)
        .expect("encodes")
        .to_vec()
}

/// A frame of `n` message bytes (at least 2) starting with message number `t` (the rest
/// zero), with a good CRC.
pub fn frame_of(t: u16, n: usize) -> Vec<u8> {
    let mut m = vec![0u8; n.max(2)];
    m[0] = (t >> 4) as u8;
    m[1] = ((t & 0xF) << 4) as u8;
    let mut f = vec![0xD3, (m.len() >> 8) as u8, m.len() as u8];
    f.extend_from_slice(&m);
    let crc = crc24q(&f);
    f.extend_from_slice(&[(crc >> 16) as u8, (crc >> 8) as u8, crc as u8]);
    f
}

/// CRC-24Q (RTCM 10403.x), bitwise.
fn crc24q(data: &[u8]) -> u32 {
    let mut crc = 0u32;
    for b in data {
        crc ^= u32::from(*b) << 16;
        for _ in 0..8 {
            crc <<= 1;
            if crc & 0x100_0000 != 0 {
                crc ^= 0x186_4CFB;
            }
        }
    }
    crc & 0xFF_FFFF
}
