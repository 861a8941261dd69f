//! The frames of MAVLink's command protocol, built in one place: `COMMAND_LONG` (seven
//! float parameters) and `COMMAND_INT` (four float parameters and an integer position,
//! for coordinates that need degE7 precision). Both are answered by `COMMAND_ACK`.
//!
//! ```
//! use skein_mavlink::dialect::MavCmd;
//! use skein_mavlink::{CommandTarget, MavMessage, command_long};
//! let arm = command_long(
//!     CommandTarget::new(3, 1),
//!     MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
//!     [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
//!     0,
//! );
//! let MavMessage::COMMAND_LONG(c) = arm else { unreachable!() };
//! assert_eq!((c.target_system, c.target_component, c.param1), (3, 1, 1.0));
//! ```

use crate::MavMessage;
use crate::dialect::{COMMAND_INT_DATA, COMMAND_LONG_DATA, MavCmd, MavFrame};

/// The component a command is addressed to: `target_system` (sysid; 0 broadcasts) and
/// `target_component` (compid; 1 is the autopilot, 0 every component).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CommandTarget {
    /// `target_system`: the vehicle's MAVLink system id.
    pub system: u8,
    /// `target_component`: the component id (`MAV_COMP_ID_AUTOPILOT1` = 1).
    pub component: u8,
}

impl CommandTarget {
    /// The component `component` of system `system`.
    pub const fn new(system: u8, component: u8) -> Self {
        Self { system, component }
    }
}

/// `COMMAND_LONG` (message 76): `command` with `params` 1–7 (NaN where the command
/// documents "unchanged" / "default") to `target`. `confirmation` counts retransmissions
/// of the same command, 0 for the first.
pub fn command_long(
    target: CommandTarget,
    command: MavCmd,
    params: [f32; 7],
    confirmation: u8,
) -> MavMessage {
    let [param1, param2, param3, param4, param5, param6, param7] = params;
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        param1,
        param2,
        param3,
        param4,
        param5,
        param6,
        param7,
        command,
        target_system: target.system,
        target_component: target.component,
        confirmation,
    })
}

/// A position in a `COMMAND_INT`: `x`, `y` as integers (degE7 latitude and longitude in
/// the global frames, or local metres × 1e4), `z` as a float (metres, in `frame`'s
/// altitude reference).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CommandPosition {
    /// The frame of `x`, `y`, `z` (`MAV_FRAME_GLOBAL`: AMSL altitude).
    pub frame: MavFrame,
    /// Latitude, degE7 (global frames).
    pub x: i32,
    /// Longitude, degE7 (global frames).
    pub y: i32,
    /// Altitude, metres.
    pub z: f32,
}

/// `COMMAND_INT` (message 75): `command` with `params` 1–4 and `position` (params 5–7)
/// to `target`; `current` and `autocontinue` 0 (they only mean something in missions).
pub fn command_int(
    target: CommandTarget,
    command: MavCmd,
    params: [f32; 4],
    position: CommandPosition,
) -> MavMessage {
    let [param1, param2, param3, param4] = params;
    MavMessage::COMMAND_INT(COMMAND_INT_DATA {
        param1,
        param2,
        param3,
        param4,
        x: position.x,
        y: position.y,
        z: position.z,
        command,
        target_system: target.system,
        target_component: target.component,
        frame: position.frame,
        current: 0,
        autocontinue: 0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn command_long_puts_every_parameter_in_its_place() {
        let m = command_long(
            CommandTarget::new(7, 154),
            MavCmd::MAV_CMD_DO_SET_MODE,
            [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0],
            2,
        );
        let MavMessage::COMMAND_LONG(c) = m else {
            panic!("{m:?}")
        };
        assert_eq!(
            [
                c.param1, c.param2, c.param3, c.param4, c.param5, c.param6, c.param7
            ],
            [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]
        );
        assert_eq!(c.command, MavCmd::MAV_CMD_DO_SET_MODE);
        assert_eq!(
            (c.target_system, c.target_component, c.confirmation),
            (7, 154, 2)
        );
    }

    #[test]
    fn command_int_carries_an_integer_position() {
        let m = command_int(
            CommandTarget::new(2, 1),
            MavCmd::MAV_CMD_DO_REPOSITION,
            [5.0, 1.0, 0.0, f32::NAN],
            CommandPosition {
                frame: MavFrame::MAV_FRAME_GLOBAL,
                x: 473_977_419,
                y: 85_455_938,
                z: 500.0,
            },
        );
        let MavMessage::COMMAND_INT(c) = m else {
            panic!("{m:?}")
        };
        assert_eq!((c.param1, c.param2, c.param3), (5.0, 1.0, 0.0));
        assert!(c.param4.is_nan());
        assert_eq!((c.x, c.y, c.z), (473_977_419, 85_455_938, 500.0));
        assert_eq!(
            (c.frame, c.current, c.autocontinue),
            (MavFrame::MAV_FRAME_GLOBAL, 0, 0)
        );
        assert_eq!((c.target_system, c.target_component), (2, 1));
    }
}
