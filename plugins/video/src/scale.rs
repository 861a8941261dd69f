//! Frames resized for the ground station and the detector (`width_px`/`height_px` of the
//! camera's config), by the `image` crate's triangle filter.

use image::{ImageBuffer, Rgb, imageops};

/// An RGB frame: `width_px * height_px * 3` bytes, 8 bits per channel, row-major.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RgbFrame {
    /// Width, pixels.
    pub width_px: u32,
    /// Height, pixels.
    pub height_px: u32,
    /// The pixels.
    pub rgb: Vec<u8>,
}

/// `frame` resized to `width_px` × `height_px` (unchanged when it already has that size).
///
/// # Errors
/// A buffer whose length is not `width_px * height_px * 3` of the frame's own size.
pub fn scale(frame: RgbFrame, width_px: u32, height_px: u32) -> Result<RgbFrame, String> {
    if frame.width_px == width_px && frame.height_px == height_px {
        return Ok(frame);
    }
    let (w, h) = (frame.width_px, frame.height_px);
    let img = ImageBuffer::<Rgb<u8>, _>::from_raw(w, h, frame.rgb)
        .ok_or_else(|| format!("a {w}x{h} frame with the wrong number of bytes"))?;
    let out = imageops::resize(&img, width_px, height_px, imageops::FilterType::Triangle);
    Ok(RgbFrame {
        width_px,
        height_px,
        rgb: out.into_raw(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn halves_a_frame_and_keeps_its_colour() {
        let frame = RgbFrame {
            width_px: 8,
            height_px: 4,
            rgb: [10u8, 200, 30].repeat(32),
        };
        let out = scale(frame.clone(), 4, 2).unwrap();
        assert_eq!((out.width_px, out.height_px, out.rgb.len()), (4, 2, 24));
        assert!(out.rgb.chunks(3).all(|p| p == [10, 200, 30]));
        assert_eq!(scale(frame.clone(), 8, 4).unwrap(), frame);
        let short = RgbFrame {
            rgb: vec![0; 5],
            ..frame
        };
        assert!(scale(short, 4, 2).is_err());
    }
}
