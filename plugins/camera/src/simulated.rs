//! The simulated frame source: what the vehicle would see, rendered.

use crate::render::{Aircraft, CameraPose, Pinhole, Scene, render};
use crate::source::{CapturedFrame, FrameData, FrameSource, Mount, now_us, pose_info};
use skein_plugin_sdk::Context;
use skein_plugin_sdk::frame_meta::FrameMeta;
use skein_plugin_sdk::geometry::wrap_deg_360;
use skein_plugin_sdk::serde_json::{Value, json};

/// Renders what the vehicle would see: the other aircraft of the swarm and the
/// simulator's intruders ([`Context::sim_aircraft`]) through a pinhole model, from the
/// vehicle's position and heading and the gimbal's angles.
#[derive(Debug, Clone, PartialEq)]
pub struct SimulatedSource {
    /// How the camera is aimed.
    pub mount: Mount,
    /// The ground plane's `down`, swarm frame, metres.
    pub ground_down_m: f64,
    /// Span of the drawn aircraft, metres.
    pub aircraft_span_m: f64,
}

impl FrameSource for SimulatedSource {
    fn name(&self) -> &'static str {
        "simulated"
    }

    /// Renders a frame whenever asked (`take` is always honoured: the camera ticks this
    /// source at its frame rate).
    fn capture(
        &mut self,
        ctx: &Context,
        optics: &Pinhole,
        _take: bool,
    ) -> Result<Option<CapturedFrame>, String> {
        let vehicle = ctx.vehicle()?;
        let position = vehicle.ned().ok_or("waiting for the vehicle's position")?;
        let (pitch, yaw, from) = self.mount.pointing(ctx);
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
        let stamp_us = now_us();
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
        let mut info = pose_info(&meta, from);
        // What was drawn, for evaluation (the simulator's truth, never in the image).
        info["visible"] = Value::Array(
            visible
                .iter()
                .map(|v| {
                    json!({
                        "id": v.id, "intruder": v.intruder, "x_px": v.x_px, "y_px": v.y_px,
                        "depth_m": v.depth_m, "radius_px": v.radius_px,
                    })
                })
                .collect(),
        );
        Ok(Some(CapturedFrame {
            width_px: optics.width_px,
            height_px: optics.height_px,
            data: FrameData::Rgb8(pixels),
            meta: Some(meta),
            info,
        }))
    }
}
