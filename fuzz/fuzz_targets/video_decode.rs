//! Real cameras' video: arbitrary bytes as an H.264 Annex B byte stream through the
//! decoder the RTSP source uses (`skein_video::h264::H264Decoder`, OpenH264), NAL unit by
//! NAL unit and then whole, and every picture it makes through the scaler. Nothing may
//! panic or crash, and a picture is never larger than `MAX_SIDE_PX` a side.
#![no_main]

use libfuzzer_sys::fuzz_target;
use skein_video::h264::{H264Decoder, MAX_SIDE_PX};
use skein_video::scale::{RgbFrame, scale};

fn check(frame: Option<RgbFrame>) {
    if let Some(f) = frame {
        assert!(f.width_px as usize <= MAX_SIDE_PX && f.height_px as usize <= MAX_SIDE_PX);
        assert_eq!(f.rgb.len(), f.width_px as usize * f.height_px as usize * 3);
        let out = scale(f, 32, 24).expect("a decoded picture scales");
        assert_eq!(out.rgb.len(), 32 * 24 * 3);
    }
}

fuzz_target!(|data: &[u8]| {
    let mut decoder = H264Decoder::new().expect("a decoder");
    for nal in openh264::nal_units(data) {
        check(decoder.decode(nal).ok().flatten());
    }
    let mut decoder = H264Decoder::new().expect("a decoder");
    check(decoder.decode(data).ok().flatten());
});
