//! The pixels of ROS 2 image messages, decoded to RGB frames: `sensor_msgs/CompressedImage`
//! (JPEG by `jpeg-decoder`, PNG by `png`) and `sensor_msgs/Image` (raw `rgb8`, `bgr8`,
//! `rgba8`, `bgra8`, `mono8`). Pure functions on the message's fields, so that the fuzz
//! target `image_decode` reaches them without a DDS participant.

use crate::h264::MAX_SIDE_PX;
use crate::scale::RgbFrame;
use std::io::Cursor;

/// Why a message gave no frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ImageError {
    /// The message is not an image this source reads (an unsupported `format` or
    /// `encoding`, a size that does not match the data, a side over [`MAX_SIDE_PX`]);
    /// counted as `malformed`.
    Unsupported(String),
    /// The compressed data does not decode (a corrupt or truncated JPEG or PNG), with the
    /// decoder's reason; counted as `decode_error`.
    Corrupt(String),
}

impl std::fmt::Display for ImageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ImageError::Unsupported(why) => write!(f, "not a readable image: {why}"),
            ImageError::Corrupt(why) => write!(f, "image decoding failed: {why}"),
        }
    }
}

fn side_ok(width: u32, height: u32) -> Result<(), ImageError> {
    if width == 0 || height == 0 {
        return Err(ImageError::Unsupported(format!(
            "empty image ({width}x{height})"
        )));
    }
    if width as usize > MAX_SIDE_PX || height as usize > MAX_SIDE_PX {
        return Err(ImageError::Unsupported(format!(
            "{width}x{height} is larger than {MAX_SIDE_PX} px a side"
        )));
    }
    Ok(())
}

/// The codec a `sensor_msgs/CompressedImage` `format` names: `"jpeg"`, `"png"`, or
/// image_transport's `"bgr8; jpeg compressed bgr8"` / `"rgb8; png compressed rgb8"`; an
/// empty format is told by the data's signature.
fn codec(format: &str, data: &[u8]) -> Result<&'static str, ImageError> {
    let f = format.to_ascii_lowercase();
    if f.contains("compresseddepth") {
        return Err(ImageError::Unsupported(format!(
            "format \"{format}\" is a depth image"
        )));
    }
    if f.contains("jpeg") || f.contains("jpg") {
        return Ok("jpeg");
    }
    if f.contains("png") {
        return Ok("png");
    }
    if f.trim().is_empty() {
        if data.starts_with(&[0xFF, 0xD8]) {
            return Ok("jpeg");
        }
        if data.starts_with(b"\x89PNG") {
            return Ok("png");
        }
    }
    Err(ImageError::Unsupported(format!(
        "format \"{format}\": expected jpeg or png"
    )))
}

/// Decodes a `sensor_msgs/CompressedImage`'s `data` in `format` to RGB.
///
/// # Errors
/// [`ImageError`]: an unsupported format or size, or data that does not decode.
pub fn decode_compressed(format: &str, data: &[u8]) -> Result<RgbFrame, ImageError> {
    match codec(format, data)? {
        "jpeg" => decode_jpeg(data),
        _ => decode_png(data),
    }
}

fn decode_jpeg(data: &[u8]) -> Result<RgbFrame, ImageError> {
    let corrupt = |e: jpeg_decoder::Error| ImageError::Corrupt(format!("JPEG: {e}"));
    let mut d = jpeg_decoder::Decoder::new(data);
    d.set_max_decoding_buffer_size(MAX_SIDE_PX * MAX_SIDE_PX * 4);
    d.read_info().map_err(corrupt)?;
    let info = d
        .info()
        .ok_or_else(|| ImageError::Corrupt("JPEG: no frame header".into()))?;
    let (w, h) = (u32::from(info.width), u32::from(info.height));
    side_ok(w, h)?;
    let pixels = d.decode().map_err(corrupt)?;
    let n = w as usize * h as usize;
    let rgb = match info.pixel_format {
        jpeg_decoder::PixelFormat::RGB24 => pixels,
        jpeg_decoder::PixelFormat::L8 => pixels.iter().flat_map(|&l| [l, l, l]).collect(),
        jpeg_decoder::PixelFormat::L16 => pixels
            .chunks_exact(2)
            .flat_map(|l| [l[0], l[0], l[0]])
            .collect(),
        // Adobe CMYK as jpeg-decoder hands it (already inverted): RGB = (255 - C)(255 - K).
        jpeg_decoder::PixelFormat::CMYK32 => pixels
            .chunks_exact(4)
            .flat_map(|p| {
                let k = 255 - u16::from(p[3]);
                [0, 1, 2].map(|i| ((255 - u16::from(p[i])) * k / 255) as u8)
            })
            .collect(),
    };
    if rgb.len() != n * 3 {
        return Err(ImageError::Corrupt(format!(
            "JPEG: {} bytes decoded for {w}x{h}",
            rgb.len()
        )));
    }
    Ok(RgbFrame {
        width_px: w,
        height_px: h,
        rgb,
    })
}

