//! What a ground station sends to a simulated vehicle, built for
//! [`crate::VirtualVehicle::send`] or a socket (target 1/1, frame MAV_FRAME_LOCAL_NED):
//! heartbeats, commands, offboard setpoints with PX4's `type_mask` values, RTK
//! corrections in GPS_RTCM_DATA fragments.

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

/// Most fragments of one GPS_RTCM_DATA sequence (2-bit fragment id).
pub const GPS_RTCM_MAX_FRAGMENTS: usize = 4;

/// The GPS_RTCM_DATA messages carrying `rtcm` (a chunk of the RTCM3 byte stream, usually
/// one RTCM message) with sequence id `sequence` (its low 5 bits), by MAVLink's rules as
/// QGroundControl applies them: under 180 bytes one unfragmented message (`flags` =
/// sequence << 3); otherwise 180-byte fragments, `flags` = 1 | fragment id << 1 |
/// sequence << 3, and when the last fragment is full and fewer than 4 were sent, an
/// empty one after it (a reassembling receiver takes a sequence as complete at its first
/// short fragment).
///
/// # Errors
/// More than 4 × 180 = 720 bytes: one sequence cannot carry them.
pub fn gps_rtcm_data(rtcm: &[u8], sequence: u8) -> Result<Vec<MavMessage>, String> {
    const LEN: usize = 180;
    let max = GPS_RTCM_MAX_FRAGMENTS * LEN;
    if rtcm.len() > max {
        return Err(format!(
            "{} bytes of RTCM: one GPS_RTCM_DATA sequence carries at most {max}",
            rtcm.len()
        ));
    }
    let seq = (sequence & 0x1F) << 3;
    let message = |flags: u8, chunk: &[u8]| {
        let mut data = [0u8; LEN];
        data[..chunk.len()].copy_from_slice(chunk);
        MavMessage::GPS_RTCM_DATA(GPS_RTCM_DATA_DATA {
            flags,
            len: chunk.len() as u8,
            data,
        })
    };
    if rtcm.len() < LEN {
        return Ok(vec![message(seq, rtcm)]);
    }
    let mut out: Vec<MavMessage> = rtcm
        .chunks(LEN)
        .enumerate()
        .map(|(id, chunk)| message(1 | ((id as u8) << 1) | seq, chunk))
        .collect();
    if rtcm.len().is_multiple_of(LEN) && out.len() < GPS_RTCM_MAX_FRAGMENTS {
        out.push(message(1 | ((out.len() as u8) << 1) | seq, &[]));
    }
    Ok(out)
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
