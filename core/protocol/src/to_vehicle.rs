//! Coordinator → vehicle: operator commands, formation slot targets ([`SlotTarget`]),
//! payload commands and run-time payload attaches and detaches ([`ToVehicle`]).

use serde::{Deserialize, Serialize};
use skein_model::command::Command;
use skein_model::geo::Ned;

/// A formation slot target from the coordinator (swarm frame).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SlotTarget {
    /// Slot index (0 = leader).
    pub slot: usize,
    /// True for the leader.
    pub leader: bool,
    /// Where the member should be at `stamp_us`, swarm-frame NED metres: the slot, or its
    /// planned place on the way there during a formation change.
    pub position: Ned,
    /// The slot itself (where a formation change ends), swarm-frame NED metres.
    pub goal: Ned,
    /// Velocity (feed-forward) of `position`, NED m/s: the vehicle moves the target on by
    /// its age.
    pub velocity: Ned,
    /// Heading to hold, radians clockwise from north.
    pub yaw_rad: f64,
    /// When `position` was computed, wall-clock µs ([`wall_us`](crate::wall_us)).
    pub stamp_us: u64,
}

/// Coordinator → vehicle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum ToVehicle {
    /// An operator command. The vehicle answers [`FromVehicle::CommandAck`](crate::FromVehicle::CommandAck) (accepted or
    /// refused by its FSM, naming the state), then the outcome as a `command_result`
    /// event. `command_id` 0 marks the coordinator's own commands (formation joins).
    Command {
        /// Command id (the API's 202 answer carries it).
        command_id: u64,
        /// The command.
        command: Command,
    },
    /// A new formation slot target, or `None` to drop the slot.
    Slot {
        /// The slot target.
        target: Option<SlotTarget>,
    },
    /// A command for the payload in `slot`; answered by [`FromVehicle::PayloadResult`](crate::FromVehicle::PayloadResult).
    PayloadCommand {
        /// Request id, echoed in the answer.
        request_id: u64,
        /// Payload slot (`"gimbal"`).
        slot: String,
        /// The payload's own command object.
        command: serde_json::Value,
    },
    /// Attach a payload slot at run time (it lasts until skein restarts); answered by
    /// [`FromVehicle::PayloadResult`](crate::FromVehicle::PayloadResult) once its driver exists (the payload as listed), or
    /// with why not ([`PayloadCommandError::Invalid`](crate::PayloadCommandError::Invalid) / [`PayloadCommandError::Conflict`](crate::PayloadCommandError::Conflict)
    /// naming the field).
    AttachPayload {
        /// Request id, echoed in the answer.
        request_id: u64,
        /// The slot to add.
        spec: skein_model::payload::PayloadSpec,
    },
    /// Detach the payload in `slot`: its driver's `shutdown` runs, then the slot is gone;
    /// answered by [`FromVehicle::PayloadResult`](crate::FromVehicle::PayloadResult).
    DetachPayload {
        /// Request id, echoed in the answer.
        request_id: u64,
        /// Payload slot.
        slot: String,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commands_round_trip_as_the_api_spells_them() {
        let goto = Command::GoTo(Ned::new(1.0, 2.0, -3.0).into());
        let json = serde_json::to_value(&goto).unwrap();
        assert_eq!(json["command"], "goto");
        assert_eq!(json["east_m"], 2.0);
        let back: Command = serde_json::from_value(json).unwrap();
        assert_eq!(back, goto);
        let msg = ToVehicle::Command {
            command_id: 7,
            command: Command::Takeoff(skein_model::command::Takeoff {
                altitude_m: Some(10.0),
            }),
        };
        let text = serde_json::to_string(&msg).unwrap();
        assert!(text.contains("\"type\":\"command\""), "{text}");
        assert_eq!(serde_json::from_str::<ToVehicle>(&text).unwrap(), msg);
    }
}
