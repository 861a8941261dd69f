//! The detector payload plugin: finds aircraft in the camera's frames by image processing
//! and reports each as a bearing in the swarm frame, for the coordinator's tracker.
//!
//! Each tick it takes the latest frame its vehicle's camera published
//! (`ctx.payload_frame(camera_slot)`), skips it if it already processed it, decodes the
//! JPEG (`jpeg-decoder`), reads the pose the frame was taken with from the frame's own XMP
//! metadata (`skein_plugin_sdk::frame_meta`: camera position, optical axis, focal length),
//! finds the aircraft-like blobs ([`blobs`]: darker than the local background, compact,
//! connected components) and turns each blob's centroid into a bearing (azimuth clockwise
//! from north, elevation above the horizontal) through the pinhole model. It knows nothing
//! the camera did not see: swarm members are detected too (the tracker drops them by
//! their known poses).
//!
//! # Configuration (all optional)
//! `{"camera_slot": "camera", "rate_hz": 10, "threshold": 50, "min_area_px": 6,
//!   "background_radius_px": 12, "max_size_px": 160, "max_aspect": 3.0, "min_fill": 0.3,
//!   "join_gap": 0.5, "max_detections": 20}` (see [`blobs`] for what each one tunes).
//!
//! # State and events
//! Each processed frame goes into the state (the tracker and the dashboard read it there),
//! as `last` and at the end of `recent` (the frames of the last [`RECENT_S`] seconds, at
//! least `last`, oldest first, so a reader polling slower than the frame rate misses no
//! frame):
//! ```json
//! {"frame": 12, "stamp_us": 1700000000000000, "camera_slot": "camera",
//!  "observer": {"north_m": 0.0, "east_m": 5.0, "down_m": -10.0},
//!  "detections": [{"box_px": {"x": 311, "y": 200, "width": 7, "height": 6},
//!                  "center_px": {"x": 314.4, "y": 203.1},
//!                  "azimuth_deg": 12.5, "elevation_deg": 4.1,
//!                  "angular_size_deg": 0.9, "confidence": 0.8}]}
//! ```
//! `angular_size_deg` (the blob's larger side as an angle) is `null` for blobs under
//! [`MIN_SIZED_BLOB_PX`]: a distant aircraft is a blur of a few pixels whatever its size.
//! State: `{"camera_slot", "frames", "detections_total", "last_frame", "last_error",
//! "last": {…}, "recent": [{…}]}`.
//!
//! A payload event (something that happened, for the event log) only when the number of
//! aircraft in view changes: kind `detections_changed`,
//! `{"frame": 12, "stamp_us": 1700000000000000, "count": 2, "previous": 1}`.
//!
//! # Commands
//! `{"command": "status"}`, `{"command": "detect"}` (process the latest frame now, even if
//! it was processed before; replies with the frame's detections object).

pub mod blobs;

use blobs::{Blob, BlobParams, find_blobs};
use skein_plugin_sdk::args::{self, in_range};
use skein_plugin_sdk::frame_meta::FrameMeta;
use skein_plugin_sdk::geometry::{Ned, direction, look_angles};
use skein_plugin_sdk::serde::Deserialize;
use skein_plugin_sdk::serde_json::{Value, json};
use skein_plugin_sdk::{Context, Plugin, export_plugin};

/// Blobs narrower than this (pixels) get no `angular_size_deg`: too small to measure.
pub const MIN_SIZED_BLOB_PX: f64 = 8.0;

/// Payload event kind raised when the number of detections changes.
pub const DETECTIONS_CHANGED_EVENT: &str = "detections_changed";

/// How far back the state's `recent` frames go, seconds.
pub const RECENT_S: f64 = 0.5;

