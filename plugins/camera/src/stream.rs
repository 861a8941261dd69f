//! A real camera as the camera's frame source: an RTSP/H.264 stream (`source =
//! "rtsp://…"`), a ROS 2 image topic (`"ros2:/topic"`) or a V4L2 device
//! (`"v4l2:/dev/video0"`), its frames decoded by `skein_video` on a thread of its own, taken here when the
//! camera wants one, rectified when the lens is calibrated or else scaled to the
//! configured size, and given the pose the vehicle and the gimbal had at the frame's
//! capture time ([`crate::pose`]).

use crate::pose::{PoseHistory, PoseSample};
use crate::render::Pinhole;
use crate::source::{CapturedFrame, FrameData, FrameSource, Mount, now_us, pose_info};
use skein_plugin_sdk::Context;
use skein_plugin_sdk::frame_meta::FrameMeta;
use skein_plugin_sdk::geometry::wrap_deg_360;
use skein_plugin_sdk::serde_json::{self, Value, json};
use skein_video::input::VideoInput;
use skein_video::rectify::Rectifier;
use skein_video::scale::{RgbFrame, scale};
use skein_video::status::SourceState;

/// How often the camera polls a stream (and samples the pose history), Hz.
pub const POLL_RATE_HZ: f64 = 25.0;

/// A real camera's frame source.
pub struct StreamSource {
    /// `"rtsp"`, `"ros2"` or `"v4l2"`.
    name: &'static str,
    input: VideoInput,
    mount: Mount,
    /// Output size; `None`: the stream's own.
    size_px: Option<(u32, u32)>,
    /// The calibrated lens's correction (`camera_info_file`).
    rectifier: Option<Rectifier>,
    poses: PoseHistory,
}

impl StreamSource {
    /// The camera's source `name` on the running `input`; frames come out at `size_px`
    /// (or the source's size), rectified by `rectifier` when the lens is calibrated,
    /// aimed by `mount`.
    pub fn new(
        name: &'static str,
        input: VideoInput,
        mount: Mount,
        size_px: Option<(u32, u32)>,
        rectifier: Option<Rectifier>,
    ) -> Self {
        StreamSource {
            name,
            input,
            mount,
            size_px,
            rectifier,
            poses: PoseHistory::default(),
        }
    }

    /// The decoded `frame` at the output size: rectified (after a filtered scale down to
    /// about that size, which bilinear sampling alone would alias), or scaled.
    fn output_frame(&mut self, frame: RgbFrame) -> Result<RgbFrame, String> {
        let (w, h) = self.size_px.unwrap_or((frame.width_px, frame.height_px));
        let Some(rectifier) = self.rectifier.as_mut() else {
            return scale(frame, w, h);
        };
        let frame = if frame.width_px > w {
            let h_kept = f64::from(frame.height_px) * f64::from(w) / f64::from(frame.width_px);
            scale(frame, w, (h_kept.round() as u32).max(1))?
        } else {
            frame
        };
        rectifier.rectify(&frame, w, h)
    }

    /// Adds the vehicle's and gimbal's pose now (the telemetry's age taken off) to the
    /// history; nothing while the vehicle's position is unknown.
    fn sample_pose(&mut self, ctx: &Context) -> Result<(), String> {
        let vehicle = ctx.vehicle()?;
        let Some(position) = vehicle.ned() else {
            return Ok(());
        };
        let (pitch_deg, yaw_deg, _) = self.mount.pointing(ctx);
        self.poses.push(PoseSample {
            stamp_us: now_us().saturating_sub(vehicle.link.last_seen_ms * 1000),
            position,
            heading_deg: vehicle.heading_deg,
            pitch_deg,
            yaw_deg,
        });
        Ok(())
    }
}

impl FrameSource for StreamSource {
    fn name(&self) -> &'static str {
        self.name
    }

    fn polls(&self) -> bool {
        true
    }

    fn poll_rate_hz(&self) -> f64 {
        POLL_RATE_HZ
    }

    fn status(&self) -> Option<Value> {
        serde_json::to_value(self.input.status()).ok()
    }

    fn capture(
        &mut self,
        ctx: &Context,
        optics: &Pinhole,
        take: bool,
    ) -> Result<Option<CapturedFrame>, String> {
        self.sample_pose(ctx)?;
        if !take {
            return Ok(None);
        }
        let Some(decoded) = self.input.take_latest() else {
            let status = self.input.status();
            return match status.state {
                SourceState::Streaming => Ok(None),
                state => Err(format!(
                    "{} {}: {}",
                    status.url,
                    serde_json::to_value(state)
                        .unwrap_or_default()
                        .as_str()
                        .unwrap_or("?"),
                    status.detail.as_deref().unwrap_or("no frame yet")
                )),
            };
        };
        let frame = self.output_frame(decoded.frame)?;
        let (width_px, height_px) = (frame.width_px, frame.height_px);
        let capture_us = decoded.capture_us;
        let lens = Pinhole {
            width_px,
            height_px,
            ..*optics
        };
        let (meta, info) = match self.poses.at(capture_us) {
            Some((pose, outside_us)) => {
                let meta = FrameMeta {
                    frame: 0,
                    stamp_us: capture_us,
                    north_m: pose.position.north_m,
                    east_m: pose.position.east_m,
                    down_m: pose.position.down_m,
                    azimuth_deg: wrap_deg_360(pose.heading_deg + pose.yaw_deg),
                    elevation_deg: pose.pitch_deg.clamp(-90.0, 90.0),
                    focal_px: lens.focal_px(),
                    width_px,
                    height_px,
                };
                let mut info = pose_info(&meta, "telemetry at capture time");
                info["pose_outside_history_ms"] = json!(outside_us as f64 / 1000.0);
                (Some(meta), info)
            }
            // No position yet: the video is shown, the detector skips frames without a pose.
            None => (None, json!({"pointing": null, "stamp_us": capture_us})),
        };
        let mut info = info;
        info["capture_latency_ms"] = json!(now_us().saturating_sub(capture_us) as f64 / 1000.0);
        info["visible"] = json!([]);
        info["camera_info"] = self.rectifier.as_ref().map_or(Value::Null, |r| {
            let c = r.calibration();
            json!({"camera_name": c.name, "width_px": c.width_px, "height_px": c.height_px,
                   "rectified": true})
        });
        Ok(Some(CapturedFrame {
            width_px,
            height_px,
            data: FrameData::Rgb8(frame.rgb),
            info,
            meta,
        }))
    }
}
