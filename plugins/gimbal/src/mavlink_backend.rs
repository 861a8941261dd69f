//! The real-gimbal backend: Gimbal Protocol v2 messages to PX4's gimbal manager.

use crate::{GimbalConfig, RoiPoint, Target, YawFrame};
use skein_plugin_sdk::dialect::{
    GIMBAL_MANAGER_SET_PITCHYAW_DATA, GimbalManagerFlags, MavCmd, MavFrame,
};
use skein_plugin_sdk::geometry::NedFrame;
use skein_plugin_sdk::vehicle::Vehicle;
use skein_plugin_sdk::{
    CommandPosition, CommandTarget, Context, MavMessage, command_int, command_long,
};

/// Sender-side state of the mavlink backend.
#[derive(Debug, Default)]
pub struct LinkState {
    /// True once `MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE` (take control) was sent.
    configured: bool,
    /// Time of the last tracking setpoint, seconds of the instance's clock.
    last_track_send_s: Option<f64>,
}

/// `COMMAND_LONG` `command` to the gimbal manager of `vehicle` (first transmission).
fn to_manager(
    vehicle: &Vehicle,
    cfg: &GimbalConfig,
    command: MavCmd,
    params: [f32; 7],
) -> MavMessage {
    command_long(
        CommandTarget::new(vehicle.sysid, cfg.manager_compid),
        command,
        params,
        0,
    )
}

impl LinkState {
    /// Takes primary control of the gimbal manager: `MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE`
    /// with sysid/compid -2 ("set itself in control").
    ///
    /// # Errors
    /// When the vehicle or the link is not available.
    pub fn take_control(&mut self, ctx: &Context, cfg: &GimbalConfig) -> Result<(), String> {
        let vehicle = ctx.vehicle()?;
        ctx.send_mavlink(&to_manager(
            &vehicle,
            cfg,
            MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE,
            [
                -2.0,
                -2.0,
                -1.0,
                -1.0,
                0.0,
                0.0,
                f32::from(cfg.gimbal_device_id),
            ],
        ))?;
        self.configured = true;
        Ok(())
    }

    /// Releases control (sysid/compid -3, "remove control if currently in control").
    ///
    /// # Errors
    /// When the vehicle or the link is not available.
    pub fn release_control(&mut self, ctx: &Context, cfg: &GimbalConfig) -> Result<(), String> {
        let vehicle = ctx.vehicle()?;
        self.configured = false;
        ctx.send_mavlink(&to_manager(
            &vehicle,
            cfg,
            MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE,
            [
                -3.0,
                -3.0,
                -1.0,
                -1.0,
                0.0,
                0.0,
                f32::from(cfg.gimbal_device_id),
            ],
        ))
    }

    /// Sends `GIMBAL_MANAGER_SET_PITCHYAW` with angles (degrees; NaN = unchanged) in the
    /// given yaw frame.
    ///
    /// # Errors
    /// When the link cannot send.
    pub fn set_pitch_yaw(
        &mut self,
        ctx: &Context,
        cfg: &GimbalConfig,
        vehicle: &Vehicle,
        pitch_deg: f64,
        yaw_deg: f64,
        frame: YawFrame,
    ) -> Result<(), String> {
        let flags = match frame {
            // YAW_LOCK as well: older PX4 releases read it as "yaw in earth frame".
            YawFrame::Earth => {
                GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_YAW_IN_EARTH_FRAME
                    | GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_YAW_LOCK
            }
            YawFrame::Vehicle => GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_YAW_IN_VEHICLE_FRAME,
        };
        ctx.send_mavlink(&MavMessage::GIMBAL_MANAGER_SET_PITCHYAW(
            GIMBAL_MANAGER_SET_PITCHYAW_DATA {
                flags,
                pitch: pitch_deg.to_radians() as f32,
                yaw: yaw_deg.to_radians() as f32,
                pitch_rate: f32::NAN,
                yaw_rate: f32::NAN,
                target_system: vehicle.sysid,
                target_component: cfg.manager_compid,
                gimbal_device_id: cfg.gimbal_device_id,
            },
        ))
    }

