//! Frame sources: where the camera's images come from. The simulated source renders the
//! swarm; a V4L2 or RTSP source would implement [`FrameSource`] the same way and hand back
//! JPEG (MJPEG cameras) or RGB frames.

use crate::render::{Aircraft, CameraPose, Pinhole, Scene, render};
use skein_plugin_sdk::Context;
use skein_plugin_sdk::frame_meta::FrameMeta;
use skein_plugin_sdk::geometry::wrap_deg_360;
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
    /// The source's name, shown in the camera's state (`"simulated"`).
    fn name(&self) -> &'static str;

    /// Captures one frame with the given optics (size and focal length).
    ///
    /// # Errors
    /// When no frame can be made now (the vehicle's position is unknown, the device is
    /// gone); the camera reports it in its state and tries again on the next tick.
    fn capture(&mut self, ctx: &Context, optics: &Pinhole) -> Result<CapturedFrame, String>;
}

/// Renders what the vehicle would see: the other aircraft of the swarm and the
/// simulator's intruders ([`Context::sim_aircraft`]) through a pinhole model, from the
/// vehicle's position and heading and the gimbal's angles.
#[derive(Debug, Clone, PartialEq)]
pub struct SimulatedSource {
    /// Slot of the gimbal whose published `pitch_deg`/`yaw_deg` (yaw relative to the
    /// vehicle) aim the camera; `None` for a fixed mount.
    pub gimbal_slot: Option<String>,
    /// Pitch of a fixed mount (or while the gimbal has published nothing), degrees.
    pub mount_pitch_deg: f64,
    /// Yaw of a fixed mount relative to the vehicle, degrees.
    pub mount_yaw_deg: f64,
    /// The ground plane's `down`, swarm frame, metres.
    pub ground_down_m: f64,
    /// Span of the drawn aircraft, metres.
    pub aircraft_span_m: f64,
}

impl SimulatedSource {
    /// The camera's pointing (pitch, yaw relative to the vehicle) and where it came from.
    fn pointing(&self, ctx: &Context) -> (f64, f64, &'static str) {
        if let Some(slot) = &self.gimbal_slot
            && let Ok(Some(state)) = ctx.payload_state(slot)
            && let (Some(p), Some(y)) = (state["pitch_deg"].as_f64(), state["yaw_deg"].as_f64())
        {
            return (p, y, "gimbal");
        }
        (self.mount_pitch_deg, self.mount_yaw_deg, "mount")
    }
}

impl FrameSource for SimulatedSource {
    fn name(&self) -> &'static str {
        "simulated"
    }

    fn capture(&mut self, ctx: &Context, optics: &Pinhole) -> Result<CapturedFrame, String> {
        let vehicle = ctx.vehicle()?;
        let position = vehicle.ned().ok_or("waiting for the vehicle's position")?;
        let (pitch, yaw, from) = self.pointing(ctx);
        let pose = CameraPose {
            position,
            azimuth_deg: wrap_deg_360(vehicle.heading_deg + yaw),
            elevation_deg: pitch.clamp(-90.0, 90.0),
        };
        let mut aircraft: Vec<Aircraft> = ctx
            .swarm()?
            .into_iter()
            .filter(|v| v.id != vehicle.id)
            .filter_map(|v| {
                Some(Aircraft {
                    position: v.ned()?,
                    id: v.id,
                    span_m: None,
                    intruder: false,
                })
            })
            .collect();
        // The simulator's non-cooperative aircraft, only when this vehicle is simulated.
        if ctx.simulated() {
            aircraft.extend(ctx.sim_aircraft()?.into_iter().map(|a| Aircraft {
                position: a.ned(),
                span_m: Some(a.span_m),
                id: a.id,
                intruder: true,
            }));
        }
        let stamp_us = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_micros() as u64);
        let scene = Scene {
            pose,
            ground_down_m: self.ground_down_m,
            aircraft,
            aircraft_span_m: self.aircraft_span_m,
        };
        let (pixels, visible) = render(optics, &scene);
        let meta = FrameMeta {
            frame: 0,
            stamp_us,
            north_m: position.north_m,
            east_m: position.east_m,
            down_m: position.down_m,
            azimuth_deg: pose.azimuth_deg,
            elevation_deg: pose.elevation_deg,
            focal_px: optics.focal_px(),
            width_px: optics.width_px,
            height_px: optics.height_px,
        };
        Ok(CapturedFrame {
            width_px: optics.width_px,
            height_px: optics.height_px,
            data: FrameData::Rgb8(pixels),
            meta: Some(meta),
            info: json!({
                "pointing": {
                    "azimuth_deg": pose.azimuth_deg,
                    "elevation_deg": pose.elevation_deg,
                    "from": from,
                },
                "position": {
                    "north_m": position.north_m,
                    "east_m": position.east_m,
                    "down_m": position.down_m,
                },
                "stamp_us": stamp_us,
                // What was drawn, for evaluation (the simulator's truth, never in the image).
                "visible": visible.iter().map(|v| json!({
                    "id": v.id, "intruder": v.intruder, "x_px": v.x_px, "y_px": v.y_px,
                    "depth_m": v.depth_m, "radius_px": v.radius_px,
                })).collect::<Vec<_>>(),
            }),
        })
    }
}
