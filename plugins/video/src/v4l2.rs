//! A V4L2 (Video4Linux2) camera as a source of decoded frames (`source = "v4l2:/dev/video0"`):
//! a USB (UVC) camera, or a CSI camera whose driver delivers a format read here, on the
//! companion computer. A thread of its own opens the device with `linuxvideo` (safe
//! ioctls, no C bindings), negotiates a format ([`choose_format`], `VIDIOC_S_FMT`; the
//! driver's answer is taken), streams through mmap buffers (`VIDIOC_REQBUFS`,
//! `VIDIOC_STREAMON`, `VIDIOC_DQBUF`/`VIDIOC_QBUF`) and converts each frame ([`to_rgb`]).
//!
//! The capture time is the buffer's arrival less the configured latency: linuxvideo does
//! not hand out the driver's buffer timestamps or sequence numbers, so lost frames are
//! not counted either (a USB camera drops what it cannot send, unseen). A buffer the
//! driver flags as corrupt (`V4L2_BUF_FLAG_ERROR`) or that is not a frame of the
//! negotiated format is counted `malformed`, an MJPEG frame that does not decode
//! `decode_error`. A device that cannot be opened, vanishes (unplugged: the poll reports
//! an error, `VIDIOC_DQBUF` fails) or gives no frame for the stall timeout ends the
//! session; it is reported and opened again with backoff ([`crate::input`]).

use crate::clock::wall_us;
use crate::h264::MAX_SIDE_PX;
use crate::image_msg::{ImageError, decode_compressed, decode_raw};
use crate::input::{BLOCKING_STEP, Shared, VideoInput};
use crate::scale::RgbFrame;
use linuxvideo::format::{FrameSizes, PixFormat, PixelFormat};
use linuxvideo::{BufType, CapabilityFlags, Device, Fract};
use rustix::event::{PollFd, PollFlags, Timespec, poll};
use rustix::io::Errno;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// The pixel formats this source reads, by V4L2 FourCC, in order of preference: Motion
/// JPEG (`V4L2_PIX_FMT_MJPEG`, `V4L2_PIX_FMT_JPEG`), YUYV 4:2:2 (`V4L2_PIX_FMT_YUYV`),
/// 24-bit RGB and BGR (`V4L2_PIX_FMT_RGB24`, `V4L2_PIX_FMT_BGR24`), 8-bit grey
/// (`V4L2_PIX_FMT_GREY`).
pub const READABLE: [[u8; 4]; 6] = [*b"MJPG", *b"JPEG", *b"YUYV", *b"RGB3", *b"BGR3", *b"GREY"];

/// What the source opens.
#[derive(Debug, Clone, PartialEq)]
pub struct V4l2Config {
    /// The device node (`/dev/video0`, `/dev/v4l/by-id/usb-…-video-index0`).
    pub device: PathBuf,
    /// Width asked of the device, pixels ([`choose_format`]); `None`: any.
    pub width_px: Option<u32>,
    /// Height asked of the device, pixels; `None`: any.
    pub height_px: Option<u32>,
    /// Frame rate asked of the driver, frames per second (`VIDIOC_S_PARM`; a driver that
    /// cannot set it keeps its own); `None`: the driver's.
    pub frame_rate_hz: Option<f64>,
    /// No frame decoded for this long: stalled, the device is closed and opened again.
    pub stall_timeout: Duration,
    /// Time from capture to the buffer's arrival, ms, subtracted from the arrival time.
    pub latency_ms: f64,
}

/// A pixel format a device offers (`VIDIOC_ENUM_FMT`) with its frame sizes
/// (`VIDIOC_ENUM_FRAMESIZES`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Offered {
    /// The FourCC (`*b"MJPG"`, `*b"YUYV"`, `*b"H264"` …).
    pub fourcc: [u8; 4],
    /// Sizes, (width, height) pixels: the discrete sizes, or for a stepwise range its
    /// bounds and the configured size clamped into it; empty when the driver does not
    /// enumerate them.
    pub sizes: Vec<(u32, u32)>,
}