fn decode_png(data: &[u8]) -> Result<RgbFrame, ImageError> {
    let corrupt = |e: png::DecodingError| ImageError::Corrupt(format!("PNG: {e}"));
    let mut d = png::Decoder::new_with_limits(
        Cursor::new(data),
        png::Limits {
            bytes: MAX_SIDE_PX * MAX_SIDE_PX * 8,
        },
    );
    d.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = d.read_info().map_err(corrupt)?;
    let (w, h) = (reader.info().width, reader.info().height);
    side_ok(w, h)?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| ImageError::Unsupported(format!("PNG: {w}x{h} is too large")))?;
    let mut buf = vec![0; size];
    let out = reader.next_frame(&mut buf).map_err(corrupt)?;
    buf.truncate(out.buffer_size());
    let channels = match out.color_type {
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        png::ColorType::Indexed => {
            return Err(ImageError::Unsupported("PNG: palette not expanded".into()));
        }
    };
    rows_to_rgb(&buf, w, h, out.line_size, channels, [0, 1, 2])
}

/// Rows of `channels`-byte pixels `step` bytes apart to RGB, the colour channels at
/// `order` (`[0, 1, 2]` RGB, `[2, 1, 0]` BGR); one or two channels: grey (and alpha).
fn rows_to_rgb(
    data: &[u8],
    width: u32,
    height: u32,
    step: usize,
    channels: usize,
    order: [usize; 3],
) -> Result<RgbFrame, ImageError> {
    let row = width as usize * channels;
    if step < row {
        return Err(ImageError::Unsupported(format!(
            "step {step} is shorter than a row of {width} pixels ({row} bytes)"
        )));
    }
    let needed = step * (height as usize - 1) + row;
    if data.len() < needed {
        return Err(ImageError::Unsupported(format!(
            "{} bytes of data for {width}x{height} with step {step} (needs {needed})",
            data.len()
        )));
    }
    let mut rgb = Vec::with_capacity(width as usize * height as usize * 3);
    for y in 0..height as usize {
        for p in data[y * step..y * step + row].chunks_exact(channels) {
            if channels < 3 {
                rgb.extend_from_slice(&[p[0], p[0], p[0]]);
            } else {
                rgb.extend_from_slice(&[p[order[0]], p[order[1]], p[order[2]]]);
            }
        }
    }
    Ok(RgbFrame {
        width_px: width,
        height_px: height,
        rgb,
    })
}

