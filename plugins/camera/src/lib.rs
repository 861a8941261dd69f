//! The camera payload plugin: frames for the vehicle's video stream, as JPEG.
//!
//! The frames come from a [`source::FrameSource`]: a real camera ([`stream`]: an
//! RTSP/H.264 stream, `source = "rtsp://…"`, a ROS 2 camera node's image topic, `source =
//! "ros2:/camera/image_raw/compressed"`, or a V4L2 device, `source = "v4l2:/dev/video0"`
//! (asked for `width_px` × `height_px` at `frame_rate_hz`); decoded by `skein_video`, each frame
//! given the vehicle's and gimbal's pose interpolated at its capture time, its health in
//! the state's `source_status`), or `simulated` ([`simulated`]), which renders
//! what the vehicle would see: the other aircraft of the swarm projected through a pinhole
//! model from the vehicle's position and heading and the angles its gimbal publishes,
//! drawn over a sky/ground background split by the horizon; the focal length is the zoom.
//! The simulator's intruders (non-cooperative aircraft, `ctx.sim_aircraft()`) are drawn too,
//! as the different airframe they are and without labels: only image processing tells them
//! apart. Each tick captures a frame, encodes it as JPEG (`jpeg-encoder`) with the pose it
//! was taken with as XMP metadata (`skein_plugin_sdk::frame_meta`, as drone cameras carry
//! their gimbal angles) and publishes it with `publish_frame` (skein serves it as MJPEG and
//! snapshots; the `detector` plugin reads it).
//!
//! # Configuration (all optional)
//! `{"source": "simulated", "width_px": 640, "height_px": 480, "frame_rate_hz": 5,
//! "focal_length_mm": 4.0, "focal_min_mm": 4.0, "focal_max_mm": 48.0, "sensor_width_mm": 6.17,
//! "jpeg_quality": 75, "gimbal_slot": "gimbal", "mount_pitch_deg": 0, "mount_yaw_deg": 0,
//! "ground_down_m": 0, "aircraft_span_m": 1.0}`.
//! `frame_rate_hz` 0 captures only on command. `gimbal_slot` `""` means a fixed mount
//! (`mount_pitch_deg`, `mount_yaw_deg` relative to the vehicle), which is also used while
//! the gimbal has published no angles.
//! A real camera adds `"stall_timeout_s": 2.0`, `"latency_ms": 0` (capture to arrival,
//! for frames without their own capture time), for RTSP `"rtsp_transport": "tcp" |
//! "udp"`, for ROS 2 `"ros_domain_id": 0` (default `ROS_DOMAIN_ID`, else 0) and
//! `"dds_network": ["192.168.144.20"]` (the local addresses DDS may use; default all),
//! and takes `"horizontal_fov_deg"` instead of `focal_length_mm`, or
//! `"camera_info_file": "/etc/skein/camera_info/gimbal.yaml"` (its ROS/OpenCV
//! `camera_info` calibration: every frame is rectified into the ideal pinhole the
//! detector assumes, [`skein_video::rectify`], and the calibration gives the field of
//! view); `width_px`/`height_px` both or neither (the stream's own size); `frame_rate_hz`
//! caps what it publishes.
//!
//! # Commands
//! - `{"command": "capture"}`: capture, publish and describe one frame now →
//!   `{"frame": 12, "bytes": 23114, "width_px": 640, "height_px": 480, "pointing": {...}, "visible": [...]}`
//! - `{"command": "set_focal_length", "focal_length_mm": 12.0}` (within the zoom range)
//! - `{"command": "set_zoom", "zoom": 3.0}` (focal length = `focal_min_mm` × zoom)
//!
//! A real camera (RTSP, ROS 2, V4L2) refuses both zoom commands with the reason: its zoom is the
//! camera's own, and skein's pinhole model follows the configured field of view.
//! - `{"command": "set_frame_rate", "frame_rate_hz": 10}`
//! - `{"command": "status"}`
//!
//! # Published state
//! ```json
//! {"source": "simulated", "width_px": 640, "height_px": 480, "frame_rate_hz": 5.0,
//!  "focal_length_mm": 4.0, "zoom": 1.0, "horizontal_fov_deg": 75.3, "vertical_fov_deg": 60.2,
//!  "frames": 120, "last_frame_bytes": 23114, "last_error": null,
//!  "pointing": {"azimuth_deg": 90.0, "elevation_deg": -10.0, "from": "gimbal"},
//!  "visible": [{"id": "uav-2", "x_px": 311.5, "y_px": 240.2, "depth_m": 41.0, "radius_px": 3.0}],
//!  "source_status": null, "published_rate_hz": 5.0, "viewer_kbit_s": 925.0}
//! ```
//! `source_status` is a real source's health ([`skein_video::status::StreamStatus`]).

