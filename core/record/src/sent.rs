//! What a recording keeps of a MAVLink message skein sent (`skein.SentMessage`).

use serde_json::{Value, json};
use skein_mavlink::MavMessage;

/// `msg` sent to `sysid` as JSON: setpoints and commands with their fields, anything
/// else by name.
pub(crate) fn sent_json(sysid: u8, msg: &MavMessage) -> Value {
    match msg {
        MavMessage::SET_POSITION_TARGET_LOCAL_NED(d) => json!({
            "message": "SET_POSITION_TARGET_LOCAL_NED",
            "sysid": sysid,
            "coordinate_frame": format!("{:?}", d.coordinate_frame),
            "type_mask": d.type_mask.bits(),
            "x": d.x, "y": d.y, "z": d.z,
            "vx": d.vx, "vy": d.vy, "vz": d.vz,
            "afx": d.afx, "afy": d.afy, "afz": d.afz,
            "yaw": d.yaw, "yaw_rate": d.yaw_rate,
        }),
        MavMessage::COMMAND_LONG(d) => {
            let params = [
                d.param1, d.param2, d.param3, d.param4, d.param5, d.param6, d.param7,
            ]
            .map(finite);
            json!({
                "message": "COMMAND_LONG",
                "sysid": sysid,
                "command": format!("{:?}", d.command),
                "confirmation": d.confirmation,
                "params": params,
            })
        }
        MavMessage::COMMAND_INT(d) => {
            let params = [d.param1, d.param2, d.param3, d.param4].map(finite);
            json!({
                "message": "COMMAND_INT",
                "sysid": sysid,
                "command": format!("{:?}", d.command),
                "frame": format!("{:?}", d.frame),
                "params": params,
                "x": d.x, "y": d.y, "z": finite(d.z),
            })
        }
        other => json!({
            "message": skein_mavlink::message_name(other),
            "sysid": sysid,
        }),
    }
}

/// JSON has no NaN (PX4 commands use it for "unchanged"): null instead.
fn finite(v: f32) -> Value {
    if v.is_finite() { json!(v) } else { Value::Null }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skein_mavlink::dialect::*;

    #[test]
    fn setpoints_keep_their_type_mask_and_commands_their_nan_params_as_null() {
        let sp = MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
            x: 1.0,
            z: -10.0,
            type_mask: PositionTargetTypemask::from_bits_truncate(2552),
            ..Default::default()
        });
        let v = sent_json(3, &sp);
        assert_eq!(v["type_mask"], 2552);
        assert_eq!(v["z"], -10.0);
        assert_eq!(v["sysid"], 3);
        let land = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            command: MavCmd::MAV_CMD_NAV_LAND,
            param4: f32::NAN,
            ..Default::default()
        });
        let v = sent_json(3, &land);
        assert_eq!(v["command"], "MAV_CMD_NAV_LAND");
        assert!(v["params"][3].is_null());
        // Serialises (no NaN anywhere).
        assert!(serde_json::to_string(&v).is_ok());
    }
}