/// Decodes a `sensor_msgs/Image`: `width` x `height` pixels in `encoding` (`rgb8`,
/// `bgr8`, `rgba8`, `bgra8`, `mono8`; `sensor_msgs/image_encodings`), rows `step` bytes
/// apart in `data`.
///
/// # Errors
/// [`ImageError::Unsupported`]: another encoding, an empty or oversized image, a step
/// shorter than a row, or less data than the rows need.
pub fn decode_raw(
    encoding: &str,
    width: u32,
    height: u32,
    step: u32,
    data: &[u8],
) -> Result<RgbFrame, ImageError> {
    let (channels, order) = match encoding {
        "rgb8" => (3, [0, 1, 2]),
        "bgr8" => (3, [2, 1, 0]),
        "rgba8" => (4, [0, 1, 2]),
        "bgra8" => (4, [2, 1, 0]),
        "mono8" => (1, [0, 0, 0]),
        other => {
            return Err(ImageError::Unsupported(format!(
                "encoding \"{other}\": expected rgb8, bgr8, rgba8, bgra8 or mono8"
            )));
        }
    };
    side_ok(width, height)?;
    rows_to_rgb(data, width, height, step as usize, channels, order)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn jpeg(w: u16, h: u16, rgb: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        jpeg_encoder::Encoder::new(&mut out, 100)
            .encode(rgb, w, h, jpeg_encoder::ColorType::Rgb)
            .unwrap();
        out
    }

    fn png(w: u32, h: u32, color: png::ColorType, pixels: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        let mut e = png::Encoder::new(&mut out, w, h);
        e.set_color(color);
        e.set_depth(png::BitDepth::Eight);
        e.write_header().unwrap().write_image_data(pixels).unwrap();
        out
    }

    #[test]
    fn jpeg_and_png_decode_to_rgb_by_format_or_signature() {
        let rgb: Vec<u8> = (0..8 * 4).flat_map(|_| [200u8, 40, 10]).collect();
        let j = jpeg(8, 4, &rgb);
        for format in ["jpeg", "bgr8; jpeg compressed bgr8", ""] {
            let f = decode_compressed(format, &j).unwrap();
            assert_eq!((f.width_px, f.height_px, f.rgb.len()), (8, 4, 96));
            assert!(
                f.rgb[0].abs_diff(200) < 6 && f.rgb[2].abs_diff(10) < 6,
                "{:?}",
                &f.rgb[..3]
            );
        }
        let rgba: Vec<u8> = (0..3 * 2).flat_map(|i| [i as u8, 7, 9, 255]).collect();
        let p = png(3, 2, png::ColorType::Rgba, &rgba);
        for format in ["png", "rgb8; png compressed rgb8", ""] {
            let f = decode_compressed(format, &p).unwrap();
            assert_eq!(f.rgb[..6], [0, 7, 9, 1, 7, 9]);
        }
        let grey = png(2, 1, png::ColorType::Grayscale, &[5, 250]);
        assert_eq!(
            decode_compressed("png", &grey).unwrap().rgb,
            [5, 5, 5, 250, 250, 250]
        );
    }

    #[test]
    fn broken_and_foreign_images_are_refused_with_the_reason() {
        let rgb = vec![90u8; 16 * 16 * 3];
        let j = jpeg(16, 16, &rgb);
        let truncated = decode_compressed("jpeg", &j[..j.len() / 2]);
        assert!(
            matches!(truncated, Err(ImageError::Corrupt(_))),
            "{truncated:?}"
        );
        let garbage = decode_compressed("jpeg", b"not a jpeg at all");
        assert!(
            matches!(garbage, Err(ImageError::Corrupt(_))),
            "{garbage:?}"
        );
        let p = png(2, 2, png::ColorType::Rgb, &[1; 12]);
        let e = decode_compressed("png", &p[..p.len() - 20]).unwrap_err();
        assert!(matches!(e, ImageError::Corrupt(_)), "{e:?}");
        let e = decode_compressed("compressedDepth png", &p).unwrap_err();
        assert!(e.to_string().contains("depth"), "{e}");
        let e = decode_compressed("tiff", &p).unwrap_err();
        assert!(e.to_string().contains("\"tiff\""), "{e}");
        let e = decode_compressed("", b"GIF89a").unwrap_err();
        assert!(matches!(e, ImageError::Unsupported(_)), "{e:?}");
    }

    #[test]
    fn raw_images_are_read_in_their_encoding_and_step() {
        // 2x2 bgr8 with 2 bytes of padding per row.
        let data = [1, 2, 3, 4, 5, 6, 0, 0, 7, 8, 9, 10, 11, 12, 0, 0];
        let f = decode_raw("bgr8", 2, 2, 8, &data).unwrap();
        assert_eq!(f.rgb, [3, 2, 1, 6, 5, 4, 9, 8, 7, 12, 11, 10]);
        let f = decode_raw("rgb8", 2, 2, 8, &data).unwrap();
        assert_eq!(f.rgb[..6], [1, 2, 3, 4, 5, 6]);
        assert_eq!(
            decode_raw("mono8", 2, 1, 2, &[9, 80]).unwrap().rgb,
            [9, 9, 9, 80, 80, 80]
        );
        let f = decode_raw("bgra8", 1, 1, 4, &[1, 2, 3, 255]).unwrap();
        assert_eq!(f.rgb, [3, 2, 1]);
        // Errors name what is wrong.
        let e = decode_raw("yuv422", 2, 2, 4, &data).unwrap_err();
        assert!(e.to_string().contains("yuv422"), "{e}");
        let e = decode_raw("rgb8", 2, 2, 5, &data).unwrap_err();
        assert!(e.to_string().contains("step 5"), "{e}");
        let e = decode_raw("rgb8", 2, 3, 8, &data).unwrap_err();
        assert!(e.to_string().contains("needs 22"), "{e}");
        let e = decode_raw("rgb8", 0, 2, 8, &data).unwrap_err();
        assert!(e.to_string().contains("empty"), "{e}");
        let e = decode_raw("mono8", 5000, 1, 5000, &[0; 5000]).unwrap_err();
        assert!(e.to_string().contains("4096"), "{e}");
    }
}