/// A capture format (`struct v4l2_pix_format`): asked of the driver with `VIDIOC_S_FMT`
/// ([`choose_format`], `bytes_per_line` 0: the driver's choice), or the driver's answer,
/// which tells what each buffer holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    /// The FourCC, one of [`READABLE`].
    pub fourcc: [u8; 4],
    /// Width, pixels.
    pub width_px: u32,
    /// Height, pixels.
    pub height_px: u32,
    /// Bytes from one row to the next (`bytesperline`; 0: rows packed without padding).
    pub bytes_per_line: u32,
}

impl std::fmt::Display for Layout {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (w, h) = (self.width_px, self.height_px);
        write!(f, "{} {w}x{h}", name(self.fourcc))
    }
}

fn name(fourcc: [u8; 4]) -> String {
    PixelFormat::from_fourcc(fourcc).to_string()
}

/// Picks the format to ask `device` (named in the error) for among `offered`: the first
/// of [`READABLE`] it offers, at the smallest offered size at least `width_px` ×
/// `height_px` (the configured size itself when offered), else the largest (also when
/// no size is configured); sizes over [`MAX_SIDE_PX`] are not taken. A format whose
/// sizes are not enumerated is asked for at the configured size (else the largest
/// allowed) and the driver picks the nearest.
///
/// # Errors
/// The device offers none of [`READABLE`]: the message names the device and lists the
/// formats it offers, by FourCC with their largest size.
pub fn choose_format(
    device: &str,
    offered: &[Offered],
    width_px: Option<u32>,
    height_px: Option<u32>,
) -> Result<Layout, String> {
    let area = |&(w, h): &(u32, u32)| u64::from(w) * u64::from(h);
    let Some(format) = READABLE
        .iter()
        .find_map(|r| offered.iter().find(|o| o.fourcc == *r))
    else {
        let list: Vec<String> = offered
            .iter()
            .map(|o| match o.sizes.iter().max_by_key(|s| area(s)) {
                Some((w, h)) => format!("{} {w}x{h}", name(o.fourcc)),
                None => name(o.fourcc),
            })
            .collect();
        let readable: Vec<String> = READABLE.iter().map(|f| name(*f)).collect();
        let list = if list.is_empty() {
            "nothing".into()
        } else {
            list.join(", ")
        };
        return Err(format!(
            "{device} offers no format skein reads (it offers: {list}); readable: {}",
            readable.join(", ")
        ));
    };
    let max = MAX_SIDE_PX as u32;
    let sizes = format.sizes.iter().filter(|(w, h)| *w <= max && *h <= max);
    let covers = |&&(w, h): &&(u32, u32)| w >= width_px.unwrap_or(0) && h >= height_px.unwrap_or(0);
    let largest = sizes.clone().max_by_key(|s| area(s));
    let size = match (width_px, height_px) {
        (None, None) => largest,
        _ => sizes.filter(covers).min_by_key(|s| area(s)).or(largest),
    };
    let (w, h) = size
        .copied()
        .unwrap_or((width_px.unwrap_or(max), height_px.unwrap_or(max)));
    Ok(layout(format.fourcc, w, h, 0))
}

fn layout(fourcc: [u8; 4], width_px: u32, height_px: u32, bytes_per_line: u32) -> Layout {
    Layout {
        fourcc,
        width_px,
        height_px,
        bytes_per_line,
    }
}

/// One pixel of BT.601 limited-range YCbCr to RGB (see [`yuyv_to_rgb`]).
fn ycbcr(y: u8, u: u8, v: u8) -> [u8; 3] {
    let (c, d, e) = (i32::from(y) - 16, i32::from(u) - 128, i32::from(v) - 128);
    let clamp = |x: i32| ((x + 128) >> 8).clamp(0, 255) as u8;
    [
        clamp(298 * c + 409 * e),
        clamp(298 * c - 100 * d - 208 * e),
        clamp(298 * c + 516 * d),
    ]
}

