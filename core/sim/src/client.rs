//! What a ground station sends to a simulated vehicle, built for
//! [`crate::VirtualVehicle::send`] or a socket (target 1/1, frame MAV_FRAME_LOCAL_NED):
//! heartbeats, commands, offboard setpoints with PX4's `type_mask` values.

use skein_mavlink::MavMessage;
use skein_mavlink::dialect::*;
use skein_model::geo::Ned;

/// `type_mask` position + yaw (2552).
pub const POSITION_YAW: u16 = 2552;
/// `type_mask` position + velocity feed-forward + yaw (2496).
pub const POSITION_VELOCITY_YAW: u16 = 2496;
/// `type_mask` position + velocity and acceleration feed-forward + yaw (2048).
pub const POSITION_VELOCITY_ACCELERATION_YAW: u16 = 2048;

/// A MAV_TYPE_GCS HEARTBEAT (keeps PX4's GCS-loss failsafe away).
pub fn gcs_heartbeat() -> MavMessage {
    heartbeat(MavType::MAV_TYPE_GCS)
}

/// The HEARTBEAT of a component of type `mavtype` that is not an autopilot (a ground
/// station, an onboard controller).
pub fn heartbeat(mavtype: MavType) -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    })
}

/// COMMAND_LONG `cmd` with `params` 1–7.
pub fn command(cmd: MavCmd, p: [f32; 7]) -> MavMessage {
    skein_mavlink::command_long(skein_mavlink::CommandTarget::new(1, 1), cmd, p, 0)
}

/// SET_POSITION_TARGET_LOCAL_NED: position (m), velocity (m/s), acceleration (m/s²),
/// all local NED, yaw (rad); `type_mask` says which are used.
pub fn setpoint(type_mask: u16, p: Ned, v: Ned, a: Ned, yaw_rad: f64) -> MavMessage {
    MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
        time_boot_ms: 0,
        x: p.north_m as f32,
        y: p.east_m as f32,
        z: p.down_m as f32,
        vx: v.north_m as f32,
        vy: v.east_m as f32,
        vz: v.down_m as f32,
        afx: a.north_m as f32,
        afy: a.east_m as f32,
        afz: a.down_m as f32,
        yaw: yaw_rad as f32,
        yaw_rate: 0.0,
        type_mask: PositionTargetTypemask::from_bits_retain(type_mask),
        target_system: 1,
        target_component: 1,
        coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
    })
}

/// The last LOCAL_POSITION_NED in `msgs`: (time s, position m, velocity m/s).
pub fn last_estimate(msgs: &[(f64, MavMessage)]) -> Option<(f64, Ned, Ned)> {
    msgs.iter().rev().find_map(|(t, m)| match m {
        MavMessage::LOCAL_POSITION_NED(p) => Some((
            *t,
            Ned::new(p.x.into(), p.y.into(), p.z.into()),
            Ned::new(p.vx.into(), p.vy.into(), p.vz.into()),
        )),
        _ => None,
    })
}
