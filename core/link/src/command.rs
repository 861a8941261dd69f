//! Commands to PX4 over the MAVLink command protocol (`COMMAND_LONG` / `COMMAND_INT`,
//! answered by `COMMAND_ACK`), their encoding, and how their results map to errors.

use serde::Serialize;
use skein_mavlink::dialect::{MavCmd, MavDoRepositionFlags, MavFrame, MavResult};
use skein_mavlink::{CommandPosition, CommandTarget, MavMessage, command_int, command_long};
use skein_model::geo::GeoPoint;
use skein_model::px4::{FORCE_ARM_DISARM_MAGIC, MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, Px4Mode};

/// An operation the link performs with the command protocol.
#[derive(Debug, Clone, PartialEq)]
pub enum LinkCommand {
    /// `MAV_CMD_COMPONENT_ARM_DISARM` (400), param1 = 1.
    Arm,
    /// `MAV_CMD_COMPONENT_ARM_DISARM` (400), param1 = 0; `force` adds the 21196 magic
    /// (disarms in the air: the motors stop).
    Disarm {
        /// Emergency disarm.
        force: bool,
    },
    /// `MAV_CMD_DO_SET_MODE` (176) with (1, main, sub); confirmed from the next
    /// `HEARTBEAT.custom_mode`, not from the first ACK.
    SetMode(Px4Mode),
    /// `MAV_CMD_NAV_TAKEOFF` (22); `altitude_amsl_m` in param7, NaN = `MIS_TAKEOFF_ALT`.
    Takeoff {
        /// Target altitude above mean sea level, metres.
        altitude_amsl_m: Option<f64>,
    },
    /// `MAV_CMD_NAV_LAND` (21) at the current position (param4 yaw NaN).
    Land,
    /// `MAV_CMD_NAV_RETURN_TO_LAUNCH` (20).
    ReturnToLaunch,
    /// `MAV_CMD_DO_REPOSITION` (192) as `COMMAND_INT` in `MAV_FRAME_GLOBAL_INT`.
    Reposition {
        /// Where to go (altitude AMSL).
        target: GeoPoint,
        /// Ground speed, m/s; `None` = the vehicle's default.
        ground_speed_m_s: Option<f64>,
    },
    /// `MAV_CMD_SET_MESSAGE_INTERVAL` (511): `interval_us` > 0 sets, 0 = default, -1 = off.
    SetMessageInterval {
        /// MAVLink message id.
        message_id: u32,
        /// Interval, microseconds.
        interval_us: i32,
    },
    /// `MAV_CMD_REQUEST_MESSAGE` (512): send `message_id` once.
    RequestMessage {
        /// MAVLink message id.
        message_id: u32,
    },
}

impl LinkCommand {
    /// The MAVLink command id this operation uses (the key ACKs are matched by).
    pub fn mav_cmd(&self) -> MavCmd {
        match self {
            LinkCommand::Arm | LinkCommand::Disarm { .. } => MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            LinkCommand::SetMode(_) => MavCmd::MAV_CMD_DO_SET_MODE,
            LinkCommand::Takeoff { .. } => MavCmd::MAV_CMD_NAV_TAKEOFF,
            LinkCommand::Land => MavCmd::MAV_CMD_NAV_LAND,
            LinkCommand::ReturnToLaunch => MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH,
            LinkCommand::Reposition { .. } => MavCmd::MAV_CMD_DO_REPOSITION,
            LinkCommand::SetMessageInterval { .. } => MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
            LinkCommand::RequestMessage { .. } => MavCmd::MAV_CMD_REQUEST_MESSAGE,
        }
    }

    /// A short name for errors and logs (`"arm"`, `"set_mode OFFBOARD"`).
    pub fn describe(&self) -> String {
        match self {
            LinkCommand::Arm => "arm".into(),
            LinkCommand::Disarm { force: false } => "disarm".into(),
            LinkCommand::Disarm { force: true } => "force disarm".into(),
            LinkCommand::SetMode(m) => format!("set_mode {m}"),
            LinkCommand::Takeoff { .. } => "takeoff".into(),
            LinkCommand::Land => "land".into(),
            LinkCommand::ReturnToLaunch => "rtl".into(),
            LinkCommand::Reposition { .. } => "reposition".into(),
            LinkCommand::SetMessageInterval { message_id, .. } => {
                format!("set_message_interval {message_id}")
            }
            LinkCommand::RequestMessage { message_id } => format!("request_message {message_id}"),
        }
    }