/// Converts YUYV 4:2:2 (`V4L2_PIX_FMT_YUYV`: bytes `Y0 U Y1 V` for each pair of pixels,
/// rows `step` bytes apart) of `width` × `height` pixels to RGB, BT.601 limited range
/// (Y 16–235, U and V 16–240 around 128), in 8-bit fixed point:
/// `C = Y − 16, D = U − 128, E = V − 128`;
/// `R = (298 C + 409 E + 128) >> 8`, `G = (298 C − 100 D − 208 E + 128) >> 8`,
/// `B = (298 C + 516 D + 128) >> 8`, each clamped to 0–255
/// (`R = 1.164 C + 1.596 E`, `G = 1.164 C − 0.392 D − 0.813 E`, `B = 1.164 C + 2.017 D`).
///
/// # Errors
/// [`ImageError::Unsupported`]: an empty or oversized image, a step shorter than a row,
/// or fewer bytes than the rows need.
pub fn yuyv_to_rgb(w: u32, h: u32, step: usize, data: &[u8]) -> Result<RgbFrame, ImageError> {
    let (width, height) = (w as usize, h as usize);
    if width == 0 || height == 0 || width > MAX_SIDE_PX || height > MAX_SIDE_PX {
        return Err(ImageError::Unsupported(format!("a {w}x{h} YUYV frame")));
    }
    let row = width.div_ceil(2) * 4;
    let needed = step * (height - 1) + row;
    if step < row || data.len() < needed {
        let n = data.len();
        return Err(ImageError::Unsupported(format!(
            "{n} bytes of YUYV for {w}x{h} with rows {step} bytes apart (needs {needed})"
        )));
    }
    let mut rgb = Vec::with_capacity(width * height * 3);
    for line in data.chunks(step).take(height) {
        for (i, q) in line[..row].chunks_exact(4).enumerate() {
            rgb.extend_from_slice(&ycbcr(q[0], q[1], q[3]));
            if 2 * i + 1 < width {
                rgb.extend_from_slice(&ycbcr(q[2], q[1], q[3]));
            }
        }
    }
    Ok(RgbFrame {
        width_px: w,
        height_px: h,
        rgb,
    })
}

/// An APP0 `AVI1` segment (the mark of AVI's Motion JPEG) put after an MJPEG frame's SOI:
/// jpeg-decoder then supplies the standard Huffman tables (ITU-T T.81 K.3) that a frame
/// does not define itself. Most UVC cameras send MJPEG without a DHT segment, not all
/// of them with this mark.
const AVI1: [u8; 9] = [0xFF, 0xE0, 0, 7, b'A', b'V', b'I', b'1', 0];

/// Converts one buffer in `layout` to RGB: MJPEG decoded (without Huffman tables of its
/// own too), YUYV by [`yuyv_to_rgb`], RGB3, BGR3 and GREY rows copied.
///
/// # Errors
/// [`ImageError::Corrupt`]: an MJPEG frame that does not decode; [`ImageError::Unsupported`]:
/// a buffer that is not a frame of the layout (too short, not a JPEG, another format).
pub fn to_rgb(layout: &Layout, data: &[u8]) -> Result<RgbFrame, ImageError> {
    let (w, h) = (layout.width_px, layout.height_px);
    let step = |bytes_per_px: u32| match layout.bytes_per_line {
        0 => w.saturating_mul(bytes_per_px),
        n => n,
    };
    match &layout.fourcc {
        b"MJPG" | b"JPEG" if data.starts_with(&[0xFF, 0xD8]) => {
            decode_compressed("jpeg", &[&data[..2], &AVI1, &data[2..]].concat())
        }
        b"MJPG" | b"JPEG" => Err(ImageError::Unsupported("MJPEG without an SOI".into())),
        b"YUYV" => yuyv_to_rgb(w, h, step(2) as usize, data),
        b"RGB3" => decode_raw("rgb8", w, h, step(3), data),
        b"BGR3" => decode_raw("bgr8", w, h, step(3), data),
        b"GREY" => decode_raw("mono8", w, h, step(1), data),
        other => Err(ImageError::Unsupported(format!(
            "pixel format {}",
            name(*other)
        ))),
    }
}