pub mod config;
pub mod pose;
pub mod render;
pub mod simulated;
pub mod source;
pub mod stream;

use config::{Config, SourceKind, lens_calibration, only_for, open_real};
use render::Pinhole;
use simulated::SimulatedSource;
use skein_plugin_sdk::args::{self, in_range};
use skein_plugin_sdk::frame_meta::FrameMeta;
use skein_plugin_sdk::serde::Deserialize;
use skein_plugin_sdk::serde_json::{Value, json};
use skein_plugin_sdk::{Context, Plugin, export_plugin};
use skein_video::recent::Recent;
use skein_video::rectify::Calibration;
use source::{CapturedFrame, FrameData, FrameSource, Mount};
use std::time::{Duration, Instant};

/// Encodes RGB8 pixels as a baseline JPEG, with the frame's pose as XMP metadata when
/// given (see `skein_plugin_sdk::frame_meta`).
///
/// # Errors
/// A size the encoder refuses (above 65535 px) or a buffer of the wrong length.
pub fn encode_jpeg(
    width_px: u32,
    height_px: u32,
    rgb: &[u8],
    quality: u8,
    meta: Option<&FrameMeta>,
) -> Result<Vec<u8>, String> {
    let (w, h) = (
        u16::try_from(width_px).map_err(|_| "frame too wide for JPEG")?,
        u16::try_from(height_px).map_err(|_| "frame too tall for JPEG")?,
    );
    let mut out = Vec::with_capacity(rgb.len() / 8);
    let mut encoder = jpeg_encoder::Encoder::new(&mut out, quality);
    if let Some(m) = meta {
        encoder
            .add_app_segment(1, &m.to_app1())
            .map_err(|e| format!("JPEG metadata refused: {e}"))?;
    }
    encoder
        .encode(rgb, w, h, jpeg_encoder::ColorType::Rgb)
        .map_err(|e| format!("JPEG encoding failed: {e}"))?;
    Ok(out)
}

/// The camera's commands (see the crate docs), tagged by `command`.
#[derive(Deserialize)]
#[serde(crate = "skein_plugin_sdk::serde")]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
enum Command {
    Capture,
    SetFocalLength { focal_length_mm: f64 },
    SetZoom { zoom: f64 },
    SetFrameRate { frame_rate_hz: f64 },
    Status,
}

/// One camera instance.
pub struct Camera {
    optics: Pinhole,
    focal_min_mm: f64,
    focal_max_mm: f64,
    frame_rate_hz: f64,
    jpeg_quality: u8,
    source: Box<dyn FrameSource>,
    frames: u64,
    last_frame_bytes: usize,
    last_info: Value,
    last_error: Option<String>,
    last_error_publish: Option<Instant>,
    /// The frames published in the last [`THROUGHPUT_WINDOW`], with their JPEG sizes.
    published: Recent<usize>,
}

/// How often a polled source's state is published while it fails the same way.
const ERROR_STATE_PERIOD: Duration = Duration::from_millis(500);

/// The window over which `published_rate_hz` and `viewer_kbit_s` are measured.
const THROUGHPUT_WINDOW: Duration = Duration::from_secs(3);

impl Camera {
    fn state(&self) -> Value {
        let mut s = json!({
            "source": self.source.name(),
            "width_px": self.optics.width_px,
            "height_px": self.optics.height_px,
            "frame_rate_hz": self.frame_rate_hz,
            "focal_length_mm": self.optics.focal_length_mm,
            "zoom": self.optics.focal_length_mm / self.focal_min_mm,
            "horizontal_fov_deg": self.optics.horizontal_fov_deg(),
            "vertical_fov_deg": self.optics.vertical_fov_deg(),
            "frames": self.frames,
            "last_frame_bytes": self.last_frame_bytes,
            "last_error": self.last_error,
            "pointing": Value::Null,
            "visible": [],
            "source_status": self.source.status(),
            "published_rate_hz": self.published_rate_hz(),
            "viewer_kbit_s": self.viewer_kbit_s(),
        });
        if let (Some(s), Some(info)) = (s.as_object_mut(), self.last_info.as_object()) {
            for (k, v) in info {
                s.insert(k.clone(), v.clone());
            }
        }
        s
    }

    /// Frames published per second over the last [`THROUGHPUT_WINDOW`].
    fn published_rate_hz(&self) -> f64 {
        self.published.rate_hz().unwrap_or(0.0)
    }

    /// What one viewer of the MJPEG stream costs: the JPEG bytes published per second,
    /// in kbit/s (every viewer gets every frame).
    fn viewer_kbit_s(&self) -> f64 {
        let sizes = self.published.values();
        let n = sizes.len();
        if n == 0 {
            return 0.0;
        }
        let mean_bytes = sizes.sum::<usize>() as f64 / n as f64;
        mean_bytes * 8.0 * self.published_rate_hz() / 1000.0
    }