/// The bearing through pixel `(u, v)` of a frame taken with `meta`: `(azimuth_deg,
/// elevation_deg)` in the swarm frame. Pixel coordinates from the top-left corner (pixel
/// centres at +0.5), principal point at the image centre, square pixels, no roll (the
/// camera's model, `plugins/camera/src/render.rs`).
pub fn pixel_bearing(meta: &FrameMeta, u: f64, v: f64) -> (f64, f64) {
    let forward = direction(meta.azimuth_deg, meta.elevation_deg);
    let (s, c) = meta.azimuth_deg.to_radians().sin_cos();
    let right = Ned::new(-s, c, 0.0);
    let down = forward.cross(&right);
    let du = (u - f64::from(meta.width_px) / 2.0) / meta.focal_px;
    let dv = (v - f64::from(meta.height_px) / 2.0) / meta.focal_px;
    let ray = forward + right * du + down * dv;
    let a = look_angles(Ned::default(), ray).expect("a ray through the image is never zero");
    (a.azimuth_deg, a.elevation_deg)
}

/// Confidence of a blob, 0..1: more contrast and more pixels, more confidence.
fn confidence(b: &Blob, threshold: f64) -> f64 {
    let contrast = ((b.contrast - threshold) / (2.0 * threshold)).clamp(0.0, 1.0);
    let size = (b.area as f64 / 30.0).min(1.0);
    (0.3 + 0.4 * contrast + 0.3 * size).min(1.0)
}

/// The detections object of one decoded frame (the state's `last`).
pub fn detections(meta: &FrameMeta, blobs: &[Blob], threshold: f64, camera_slot: &str) -> Value {
    let list: Vec<Value> = blobs
        .iter()
        .map(|b| {
            let (az, el) = pixel_bearing(meta, b.cx, b.cy);
            // A blob a few pixels wide is the optics' blur as much as the aircraft: its
            // size only bounds the range, so it is not reported.
            let size_px = f64::from(b.width.max(b.height));
            let angular_size_deg = (size_px >= MIN_SIZED_BLOB_PX)
                .then(|| 2.0 * (size_px / 2.0 / meta.focal_px).atan().to_degrees());
            json!({
                "box_px": {"x": b.x, "y": b.y, "width": b.width, "height": b.height},
                "center_px": {"x": b.cx, "y": b.cy},
                "azimuth_deg": az,
                "elevation_deg": el,
                "angular_size_deg": angular_size_deg,
                "confidence": confidence(b, threshold),
            })
        })
        .collect();
    json!({
        "frame": meta.frame,
        "stamp_us": meta.stamp_us,
        "camera_slot": camera_slot,
        "observer": {"north_m": meta.north_m, "east_m": meta.east_m, "down_m": meta.down_m},
        "detections": list,
    })
}

/// Decodes a JPEG frame: its pose metadata and RGB8 pixels.
///
/// # Errors
/// Not a decodable JPEG, not RGB, or no skein pose metadata.
pub fn decode_frame(jpeg: &[u8]) -> Result<(FrameMeta, Vec<u8>), String> {
    let mut d = jpeg_decoder::Decoder::new(jpeg);
    let pixels = d
        .decode()
        .map_err(|e| format!("frame is not a JPEG: {e}"))?;
    let info = d.info().ok_or("JPEG without a header")?;
    if info.pixel_format != jpeg_decoder::PixelFormat::RGB24 {
        return Err(format!("frame is {:?}, not RGB", info.pixel_format));
    }
    let meta = FrameMeta::from_xmp(
        d.xmp_data()
            .ok_or("frame carries no pose metadata (XMP): cannot turn pixels into bearings")?,
    )?;
    if (u32::from(info.width), u32::from(info.height)) != (meta.width_px, meta.height_px) {
        return Err("frame size differs from its metadata".into());
    }
    Ok((meta, pixels))
}

/// The configuration (see the crate docs): every field optional, ranges checked in
/// `create`; counts are read as numbers, as they always were.
#[derive(Deserialize)]
#[serde(crate = "skein_plugin_sdk::serde", deny_unknown_fields)]
struct Config {
    camera_slot: Option<String>,
    rate_hz: Option<f64>,
    threshold: Option<f64>,
    min_area_px: Option<f64>,
    background_radius_px: Option<f64>,
    max_size_px: Option<f64>,
    max_aspect: Option<f64>,
    min_fill: Option<f64>,
    join_gap: Option<f64>,
    max_detections: Option<f64>,
}