/// Starts capturing from `config.device` on a thread of its own; it opens the device at
/// once and keeps trying. The source is reported as `v4l2:<device>`, transport `mmap`.
///
/// # Errors
/// The thread could not be started.
pub fn start(config: V4l2Config) -> Result<VideoInput, String> {
    let url = format!("v4l2:{}", config.device.display());
    VideoInput::spawn("skein-v4l2", url, "mmap", move |shared| {
        shared.sessions_blocking(|| {
            // linuxvideo asserts on driver answers it does not expect: a failed session,
            // not a dead thread.
            catch_unwind(AssertUnwindSafe(|| session(shared, &config))).unwrap_or_else(|_| {
                Err(format!(
                    "{}: unexpected driver answer",
                    config.device.display()
                ))
            })
        })
    })
}

/// The formats `device` offers for capture, with their sizes.
fn offered(device: &Device, config: &V4l2Config) -> std::io::Result<Vec<Offered>> {
    let fit = |want: Option<u32>, lo: u32, hi: u32| want.unwrap_or(hi).min(hi).max(lo);
    let sizes = |format| match device.frame_sizes(format) {
        Ok(FrameSizes::Discrete(s)) => s.iter().map(|s| (s.width(), s.height())).collect(),
        Ok(FrameSizes::Stepwise(r) | FrameSizes::Continuous(r)) => vec![
            (r.min_width(), r.min_height()),
            (
                fit(config.width_px, r.min_width(), r.max_width()),
                fit(config.height_px, r.min_height(), r.max_height()),
            ),
            (r.max_width(), r.max_height()),
        ],
        Err(_) => Vec::new(),
    };
    let formats = device.formats(BufType::VIDEO_CAPTURE);
    formats
        .map(|desc| desc.map(|d| (d.pixel_format().as_fourcc(), sizes(d.pixel_format()))))
        .map(|r| r.map(|(fourcc, sizes)| Offered { fourcc, sizes }))
        .collect()
}

