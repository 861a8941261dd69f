//! H.264 access units (Annex B byte stream, ITU-T H.264 Annex B) decoded to RGB frames by
//! Cisco's OpenH264 (the `openh264` crate, compiled from its bundled source).

use crate::scale::RgbFrame;
use openh264::decoder::Decoder;
use openh264::formats::YUVSource;

/// Why an access unit gave no frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DecodeError {
    /// Not an Annex B access unit: empty, or no start code (`00 00 01`) at its head.
    Malformed(&'static str),
    /// The decoder refused the bitstream (corrupt, truncated, or referring to parameter
    /// sets or frames it never received), with OpenH264's reason.
    Corrupt(String),
}

impl std::fmt::Display for DecodeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DecodeError::Malformed(why) => write!(f, "not an H.264 access unit: {why}"),
            DecodeError::Corrupt(why) => write!(f, "H.264 decoding failed: {why}"),
        }
    }
}

/// Largest frame decoded, pixels per side (4096: UHD and DCI 4K); larger sizes in a
/// (possibly forged) sequence parameter set are refused before any RGB buffer is made.
pub const MAX_SIDE_PX: usize = 4096;

/// One H.264 stream's decoder: feed it the stream's access units in order.
pub struct H264Decoder {
    decoder: Decoder,
}

impl H264Decoder {
    /// A decoder waiting for the stream's first parameter sets (SPS, PPS) and key frame.
    ///
    /// # Errors
    /// OpenH264 failed to create a decoder (out of memory).
    pub fn new() -> Result<Self, String> {
        Ok(H264Decoder {
            decoder: Decoder::new().map_err(|e| format!("no H.264 decoder: {e}"))?,
        })
    }

    /// Decodes one access unit (Annex B: start-code-prefixed NAL units, parameter sets
    /// before key frames). `Ok(None)` when the unit completes no picture (parameter sets
    /// alone, or the decoder still waiting for a key frame).
    ///
    /// # Errors
    /// [`DecodeError`]: the unit is dropped, the decoder goes on with the next one (it
    /// recovers at the next key frame).
    pub fn decode(&mut self, access_unit: &[u8]) -> Result<Option<RgbFrame>, DecodeError> {
        if access_unit.is_empty() {
            return Err(DecodeError::Malformed("empty"));
        }
        if !(access_unit.starts_with(&[0, 0, 1]) || access_unit.starts_with(&[0, 0, 0, 1])) {
            return Err(DecodeError::Malformed("no Annex B start code"));
        }
        let yuv = match self.decoder.decode(access_unit) {
            Ok(Some(yuv)) => yuv,
            Ok(None) => return Ok(None),
            Err(e) => return Err(DecodeError::Corrupt(e.to_string())),
        };
        let (w, h) = yuv.dimensions();
        if w == 0 || h == 0 || w > MAX_SIDE_PX || h > MAX_SIDE_PX {
            return Err(DecodeError::Corrupt(format!("a {w}x{h} picture")));
        }
        let mut rgb = vec![0u8; yuv.rgb8_len()];
        yuv.write_rgb8(&mut rgb);
        Ok(Some(RgbFrame {
            width_px: w as u32,
            height_px: h as u32,
            rgb,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use openh264::encoder::Encoder;
    use openh264::formats::{RgbSliceU8, YUVBuffer};

    /// A 64x48 picture: a dark square on a light background at `(x, y)`.
    fn picture(x: usize, y: usize) -> Vec<u8> {
        let mut rgb = vec![220u8; 64 * 48 * 3];
        for row in y..y + 8 {
            for col in x..x + 8 {
                rgb[(row * 64 + col) * 3..][..3].copy_from_slice(&[20, 20, 20]);
            }
        }
        rgb
    }

    /// Access units of an encoded sequence, as an RTSP source hands them over.
    fn encoded(pictures: &[Vec<u8>]) -> Vec<Vec<u8>> {
        let mut enc = Encoder::new().unwrap();
        pictures
            .iter()
            .map(|p| {
                let yuv = YUVBuffer::from_rgb8_source(RgbSliceU8::new(p, (64, 48)));
                enc.encode(&yuv).unwrap().to_vec()
            })
            .collect()
    }

    #[test]
    fn decodes_what_the_encoder_made_where_it_drew_it() {
        let units = encoded(&[picture(8, 8), picture(40, 30)]);
        let mut d = H264Decoder::new().unwrap();
        let frames: Vec<RgbFrame> = units.iter().filter_map(|u| d.decode(u).unwrap()).collect();
        assert_eq!(frames.len(), 2);
        let f = &frames[1];
        assert_eq!((f.width_px, f.height_px), (64, 48));
        let px = |x: usize, y: usize| f.rgb[(y * 64 + x) * 3];
        assert!(px(44, 34) < 80, "the square is dark: {}", px(44, 34));
        assert!(
            px(12, 12) > 160,
            "where it was is light again: {}",
            px(12, 12)
        );
    }

    #[test]
    fn garbage_and_truncation_are_errors_and_the_decoder_recovers() {
        let units = encoded(&[picture(8, 8), picture(16, 16), picture(24, 24)]);
        let mut d = H264Decoder::new().unwrap();
        assert_eq!(d.decode(&[]), Err(DecodeError::Malformed("empty")));
        assert!(matches!(
            d.decode(b"RTSP/1.0 200 OK"),
            Err(DecodeError::Malformed(_))
        ));
        // A key frame cut in half: refused or no picture, never a panic.
        let cut = &units[0][..units[0].len() / 2];
        assert!(!matches!(d.decode(cut), Ok(Some(_))));
        // Garbage behind a start code.
        let mut junk = vec![0, 0, 0, 1];
        junk.extend((0..400u32).map(|i| (i * 7919 % 251) as u8));
        assert!(!matches!(d.decode(&junk), Ok(Some(_))));
        // A fresh decoder given the whole stream decodes it all.
        let mut d = H264Decoder::new().unwrap();
        assert_eq!(
            units
                .iter()
                .filter(|u| matches!(d.decode(u), Ok(Some(_))))
                .count(),
            3
        );
    }
}