/// The detector's two commands: `status`, and `detect` (the latest frame, now).
#[derive(Deserialize)]
#[serde(crate = "skein_plugin_sdk::serde")]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
enum Command {
    Status,
    Detect,
}

/// One detector instance.
pub struct Detector {
    camera_slot: String,
    rate_hz: f64,
    params: BlobParams,
    max_detections: usize,
    frames: u64,
    detections_total: u64,
    last_frame: Option<u64>,
    last: Value,
    /// The frames of the last [`RECENT_S`], oldest first.
    recent: std::collections::VecDeque<Value>,
    /// Detections in the last frame (`None` before the first).
    last_count: Option<usize>,
    last_error: Option<String>,
}

impl Detector {
    fn state(&self) -> Value {
        json!({
            "camera_slot": self.camera_slot,
            "rate_hz": self.rate_hz,
            "frames": self.frames,
            "detections_total": self.detections_total,
            "last_frame": self.last_frame,
            "last_error": self.last_error,
            "last": self.last,
            "recent": self.recent,
        })
    }

    /// Keeps `frame` in `recent` and drops the frames older than [`RECENT_S`] before it.
    /// A frame processed again (the `detect` command) replaces its first account.
    fn remember(&mut self, frame: &Value, stamp_us: u64) {
        if self
            .recent
            .back()
            .is_some_and(|b| b["frame"] == frame["frame"])
        {
            self.recent.pop_back();
        }
        self.recent.push_back(frame.clone());
        let horizon_us = (RECENT_S * 1e6) as u64;
        while self.recent.len() > 1
            && self
                .recent
                .front()
                .and_then(|f| f["stamp_us"].as_u64())
                .is_some_and(|s| stamp_us.saturating_sub(s) > horizon_us)
        {
            self.recent.pop_front();
        }
    }

    /// Processes the camera's latest frame (`force`: even when already processed).
    /// Returns the frame's detections object, `None` when there is no new frame.
    fn process(&mut self, ctx: &Context, force: bool) -> Result<Option<Value>, String> {
        let Some(jpeg) = ctx.payload_frame(&self.camera_slot)? else {
            return Err(format!(
                "waiting for frames from slot `{}`",
                self.camera_slot
            ));
        };
        let (meta, pixels) = decode_frame(&jpeg)?;
        if !force && self.last_frame == Some(meta.frame) {
            return Ok(None);
        }
        let mut blobs = find_blobs(&pixels, meta.width_px, meta.height_px, &self.params);
        blobs.truncate(self.max_detections);
        let ev = detections(&meta, &blobs, self.params.threshold, &self.camera_slot);
        if self.last_count != Some(blobs.len()) {
            ctx.emit_event(
                DETECTIONS_CHANGED_EVENT,
                &json!({"frame": meta.frame, "stamp_us": meta.stamp_us,
                        "count": blobs.len(), "previous": self.last_count}),
            )?;
            self.last_count = Some(blobs.len());
        }
        self.remember(&ev, meta.stamp_us);
        self.frames += 1;
        self.detections_total += blobs.len() as u64;
        self.last_frame = Some(meta.frame);
        self.last = ev.clone();
        self.last_error = None;
        Ok(Some(ev))
    }
}