/// One session: open, negotiate, stream until the device fails, vanishes or stalls, or
/// the camera drops the source (`Ok`).
fn session(shared: &Shared, config: &V4l2Config) -> Result<(), String> {
    let dev = config.device.display().to_string();
    let device = Device::open(&config.device).map_err(|e| match Errno::from_io_error(&e) {
        Some(Errno::NOTTY) => format!("{dev} is not a V4L2 device ({e})"),
        _ => format!("cannot open {dev}: {e}"),
    })?;
    let caps = device
        .capabilities()
        .map_err(|e| format!("{dev}: VIDIOC_QUERYCAP: {e}"))?;
    let caps = caps.device_capabilities();
    if !caps.contains(CapabilityFlags::VIDEO_CAPTURE | CapabilityFlags::STREAMING) {
        return Err(format!(
            "{dev} is not a single-planar video capture device with streaming I/O ({caps:?})"
        ));
    }
    let offered = offered(&device, config).map_err(|e| format!("{dev}: VIDIOC_ENUM_FMT: {e}"))?;
    let asked = choose_format(&dev, &offered, config.width_px, config.height_px)?;
    let (w, h, fourcc) = (asked.width_px, asked.height_px, asked.fourcc);
    let capture = device
        .video_capture(PixFormat::new(w, h, PixelFormat::from_fourcc(fourcc)))
        .map_err(|e| format!("{dev}: VIDIOC_S_FMT {asked}: {e}"))?;
    let f = capture.format();
    let (fourcc, line) = (f.pixel_format().as_fourcc(), f.bytes_per_line());
    let layout = layout(fourcc, f.width(), f.height(), line);
    if !READABLE.contains(&layout.fourcc) {
        return Err(format!("{dev} answered {layout} to VIDIOC_S_FMT {asked}"));
    }
    let rate_hz = config
        .frame_rate_hz
        .filter(|hz| hz.is_finite() && *hz > 0.0);
    if let Some(hz) = rate_hz {
        // VIDIOC_S_PARM: a driver that cannot set the rate keeps its own.
        let _ = capture.set_frame_interval(Fract::new(1000, (hz * 1000.0).round().max(1.0) as u32));
    }
    let mut stream = capture
        .into_stream()
        .map_err(|e| format!("{dev}: VIDIOC_REQBUFS/VIDIOC_STREAMON: {e}"))?;
    let wait = Timespec::try_from(BLOCKING_STEP.min(config.stall_timeout)).unwrap_or_default();
    let latency_us = (config.latency_ms.max(0.0) * 1000.0) as u64;
    let mut last_decoded = Instant::now();
    loop {
        if shared.stopping() {
            return Ok(());
        }
        if last_decoded.elapsed() >= config.stall_timeout {
            let s = config.stall_timeout.as_secs_f64();
            return Err(format!("no frame from {dev} for {s:.1} s"));
        }
        let mut fds = [PollFd::new(&stream, PollFlags::IN)];
        match poll(&mut fds, Some(&wait)) {
            Ok(0) | Err(Errno::INTR) => continue,
            Ok(_) if fds[0].revents().contains(PollFlags::IN) => {}
            Ok(_) => return Err(format!("{dev} stopped streaming (unplugged?)")),
            Err(e) => return Err(format!("{dev}: poll: {e}")),
        }
        let arrival_us = wall_us();
        // Copied out at once: the buffer goes back to the driver before decoding, and
        // reading a DMA buffer sequentially is fast where random access may be slow.
        let data = stream
            .dequeue(|buf| Ok((!buf.is_error()).then(|| buf.to_vec())))
            .map_err(|e| format!("{dev}: VIDIOC_DQBUF: {e} (unplugged?)"))?;
        match data.map(|d| to_rgb(&layout, &d)) {
            Some(Ok(frame)) => {
                last_decoded = Instant::now();
                let capture_us = arrival_us.saturating_sub(latency_us);
                shared.publish(frame, capture_us);
            }
            None | Some(Err(ImageError::Unsupported(_))) => shared.count(|d| d.malformed += 1),
            Some(Err(ImageError::Corrupt(_))) => shared.count(|d| d.decode_error += 1),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::status::SourceState;
    use jpeg_encoder::ColorType;

    fn offer(fourcc: &[u8; 4], sizes: &[(u32, u32)]) -> Offered {
        Offered {
            fourcc: *fourcc,
            sizes: sizes.to_vec(),
        }
    }

    fn config(device: PathBuf) -> V4l2Config {
        let stall_timeout = Duration::from_secs(5);
        let (width_px, height_px, frame_rate_hz, latency_ms) = (None, None, None, 0.0);
        V4l2Config {
            device,
            width_px,
            height_px,
            frame_rate_hz,
            stall_timeout,
            latency_ms,
        }
    }

    #[test]
    fn negotiation_prefers_mjpeg_then_yuyv_and_the_nearest_size() {
        let sizes = [(640, 480), (1280, 720), (1920, 1080), (8192, 4320)];
        let both = [offer(b"YUYV", &sizes), offer(b"MJPG", &sizes[..3])];
        let pick = |o: &[Offered], w, h| choose_format("/dev/video0", o, w, h).unwrap();
        let size = |l: Layout| (l.width_px, l.height_px);
        assert_eq!(
            pick(&both, Some(1280), Some(720)),
            layout(*b"MJPG", 1280, 720, 0)
        );
        assert_eq!(pick(&both[..1], Some(1280), Some(720)).fourcc, *b"YUYV");
        // The smallest size at least as large, else the largest (never over MAX_SIDE_PX).
        assert_eq!(size(pick(&both, Some(800), Some(600))), (1280, 720));
        assert_eq!(size(pick(&both, Some(1000), None)), (1280, 720));
        assert_eq!(size(pick(&both[..1], Some(5000), Some(5000))), (1920, 1080));
        assert_eq!(size(pick(&both[..1], None, None)), (1920, 1080));
        // Sizes not enumerated: the configured size, the driver adjusts it.
        let grey = pick(&[offer(b"GREY", &[])], Some(320), Some(240));
        assert_eq!(grey, layout(*b"GREY", 320, 240, 0));
        let rgb = [offer(b"BGR3", &[]), offer(b"RGB3", &[])];
        assert_eq!(pick(&rgb, None, None).to_string(), "RGB3 4096x4096");
    }

    #[test]
    fn a_device_without_a_readable_format_is_named_with_what_it_offers() {
        let h264 = offer(b"H264", &[(640, 480), (1920, 1080)]);
        let o = [h264, offer(b"NV12", &[(1280, 720)]), offer(b"RG10", &[])];
        let e = choose_format("/dev/video0", &o, None, None).unwrap_err();
        assert_eq!(
            e,
            "/dev/video0 offers no format skein reads (it offers: H264 1920x1080, NV12 1280x720, \
             RG10); readable: MJPG, JPEG, YUYV, RGB3, BGR3, GREY"
        );
        let e = choose_format("/dev/video2", &[], None, None).unwrap_err();
        assert!(e.starts_with("/dev/video2 offers no format skein reads (it offers: nothing)"));
    }

    #[test]
    fn yuyv_converts_with_bt601_limited_range_and_honours_the_row_stride() {
        // White and black, then two reds (Y 82, U 90, V 240), rows 6 bytes apart.
        let data = [235, 128, 16, 128, 0, 0, 82, 90, 82, 240];
        let f = yuyv_to_rgb(2, 2, 6, &data).unwrap();
        assert_eq!(f.rgb[..6], [255, 255, 255, 0, 0, 0]);
        for red in f.rgb[6..].chunks(3) {
            assert!(red[0] == 255 && red[1] <= 2 && red[2] <= 2, "{red:?}");
        }
        let grey = yuyv_to_rgb(3, 1, 8, &[126, 128, 126, 128, 126, 128, 0, 128]).unwrap();
        assert_eq!(
            grey.rgb, [128; 9],
            "odd width: the last pair's second pixel left out"
        );
        let padded = layout(*b"YUYV", 2, 2, 6);
        assert_eq!(to_rgb(&padded, &data).unwrap(), f);
        let packed = [&data[..4], &data[6..]].concat();
        assert_eq!(to_rgb(&layout(*b"YUYV", 2, 2, 0), &packed).unwrap(), f);
        // A buffer that is not a frame of the layout: refused with the reason.
        let e = to_rgb(&padded, &data[..9]).unwrap_err();
        assert!(matches!(&e, ImageError::Unsupported(w) if w.contains("needs 10")));
        assert!(yuyv_to_rgb(2, 1, 2, &data).is_err()); // step shorter than a row
        assert!(yuyv_to_rgb(0, 1, 4, &data).is_err());
    }

    #[test]
    fn mjpeg_without_huffman_tables_and_raw_formats_decode() {
        let rgb: Vec<u8> = (0..16 * 16).flat_map(|_| [200u8, 40, 10]).collect();
        let mut jpeg = Vec::new();
        let encoder = jpeg_encoder::Encoder::new(&mut jpeg, 90);
        encoder.encode(&rgb, 16, 16, ColorType::Rgb).unwrap();
        // Every DHT segment before the scan removed, as UVC cameras send MJPEG.
        let mut i = 2;
        while jpeg[i + 1] != 0xDA {
            let len = usize::from(u16::from_be_bytes([jpeg[i + 2], jpeg[i + 3]])) + 2;
            if jpeg[i + 1] == 0xC4 {
                jpeg.drain(i..i + len);
            } else {
                i += len;
            }
        }
        let plain = decode_compressed("jpeg", &jpeg);
        assert!(matches!(plain, Err(ImageError::Corrupt(_))));
        let mjpg = layout(*b"MJPG", 16, 16, 0);
        let f = to_rgb(&mjpg, &jpeg).unwrap();
        assert_eq!((f.width_px, f.height_px), (16, 16));
        assert!(f.rgb[0].abs_diff(200) < 8 && f.rgb[2].abs_diff(10) < 8);
        let half = to_rgb(&mjpg, &jpeg[..jpeg.len() / 2]);
        assert!(matches!(half, Err(ImageError::Corrupt(_))));
        let garbage = to_rgb(&mjpg, b"garbage");
        assert!(matches!(garbage, Err(ImageError::Unsupported(_))));
        // Raw formats, rows padded or packed (bytesperline 0).
        let bgr = to_rgb(&layout(*b"BGR3", 1, 2, 4), &[1, 2, 3, 0, 4, 5, 6]).unwrap();
        assert_eq!(bgr.rgb, [3, 2, 1, 6, 5, 4]);
        let grey = to_rgb(&layout(*b"GREY", 2, 1, 0), &[7, 9]).unwrap();
        assert_eq!(grey.rgb, [7, 7, 7, 9, 9, 9]);
        assert!(to_rgb(&layout(*b"RGB3", 2, 1, 0), &[1, 2, 3]).is_err()); // short
    }

    #[test]
    fn a_missing_device_and_a_file_that_is_no_device_fail_naming_them() {
        let file = std::env::temp_dir().join(format!("skein-v4l2-test-{}", std::process::id()));
        std::fs::write(&file, b"not a camera").unwrap();
        let missing = PathBuf::from("/dev/skein-no-such-video9");
        for (path, why) in [(&missing, "cannot open"), (&file, "is not a V4L2 device")] {
            let source = start(config(path.clone())).unwrap();
            let status = source.status_when(SourceState::Failed, Duration::from_secs(20));
            assert_eq!(status.state, SourceState::Failed, "{status:?}");
            let shown = path.display().to_string();
            assert_eq!(
                (status.url, status.transport),
                (format!("v4l2:{shown}"), "mmap")
            );
            let detail = status.detail.unwrap();
            let named = detail.contains(&shown) && detail.contains(why);
            assert!(named && detail.contains("again in"), "{detail}");
            let dropped = Instant::now();
            drop(source);
            assert!(dropped.elapsed() < Duration::from_secs(2)); // the thread stops at once
        }
        std::fs::remove_file(&file).unwrap();
    }

    /// The first capture device on this machine offering a format read here.
    fn capture_device() -> Option<PathBuf> {
        let mut paths: Vec<PathBuf> = std::fs::read_dir("/dev")
            .ok()?
            .flatten()
            .map(|e| e.path())
            .collect();
        paths.sort();
        paths.into_iter().find(|p| {
            let name = p.file_name().map(|n| n.to_string_lossy().into_owned());
            let video = name.is_some_and(|n| n.starts_with("video"));
            let Some(d) = video.then(|| Device::open(p).ok()).flatten() else {
                return false;
            };
            let capture = CapabilityFlags::VIDEO_CAPTURE | CapabilityFlags::STREAMING;
            let caps = d.capabilities().map(|c| c.device_capabilities());
            let readable = |o: Vec<Offered>| choose_format("", &o, None, None).is_ok();
            caps.is_ok_and(|c| c.contains(capture))
                && offered(&d, &config(p.clone())).is_ok_and(readable)
        })
    }

    #[test]
    fn captures_frames_from_a_real_device_when_one_is_present() {
        let Some(device) = capture_device() else {
            eprintln!("skipped: no V4L2 capture device (/dev/video*) on this machine");
            return;
        };
        let mut config = config(device.clone());
        (config.width_px, config.height_px) = (Some(640), Some(480));
        let source = start(config).unwrap();
        let deadline = Instant::now() + Duration::from_secs(20);
        let mut frames = Vec::new();
        while frames.len() < 3 && Instant::now() < deadline {
            frames.extend(source.take_latest());
            std::thread::sleep(Duration::from_millis(5));
        }
        let status = source.status();
        assert_eq!(frames.len(), 3, "{}: {status:?}", device.display());
        for f in &frames {
            let (w, h) = (f.frame.width_px, f.frame.height_px);
            assert!(w > 0 && h > 0 && f.frame.rgb.len() == (w * h * 3) as usize);
            let streamed = (status.stream_width_px, status.stream_height_px);
            assert_eq!((Some(w), Some(h)), streamed);
            assert!(f.capture_us > 0);
        }
    }
}
