//! Frame sources: where the camera's images come from. [`crate::simulated`] renders the
//! swarm; [`crate::stream`] decodes a real camera's RTSP/H.264 stream. Each hands back RGB
//! (or already encoded JPEG) frames with the pose they were taken with.

use crate::render::Pinhole;
use skein_plugin_sdk::Context;
use skein_plugin_sdk::frame_meta::FrameMeta;
use skein_plugin_sdk::serde_json::{Value, json};

/// Pixels of one frame.
#[derive(Debug, Clone, PartialEq)]
pub enum FrameData {
    /// RGB, 8 bits per channel, row-major, `width_px * height_px * 3` bytes; the camera
    /// encodes it to JPEG.
    Rgb8(Vec<u8>),
    /// An already encoded baseline JPEG image.
    Jpeg(Vec<u8>),
}

/// One captured frame.
#[derive(Debug, Clone, PartialEq)]
pub struct CapturedFrame {
    /// Width, pixels.
    pub width_px: u32,
    /// Height, pixels.
    pub height_px: u32,
    /// The pixels.
    pub data: FrameData,
    /// Source-specific metadata merged into the camera's state (the simulated source:
    /// `pointing`, `position`, `stamp_us` and `visible`).
    pub info: Value,
    /// The pose the frame was taken with, written into the JPEG (XMP) for whoever
    /// processes the frame; the camera sets the frame number.
    pub meta: Option<FrameMeta>,
}

/// A source of frames for the camera.
pub trait FrameSource: Send {
    /// The source's name, shown in the camera's state (`"simulated"`, `"rtsp"`).
    fn name(&self) -> &'static str;

    /// Captures one frame with the given optics (size and focal length). `take` false:
    /// the camera polls without wanting a frame (not due yet); a source that keeps
    /// history (the vehicle's pose) updates it and returns `Ok(None)`.
    ///
    /// `Ok(None)` also when a real source has no new frame since the last one.
    ///
    /// # Errors
    /// When no frame can be made now (the vehicle's position is unknown, the stream is
    /// stalled or not open); the camera reports it in its state and tries again on the
    /// next tick.
    fn capture(
        &mut self,
        ctx: &Context,
        optics: &Pinhole,
        take: bool,
    ) -> Result<Option<CapturedFrame>, String>;

    /// True for a source the camera polls faster than it publishes (a stream delivering
    /// frames at its own rate): the camera then ticks at [`FrameSource::poll_rate_hz`]
    /// and asks for a frame only when one is due.
    fn polls(&self) -> bool {
        false
    }

    /// How often the camera ticks for a polled source, Hz.
    fn poll_rate_hz(&self) -> f64 {
        0.0
    }

    /// The source's health for the camera's state (`source_status`), `None` for a
    /// source that cannot fail (the simulated one).
    fn status(&self) -> Option<Value> {
        None
    }
}

/// How the camera is aimed: by a gimbal that publishes its angles, or a fixed mount.
#[derive(Debug, Clone, PartialEq)]
pub struct Mount {
    /// Slot of the gimbal whose published `pitch_deg`/`yaw_deg` (yaw relative to the
    /// vehicle) aim the camera; `None` for a fixed mount.
    pub gimbal_slot: Option<String>,
    /// Pitch of a fixed mount (or while the gimbal has published nothing), degrees.
    pub mount_pitch_deg: f64,
    /// Yaw of a fixed mount relative to the vehicle, degrees.
    pub mount_yaw_deg: f64,
}

impl Mount {
    /// The camera's pointing now (pitch, yaw relative to the vehicle, degrees) and where
    /// it came from (`"gimbal"` or `"mount"`).
    pub fn pointing(&self, ctx: &Context) -> (f64, f64, &'static str) {
        if let Some(slot) = &self.gimbal_slot
            && let Ok(Some(state)) = ctx.payload_state(slot)
            && let (Some(p), Some(y)) = (state["pitch_deg"].as_f64(), state["yaw_deg"].as_f64())
        {
            return (p, y, "gimbal");
        }
        (self.mount_pitch_deg, self.mount_yaw_deg, "mount")
    }
}

/// The `pointing` and `position` objects of a frame's info (the camera's state).
pub fn pose_info(meta: &FrameMeta, from: &str) -> Value {
    json!({
        "pointing": {
            "azimuth_deg": meta.azimuth_deg,
            "elevation_deg": meta.elevation_deg,
            "from": from,
        },
        "position": {
            "north_m": meta.north_m,
            "east_m": meta.east_m,
            "down_m": meta.down_m,
        },
        "stamp_us": meta.stamp_us,
    })
}

/// Wall-clock µs since the Unix epoch: the frames' capture stamps (`FrameMeta::stamp_us`),
/// on the clock the real sources stamp with.
pub use skein_video::clock::wall_us as now_us;