    /// The frame to send: `COMMAND_LONG`, or `COMMAND_INT` where coordinates need integer
    /// precision. `confirmation` counts resends (0 for the first transmission).
    pub fn encode(&self, target_system: u8, target_component: u8, confirmation: u8) -> MavMessage {
        let to = CommandTarget::new(target_system, target_component);
        let long = |params: [f32; 7]| command_long(to, self.mav_cmd(), params, confirmation);
        let nan = f32::NAN;
        match self {
            LinkCommand::Arm => long([1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
            LinkCommand::Disarm { force } => long([
                0.0,
                if *force { FORCE_ARM_DISARM_MAGIC } else { 0.0 },
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
            ]),
            LinkCommand::SetMode(mode) => {
                let (main, sub) = mode.main_sub();
                long([
                    MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                    f32::from(main),
                    f32::from(sub),
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                ])
            }
            LinkCommand::Takeoff { altitude_amsl_m } => long([
                -1.0,
                0.0,
                0.0,
                nan,
                nan,
                nan,
                altitude_amsl_m.map_or(nan, |a| a as f32),
            ]),
            LinkCommand::Land => long([0.0, 0.0, 0.0, nan, nan, nan, nan]),
            LinkCommand::ReturnToLaunch => long([0.0; 7]),
            LinkCommand::SetMessageInterval {
                message_id,
                interval_us,
            } => long([
                *message_id as f32,
                *interval_us as f32,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
            ]),
            LinkCommand::RequestMessage { message_id } => {
                long([*message_id as f32, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
            }
            LinkCommand::Reposition {
                target,
                ground_speed_m_s,
            } => {
                let (lat, lon, _) = target.to_mavlink();
                command_int(
                    to,
                    self.mav_cmd(),
                    [
                        ground_speed_m_s.map_or(-1.0, |v| v as f32),
                        MavDoRepositionFlags::MAV_DO_REPOSITION_FLAGS_CHANGE_MODE.bits() as f32,
                        0.0,
                        nan,
                    ],
                    CommandPosition {
                        frame: MavFrame::MAV_FRAME_GLOBAL,
                        x: lat,
                        y: lon,
                        z: target.alt_amsl_m as f32,
                    },
                )
            }
        }
    }
}

/// Why a link operation failed.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum LinkError {
    /// The vehicle answered with a result other than ACCEPTED.
    Rejected {
        /// What was asked (`"arm"`).
        command: String,
        /// `MAV_RESULT` name, e.g. `"TEMPORARILY_REJECTED"`, `"DENIED"`, `"UNSUPPORTED"`.
        result: String,
        /// What the vehicle said about it: its warning and error `STATUSTEXT`s while the
        /// command was in flight, oldest first (PX4: `"Preflight Fail: …"`, `"Arming
        /// denied: …"`); empty when it said nothing, or for a refusal that is no command
        /// (a parameter or a mission transfer).
        #[serde(skip_serializing_if = "Vec::is_empty")]
        statustexts: Vec<String>,
    },
    /// No ACK after every resend.
    Timeout {
        /// What was asked.
        command: String,
        /// Transmissions made.
        attempts: u32,
    },
    /// The ACK came but the HEARTBEAT never showed the mode.
    ModeNotConfirmed {
        /// Mode asked for.
        wanted: String,
        /// Mode in the last heartbeat.
        reported: String,
    },
    /// Nothing heard from the vehicle (link lost or never connected).
    NoLink,
    /// The frame could not be sent.
    Send(String),
}

impl std::fmt::Display for LinkError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LinkError::Rejected {
                command,
                result,
                statustexts,
            } => {
                write!(f, "{command} rejected by the vehicle: {result}")?;
                if !statustexts.is_empty() {
                    write!(f, " ({})", statustexts.join("; "))?;
                }
                Ok(())
            }
            LinkError::Timeout { command, attempts } => {
                write!(
                    f,
                    "{command}: no COMMAND_ACK after {attempts} transmissions"
                )
            }
            LinkError::ModeNotConfirmed { wanted, reported } => write!(
                f,
                "mode {wanted} accepted but the heartbeat still reports {reported}"
            ),
            LinkError::NoLink => f.write_str("no link to the vehicle"),
            LinkError::Send(e) => write!(f, "send failed: {e}"),
        }
    }
}

impl std::error::Error for LinkError {}

/// The `MAV_RESULT` name without its prefix (`"TEMPORARILY_REJECTED"`).
pub fn result_name(r: MavResult) -> String {
    format!("{r:?}")
        .trim_start_matches("MAV_RESULT_")
        .to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn set_mode_offboard_is_1_6_0() {
        let MavMessage::COMMAND_LONG(c) = LinkCommand::SetMode(Px4Mode::Offboard).encode(3, 1, 0)
        else {
            panic!()
        };
        assert_eq!(c.command, MavCmd::MAV_CMD_DO_SET_MODE);
        assert_eq!((c.param1, c.param2, c.param3), (1.0, 6.0, 0.0));
        assert_eq!((c.target_system, c.target_component), (3, 1));
        let MavMessage::COMMAND_LONG(c) = LinkCommand::SetMode(Px4Mode::Rtl).encode(3, 1, 2) else {
            panic!()
        };
        assert_eq!((c.param2, c.param3, c.confirmation), (4.0, 5.0, 2));
    }

    #[test]
    fn force_disarm_carries_the_magic() {
        let MavMessage::COMMAND_LONG(c) = LinkCommand::Disarm { force: true }.encode(1, 1, 0)
        else {
            panic!()
        };
        assert_eq!((c.param1, c.param2), (0.0, 21196.0));
    }

    #[test]
    fn reposition_is_a_command_int_in_degrees_e7() {
        let target = GeoPoint::new(47.3977419, 8.5455938, 500.0);
        let MavMessage::COMMAND_INT(c) = LinkCommand::Reposition {
            target,
            ground_speed_m_s: Some(5.0),
        }
        .encode(2, 1, 0) else {
            panic!()
        };
        assert_eq!(
            (c.x, c.y, c.z, c.param1),
            (473_977_419, 85_455_938, 500.0, 5.0)
        );
    }

    #[test]
    fn result_names_drop_the_prefix() {
        assert_eq!(
            result_name(MavResult::MAV_RESULT_TEMPORARILY_REJECTED),
            "TEMPORARILY_REJECTED"
        );
    }
}