    /// True (and remembers the time) when a tracking setpoint is due at `hz`.
    pub fn due_for_tracking(&mut self, now_s: f64, hz: f64) -> bool {
        let due = self
            .last_track_send_s
            .is_none_or(|last| now_s - last >= 1.0 / hz - 1e-9);
        if due {
            self.last_track_send_s = Some(now_s);
        }
        due
    }

    /// Sends what `target` means to the gimbal manager (a vehicle to track sends nothing
    /// now: the tick sends earth-frame setpoints toward it).
    ///
    /// # Errors
    /// When the link cannot send, or an ROI given in the swarm frame cannot be converted
    /// because the vehicle's position is unknown.
    pub fn send_target(
        &mut self,
        ctx: &Context,
        cfg: &GimbalConfig,
        vehicle: &Vehicle,
        target: &Target,
    ) -> Result<(), String> {
        if !self.configured {
            self.take_control(ctx, cfg)?;
        }
        let nan = f64::NAN;
        match target {
            Target::Angles {
                pitch_deg,
                yaw_deg,
                yaw_frame,
            } => self.set_pitch_yaw(
                ctx,
                cfg,
                vehicle,
                pitch_deg.unwrap_or(nan),
                yaw_deg.unwrap_or(nan),
                *yaw_frame,
            ),
            Target::Rates {
                pitch_rate_deg_s,
                yaw_rate_deg_s,
            } => ctx.send_mavlink(&MavMessage::GIMBAL_MANAGER_SET_PITCHYAW(
                GIMBAL_MANAGER_SET_PITCHYAW_DATA {
                    flags: GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_YAW_IN_VEHICLE_FRAME,
                    pitch: f32::NAN,
                    yaw: f32::NAN,
                    pitch_rate: pitch_rate_deg_s.to_radians() as f32,
                    yaw_rate: yaw_rate_deg_s.to_radians() as f32,
                    target_system: vehicle.sysid,
                    target_component: cfg.manager_compid,
                    gimbal_device_id: cfg.gimbal_device_id,
                },
            )),
            Target::RoiLocation(point) => {
                let geo = match point {
                    RoiPoint::Geo(g) => *g,
                    RoiPoint::Ned(p) => {
                        let pos = vehicle.position.ok_or(
                            "an ROI in the swarm frame needs the vehicle's position, not known yet",
                        )?;
                        NedFrame::new(pos.geo()).to_geo(*p - pos.ned())
                    }
                };
                let (x, y, _) = geo.to_mavlink();
                ctx.send_mavlink(&command_int(
                    CommandTarget::new(vehicle.sysid, cfg.manager_compid),
                    MavCmd::MAV_CMD_DO_SET_ROI_LOCATION,
                    [f32::from(cfg.gimbal_device_id), 0.0, 0.0, 0.0],
                    CommandPosition {
                        frame: MavFrame::MAV_FRAME_GLOBAL,
                        x,
                        y,
                        z: geo.alt_amsl_m as f32,
                    },
                ))
            }
            Target::RoiVehicle(_) => {
                // Cancel any ROI the autopilot follows; the tick takes over.
                self.last_track_send_s = None;
                ctx.send_mavlink(&to_manager(
                    vehicle,
                    cfg,
                    MavCmd::MAV_CMD_DO_SET_ROI_NONE,
                    [
                        f32::from(cfg.gimbal_device_id),
                        0.0,
                        0.0,
                        0.0,
                        0.0,
                        0.0,
                        0.0,
                    ],
                ))
            }
            Target::Neutral => ctx.send_mavlink(&MavMessage::GIMBAL_MANAGER_SET_PITCHYAW(
                GIMBAL_MANAGER_SET_PITCHYAW_DATA {
                    flags: GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_NEUTRAL
                        | GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_YAW_IN_VEHICLE_FRAME,
                    pitch: 0.0,
                    yaw: 0.0,
                    pitch_rate: f32::NAN,
                    yaw_rate: f32::NAN,
                    target_system: vehicle.sysid,
                    target_component: cfg.manager_compid,
                    gimbal_device_id: cfg.gimbal_device_id,
                },
            )),
        }
    }
}
