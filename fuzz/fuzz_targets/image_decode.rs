//! ROS 2 image messages: arbitrary bytes as the pixels of a `sensor_msgs/CompressedImage`
//! (JPEG, PNG, or told by its signature) or a `sensor_msgs/Image` (raw, with a size,
//! step and encoding taken from the input's head), through the decoders the ROS 2 image
//! source uses (`skein_video::image_msg`), and every image they make through the scaler.
//! Nothing may panic or crash, and an image is never larger than `MAX_SIDE_PX` a side.
//!
//! Input: byte 0 picks the message (0 JPEG, 1 PNG, 2 CompressedImage without a format,
//! 3 raw Image); for a raw Image bytes 1–6 are width, height and step (u16 LE each), byte
//! 7 the encoding; the rest is `data`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use skein_video::h264::MAX_SIDE_PX;
use skein_video::image_msg::{decode_compressed, decode_raw};
use skein_video::scale::scale;

const ENCODINGS: [&str; 6] = ["rgb8", "bgr8", "rgba8", "bgra8", "mono8", "yuv422"];

fuzz_target!(|input: &[u8]| {
    let Some((&kind, rest)) = input.split_first() else {
        return;
    };
    let frame = match kind % 4 {
        0 => decode_compressed("jpeg", rest),
        1 => decode_compressed("png", rest),
        2 => decode_compressed("", rest),
        _ => {
            if rest.len() < 7 {
                return;
            }
            let u16_at = |i: usize| u32::from(u16::from_le_bytes([rest[i], rest[i + 1]]));
            let encoding = ENCODINGS[usize::from(rest[6]) % ENCODINGS.len()];
            decode_raw(encoding, u16_at(0), u16_at(2), u16_at(4), &rest[7..])
        }
    };
    if let Ok(f) = frame {
        assert!(f.width_px as usize <= MAX_SIDE_PX && f.height_px as usize <= MAX_SIDE_PX);
        assert_eq!(f.rgb.len(), f.width_px as usize * f.height_px as usize * 3);
        let out = scale(f, 32, 24).expect("a decoded image scales");
        assert_eq!(out.rgb.len(), 32 * 24 * 3);
    }
});
