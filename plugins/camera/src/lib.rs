//! The camera payload plugin: frames for the vehicle's video stream, as JPEG.
//!
//! The frames come from a [`source::FrameSource`]. The one provided, `simulated`, renders
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
//!
//! # Commands
//! - `{"command": "capture"}`: capture, publish and describe one frame now →
//!   `{"frame": 12, "bytes": 23114, "width_px": 640, "height_px": 480, "pointing": {...}, "visible": [...]}`
//! - `{"command": "set_focal_length", "focal_length_mm": 12.0}` (within the zoom range)
//! - `{"command": "set_zoom", "zoom": 3.0}` (focal length = `focal_min_mm` × zoom)
//! - `{"command": "set_frame_rate", "frame_rate_hz": 10}`
//! - `{"command": "status"}`
//!
//! # Published state
//! ```json
//! {"source": "simulated", "width_px": 640, "height_px": 480, "frame_rate_hz": 5.0,
//!  "focal_length_mm": 4.0, "zoom": 1.0, "horizontal_fov_deg": 75.3, "vertical_fov_deg": 60.2,
//!  "frames": 120, "last_frame_bytes": 23114, "last_error": null,
//!  "pointing": {"azimuth_deg": 90.0, "elevation_deg": -10.0, "from": "gimbal"},
//!  "visible": [{"id": "uav-2", "x_px": 311.5, "y_px": 240.2, "depth_m": 41.0, "radius_px": 3.0}]}
//! ```

pub mod render;
pub mod source;

use render::Pinhole;
use skein_plugin_sdk::args::{self, in_range};
use skein_plugin_sdk::frame_meta::FrameMeta;
use skein_plugin_sdk::serde::Deserialize;
use skein_plugin_sdk::serde_json::{Value, json};
use skein_plugin_sdk::{Context, Plugin, export_plugin};
use source::{CapturedFrame, FrameData, FrameSource, SimulatedSource};

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

/// Where frames come from (`source`): the one provided renders the simulated world.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(crate = "skein_plugin_sdk::serde", rename_all = "snake_case")]
enum SourceKind {
    Simulated,
}

/// The configuration (see the crate docs): every field optional, ranges checked in
/// `create`. Pixel counts and the JPEG quality are read as numbers, as they
/// always were (`640.0` is 640).
#[derive(Deserialize)]
#[serde(crate = "skein_plugin_sdk::serde", deny_unknown_fields)]
struct Config {
    source: Option<SourceKind>,
    width_px: Option<f64>,
    height_px: Option<f64>,
    frame_rate_hz: Option<f64>,
    focal_length_mm: Option<f64>,
    focal_min_mm: Option<f64>,
    focal_max_mm: Option<f64>,
    sensor_width_mm: Option<f64>,
    jpeg_quality: Option<f64>,
    gimbal_slot: Option<String>,
    mount_pitch_deg: Option<f64>,
    mount_yaw_deg: Option<f64>,
    ground_down_m: Option<f64>,
    aircraft_span_m: Option<f64>,
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
}

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
        });
        if let (Some(s), Some(info)) = (s.as_object_mut(), self.last_info.as_object()) {
            for (k, v) in info {
                s.insert(k.clone(), v.clone());
            }
        }
        s
    }

    /// Captures, encodes and publishes one frame; returns its description.
    fn capture(&mut self, ctx: &Context) -> Result<Value, String> {
        let CapturedFrame {
            width_px,
            height_px,
            data,
            info,
            meta,
        } = self.source.capture(ctx, &self.optics)?;
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
        Ok(reply)
    }
}

impl Plugin for Camera {
    const NAME: &'static str = "camera";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");
    const KINDS: &'static [&'static str] = &["camera"];

    fn create(_kind: &str, config: Value, _ctx: &Context) -> Result<Self, String> {
        let c: Config = args::config(config)?;
        let focal_min_mm = in_range("focal_min_mm", c.focal_min_mm.unwrap_or(4.0), 0.5, 500.0)?;
        let focal_max_mm = in_range(
            "focal_max_mm",
            c.focal_max_mm.unwrap_or(48.0),
            focal_min_mm,
            2000.0,
        )?;
        let optics = Pinhole {
            width_px: in_range("width_px", c.width_px.unwrap_or(640.0), 16.0, 4096.0)? as u32,
            height_px: in_range("height_px", c.height_px.unwrap_or(480.0), 16.0, 4096.0)? as u32,
            focal_length_mm: in_range(
                "focal_length_mm",
                c.focal_length_mm.unwrap_or(focal_min_mm),
                focal_min_mm,
                focal_max_mm,
            )?,
            sensor_width_mm: in_range(
                "sensor_width_mm",
                c.sensor_width_mm.unwrap_or(6.17),
                1.0,
                100.0,
            )?,
        };
        let gimbal_slot = match c.gimbal_slot.as_deref() {
            None => Some("gimbal".to_string()),
            Some("") => None,
            Some(s) => Some(s.to_string()),
        };
        let source: Box<dyn FrameSource> = match c.source.unwrap_or(SourceKind::Simulated) {
            SourceKind::Simulated => Box::new(SimulatedSource {
                gimbal_slot,
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
        })
    }

    fn tick_rate_hz(&self) -> f64 {
        self.frame_rate_hz
    }

    fn tick(&mut self, ctx: &Context, _dt_s: f64) -> Result<(), String> {
        // A frame that cannot be made now (no position yet) is reported in the state, not
        // raised: the supervisor need not restart a camera waiting for its vehicle.
        if let Err(e) = self.capture(ctx) {
            if self.last_error.as_deref() != Some(e.as_str()) {
                ctx.log_warn(&format!("camera: no frame: {e}"));
            }
            self.last_error = Some(e);
        }
        ctx.publish_state(&self.state())
    }

    fn handle(&mut self, ctx: &Context, command: Value) -> Result<Value, String> {
        let reply = match args::command(command)? {
            Command::Capture => {
                let reply = self.capture(ctx)?;
                ctx.publish_state(&self.state())?;
                return Ok(reply);
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