    /// True when the camera should publish its next frame: `frame_rate_hz` caps it
    /// (with a tenth of a period of slack for tick jitter); 0 only on command.
    fn due(&self) -> bool {
        if self.frame_rate_hz <= 0.0 {
            return false;
        }
        self.published
            .last_at()
            .is_none_or(|t| t.elapsed().as_secs_f64() >= 0.9 / self.frame_rate_hz)
    }

    /// Captures, encodes and publishes one frame if the source has one (`take` false: a
    /// polled source only updates its history); returns its description.
    fn capture(&mut self, ctx: &Context, take: bool) -> Result<Option<Value>, String> {
        let Some(CapturedFrame {
            width_px,
            height_px,
            data,
            info,
            meta,
        }) = self.source.capture(ctx, &self.optics, take)?
        else {
            return Ok(None);
        };
        let meta = meta.map(|m| FrameMeta {
            frame: self.frames + 1,
            ..m
        });
        let jpeg = match data {
            FrameData::Jpeg(j) => j,
            FrameData::Rgb8(rgb) => {
                encode_jpeg(width_px, height_px, &rgb, self.jpeg_quality, meta.as_ref())?
            }
        };
        ctx.publish_frame(&jpeg)?;
        self.published.push(Instant::now(), jpeg.len());
        if self.source.polls() {
            // A real source's size is the stream's (or the configured output size).
            self.optics.width_px = width_px;
            self.optics.height_px = height_px;
        }
        self.frames += 1;
        self.last_frame_bytes = jpeg.len();
        self.last_info = info;
        self.last_error = None;
        let mut reply = json!({
            "frame": self.frames,
            "bytes": jpeg.len(),
            "width_px": width_px,
            "height_px": height_px,
        });
        if let (Some(r), Some(info)) = (reply.as_object_mut(), self.last_info.as_object()) {
            for (k, v) in info {
                r.insert(k.clone(), v.clone());
            }
        }
        Ok(Some(reply))
    }
}

