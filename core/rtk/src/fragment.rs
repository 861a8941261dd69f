//! One RTCM3 message as MAVLink `GPS_RTCM_DATA` (id 233), following MAVLink's
//! fragmentation rules (common.xml, `GPS_RTCM_DATA.flags`): a message of up to 180 bytes
//! goes in one unfragmented message; a longer one in up to four fragments of 180 bytes,
//! `flags` = 1 (fragmented) | fragment id << 1 | sequence id << 3. An autopilot that
//! reassembles (ArduPilot) takes a message as complete when all four fragments arrived or
//! every fragment before the first one shorter than 180 bytes did, so a message of exactly
//! 360 or 540 bytes is followed by an empty fragment (as MAVProxy's `DGPS` module sends
//! it). PX4 passes each fragment's bytes to the receiver as they come. A message over 720
//! bytes cannot be sent and is dropped (counted by the caller).

use skein_mavlink::dialect::GPS_RTCM_DATA_DATA;

/// Data bytes of one `GPS_RTCM_DATA`.
pub const FRAGMENT_BYTES: usize = 180;

/// The longest RTCM message `GPS_RTCM_DATA` carries: four full fragments.
pub const MAX_MESSAGE_BYTES: usize = 4 * FRAGMENT_BYTES;

/// An RTCM message longer than [`MAX_MESSAGE_BYTES`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TooLarge(pub usize);

/// `message` (a whole RTCM3 frame) as `GPS_RTCM_DATA` messages, with sequence id
/// `sequence` (its low 5 bits; the caller counts it up per message).
///
/// # Errors
/// [`TooLarge`] for a message over [`MAX_MESSAGE_BYTES`].
pub fn fragments(message: &[u8], sequence: u8) -> Result<Vec<GPS_RTCM_DATA_DATA>, TooLarge> {
    if message.len() > MAX_MESSAGE_BYTES {
        return Err(TooLarge(message.len()));
    }
    let seq = (sequence & 0x1F) << 3;
    if message.len() <= FRAGMENT_BYTES {
        return Ok(vec![data(seq, message)]);
    }
    let mut out: Vec<GPS_RTCM_DATA_DATA> = message
        .chunks(FRAGMENT_BYTES)
        .enumerate()
        .map(|(id, chunk)| data(1 | (id as u8) << 1 | seq, chunk))
        .collect();
    let n = out.len();
    if n < 4 && message.len().is_multiple_of(FRAGMENT_BYTES) {
        // Every fragment full and fewer than four: an empty one says the message ended.
        out.push(data(1 | (n as u8) << 1 | seq, &[]));
    }
    Ok(out)
}

fn data(flags: u8, bytes: &[u8]) -> GPS_RTCM_DATA_DATA {
    let mut d = [0u8; FRAGMENT_BYTES];
    d[..bytes.len()].copy_from_slice(bytes);
    GPS_RTCM_DATA_DATA {
        flags,
        len: bytes.len() as u8,
        data: d,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn message(n: usize) -> Vec<u8> {
        (0..n).map(|i| (i % 251) as u8).collect()
    }

    /// Reassembles as MAVLink's rule says an autopilot does.
    fn reassemble(frags: &[GPS_RTCM_DATA_DATA]) -> Vec<u8> {
        if frags.len() == 1 && frags[0].flags & 1 == 0 {
            return frags[0].data[..usize::from(frags[0].len)].to_vec();
        }
        let mut out = Vec::new();
        for (i, f) in frags.iter().enumerate() {
            assert_eq!(f.flags & 1, 1, "every fragment is marked fragmented");
            assert_eq!(usize::from((f.flags >> 1) & 3), i, "fragment ids in order");
            out.extend_from_slice(&f.data[..usize::from(f.len)]);
            if usize::from(f.len) < FRAGMENT_BYTES {
                assert_eq!(i, frags.len() - 1, "a short fragment ends the message");
            }
        }
        out
    }

    #[test]
    fn every_length_round_trips_with_its_sequence() {
        for n in [0, 1, 179, 180, 181, 359, 360, 361, 540, 719, 720] {
            let m = message(n);
            let f = fragments(&m, 37).unwrap();
            assert_eq!(reassemble(&f), m, "length {n}");
            assert!(f.iter().all(|f| f.flags >> 3 == 37 & 0x1F), "length {n}");
            assert!(f.len() <= 4);
        }
    }

    #[test]
    fn exact_multiples_end_with_an_empty_fragment() {
        let count = |n| fragments(&message(n), 0).unwrap().len();
        assert_eq!(
            (count(180), count(360), count(540), count(720)),
            (1, 3, 4, 4)
        );
        let f = fragments(&message(360), 2).unwrap();
        assert_eq!((f[2].len, f[2].flags), (0, 1 | 2 << 1 | 2 << 3));
    }

    #[test]
    fn a_message_over_four_fragments_is_refused() {
        assert_eq!(fragments(&message(721), 0), Err(TooLarge(721)));
    }
}