impl Plugin for Detector {
    const NAME: &'static str = "detector";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");
    const KINDS: &'static [&'static str] = &["detector"];

    fn create(_kind: &str, config: Value, _ctx: &Context) -> Result<Self, String> {
        let c: Config = args::config(config)?;
        let d = BlobParams::default();
        Ok(Detector {
            camera_slot: c.camera_slot.unwrap_or_else(|| "camera".to_string()),
            rate_hz: in_range("rate_hz", c.rate_hz.unwrap_or(10.0), 0.0, 60.0)?,
            params: BlobParams {
                background_radius_px: in_range(
                    "background_radius_px",
                    c.background_radius_px
                        .unwrap_or(f64::from(d.background_radius_px)),
                    2.0,
                    200.0,
                )? as u32,
                threshold: in_range("threshold", c.threshold.unwrap_or(d.threshold), 1.0, 255.0)?,
                min_area_px: in_range(
                    "min_area_px",
                    c.min_area_px.unwrap_or(d.min_area_px as f64),
                    1.0,
                    1e6,
                )? as usize,
                max_size_px: in_range(
                    "max_size_px",
                    c.max_size_px.unwrap_or(f64::from(d.max_size_px)),
                    2.0,
                    4096.0,
                )? as u32,
                max_aspect: in_range(
                    "max_aspect",
                    c.max_aspect.unwrap_or(d.max_aspect),
                    1.0,
                    100.0,
                )?,
                min_fill: in_range("min_fill", c.min_fill.unwrap_or(d.min_fill), 0.0, 1.0)?,
                join_gap: in_range("join_gap", c.join_gap.unwrap_or(d.join_gap), 0.0, 10.0)?,
            },
            max_detections: in_range(
                "max_detections",
                c.max_detections.unwrap_or(20.0),
                1.0,
                1000.0,
            )? as usize,
            frames: 0,
            detections_total: 0,
            last_frame: None,
            last: Value::Null,
            recent: std::collections::VecDeque::new(),
            last_count: None,
            last_error: None,
        })
    }

    fn tick_rate_hz(&self) -> f64 {
        self.rate_hz
    }

    fn tick(&mut self, ctx: &Context, _dt_s: f64) -> Result<(), String> {
        // No frame yet (or a bad one) is reported in the state, not raised: the supervisor
        // need not restart a detector waiting for its camera.
        match self.process(ctx, false) {
            Ok(None) => return Ok(()),
            Ok(Some(_)) => {}
            Err(e) => {
                if self.last_error.as_deref() != Some(e.as_str()) {
                    ctx.log_debug(&format!("detector: {e}"));
                }
                self.last_error = Some(e);
            }
        }
        ctx.publish_state(&self.state())
    }

    fn handle(&mut self, ctx: &Context, command: Value) -> Result<Value, String> {
        match args::command(command)? {
            Command::Detect => {
                let ev = self.process(ctx, true)?.unwrap_or(Value::Null);
                ctx.publish_state(&self.state())?;
                Ok(ev)
            }
            Command::Status => Ok(self.state()),
        }
    }
}

export_plugin!(Detector);

#[cfg(test)]
mod tests {
    use super::*;

    fn meta() -> FrameMeta {
        FrameMeta {
            frame: 1,
            stamp_us: 0,
            north_m: 0.0,
            east_m: 0.0,
            down_m: -10.0,
            azimuth_deg: 30.0,
            elevation_deg: -10.0,
            focal_px: 400.0,
            width_px: 640,
            height_px: 480,
        }
    }

    #[test]
    fn the_image_centre_looks_along_the_axis_and_right_is_clockwise() {
        let m = meta();
        let (az, el) = pixel_bearing(&m, 320.0, 240.0);
        assert!((az - 30.0).abs() < 1e-9 && (el + 10.0).abs() < 1e-9);
        let (az_r, _) = pixel_bearing(&m, 420.0, 240.0);
        assert!(az_r > 30.0);
        let (_, el_up) = pixel_bearing(&m, 320.0, 140.0);
        assert!(el_up > -10.0);
        // 100 px right of centre at f = 400 px, level camera: atan(0.25) = 14.04°.
        let level = FrameMeta {
            elevation_deg: 0.0,
            ..m
        };
        let (az, el) = pixel_bearing(&level, 420.0, 240.0);
        assert!((az - 30.0 - 0.25f64.atan().to_degrees()).abs() < 1e-9 && el.abs() < 1e-9);
    }
}