impl Plugin for Camera {
    const NAME: &'static str = "camera";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");
    const KINDS: &'static [&'static str] = &["camera"];

    fn create(_kind: &str, config: Value, _ctx: &Context) -> Result<Self, String> {
        let c: Config = args::config(config)?;
        let kind = SourceKind::parse(c.source.as_deref().unwrap_or("simulated"))?;
        only_for(&kind, &c)?;
        let sensor_width_mm = in_range(
            "sensor_width_mm",
            c.sensor_width_mm.unwrap_or(6.17),
            1.0,
            100.0,
        )?;
        let calibration = lens_calibration(&kind, &c)?;
        let horizontal_fov_deg = c
            .horizontal_fov_deg
            .or(calibration.as_ref().map(Calibration::horizontal_fov_deg));
        // A real camera's lens is most often known by its field of view.
        let fov_focal_mm = match (horizontal_fov_deg, c.focal_length_mm) {
            (Some(_), Some(_)) => {
                return Err("horizontal_fov_deg: give it or focal_length_mm, not both".to_string());
            }
            (Some(fov), None) => {
                let fov = in_range("horizontal_fov_deg", fov, 1.0, 170.0)?;
                Some(sensor_width_mm / (2.0 * (fov.to_radians() / 2.0).tan()))
            }
            (None, _) => None,
        };
        let focal_min_mm = in_range(
            "focal_min_mm",
            c.focal_min_mm.or(fov_focal_mm).unwrap_or(4.0),
            0.5,
            500.0,
        )?;
        let focal_max_mm = in_range(
            "focal_max_mm",
            c.focal_max_mm.unwrap_or(48f64.max(focal_min_mm)),
            focal_min_mm,
            2000.0,
        )?;
        let size = |key: &str, v: Option<f64>| -> Result<Option<u32>, String> {
            v.map(|v| in_range(key, v, 16.0, 4096.0).map(|v| v as u32))
                .transpose()
        };
        let (width_px, height_px) = (
            size("width_px", c.width_px)?,
            size("height_px", c.height_px)?,
        );
        let optics = Pinhole {
            width_px: width_px.unwrap_or(640),
            height_px: height_px.unwrap_or(480),
            focal_length_mm: in_range(
                "focal_length_mm",
                c.focal_length_mm.or(fov_focal_mm).unwrap_or(focal_min_mm),
                focal_min_mm,
                focal_max_mm,
            )?,
            sensor_width_mm,
        };
        let mount = Mount {
            gimbal_slot: match c.gimbal_slot.as_deref() {
                None => Some("gimbal".to_string()),
                Some("") => None,
                Some(s) => Some(s.to_string()),
            },
            mount_pitch_deg: in_range(
                "mount_pitch_deg",
                c.mount_pitch_deg.unwrap_or(0.0),
                -90.0,
                90.0,
            )?,
            mount_yaw_deg: in_range(
                "mount_yaw_deg",
                c.mount_yaw_deg.unwrap_or(0.0),
                -180.0,
                180.0,
            )?,
        };
        let source: Box<dyn FrameSource> = match kind {
            SourceKind::Simulated => Box::new(SimulatedSource {
                mount,
                ground_down_m: in_range(
                    "ground_down_m",
                    c.ground_down_m.unwrap_or(0.0),
                    -10_000.0,
                    10_000.0,
                )?,
                aircraft_span_m: in_range(
                    "aircraft_span_m",
                    c.aircraft_span_m.unwrap_or(1.0),
                    0.05,
                    100.0,
                )?,
            }),
            real => {
                let size = match (width_px, height_px) {
                    (Some(w), Some(h)) => Some((w, h)),
                    (None, None) => None,
                    _ => return Err("width_px: give both width_px and height_px, or neither (the source's size)".into()),
                };
                Box::new(open_real(real, &c, mount, size, calibration)?)
            }
        };
        Ok(Camera {
            optics,
            focal_min_mm,
            focal_max_mm,
            frame_rate_hz: in_range("frame_rate_hz", c.frame_rate_hz.unwrap_or(5.0), 0.0, 60.0)?,
            jpeg_quality: in_range("jpeg_quality", c.jpeg_quality.unwrap_or(75.0), 1.0, 100.0)?
                as u8,
            source,
            frames: 0,
            last_frame_bytes: 0,
            last_info: Value::Null,
            last_error: None,
            last_error_publish: None,
            published: Recent::new(THROUGHPUT_WINDOW),
        })
    }

    fn tick_rate_hz(&self) -> f64 {
        if self.source.polls() {
            self.source.poll_rate_hz()
        } else {
            self.frame_rate_hz
        }
    }

    fn tick(&mut self, ctx: &Context, _dt_s: f64) -> Result<(), String> {
        // A frame that cannot be made now (no position yet, a stalled stream) is reported
        // in the state, not raised: the supervisor need not restart a camera waiting for
        // its vehicle or its stream.
        let take = !self.source.polls() || self.due();
        match self.capture(ctx, take) {
            Ok(Some(_)) => {}
            // Polled and nothing new: the state published with the last frame stands.
            Ok(None) => return Ok(()),
            Err(e) => {
                let changed = self.last_error.as_deref() != Some(e.as_str());
                if changed {
                    ctx.log_warn(&format!("camera: no frame: {e}"));
                }
                self.last_error = Some(e);
                // A polled source fails every tick while it is down: its state at most
                // twice a second, at once when the reason changes.
                if !changed
                    && self.source.polls()
                    && self
                        .last_error_publish
                        .is_some_and(|t| t.elapsed() < ERROR_STATE_PERIOD)
                {
                    return Ok(());
                }
                self.last_error_publish = Some(Instant::now());
            }
        }
        ctx.publish_state(&self.state())
    }

    fn handle(&mut self, ctx: &Context, command: Value) -> Result<Value, String> {
        let reply = match args::command(command)? {
            Command::Capture => {
                let reply = self
                    .capture(ctx, true)?
                    .ok_or("no new frame from the source since the last one")?;
                ctx.publish_state(&self.state())?;
                return Ok(reply);
            }
            Command::SetFocalLength { .. } | Command::SetZoom { .. } if self.source.polls() => {
                return Err(format!(
                    "a {} camera zooms on the camera itself: skein only knows its configured \
                     field of view ({:.1}°); set focal_length_mm or horizontal_fov_deg in the \
                     payload's config to match it",
                    self.source.name(),
                    self.optics.horizontal_fov_deg()
                ));
            }
            Command::SetFocalLength { focal_length_mm } => {
                self.optics.focal_length_mm = in_range(
                    "focal_length_mm",
                    focal_length_mm,
                    self.focal_min_mm,
                    self.focal_max_mm,
                )?;
                self.state()
            }
            Command::SetZoom { zoom } => {
                let zoom = in_range("zoom", zoom, 1.0, self.focal_max_mm / self.focal_min_mm)?;
                self.optics.focal_length_mm = self.focal_min_mm * zoom;
                self.state()
            }
            Command::SetFrameRate { frame_rate_hz } => {
                self.frame_rate_hz = in_range("frame_rate_hz", frame_rate_hz, 0.0, 60.0)?;
                self.state()
            }
            Command::Status => self.state(),
        };
        ctx.publish_state(&reply)?;
        Ok(reply)
    }
}

export_plugin!(Camera);
