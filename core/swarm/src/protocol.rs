//! The swarm protocol: everything the coordinator and a vehicle say to each other, as
//! plain serde types.
//!
//! The coordinator never holds a vehicle's actor: it sends [`ToVehicle`] through a
//! [`VehiclePort`] and hears [`FromVehicle`] through an [`Uplink`], plus the latest
//! [`VehicleReport`] (keep-last, like a best-effort DDS topic of depth 1). Two carriers
//! carry the same types: in-process messages ([`crate::carrier`]) in `skein up`, and DDS
//! between an agent and its coordinators.
//!
//! Time on the wire is wall-clock microseconds since the Unix epoch ([`wall_us`]): a slot
//! target carries the instant it was computed and its velocity, so the vehicle side moves
//! it on by its age. Between hosts, the receiving carrier first converts a stamp into its
//! own clock ([`crate::clocks`]: offsets estimated from clock exchanges); a negative age
//! counts as zero, and the extrapolation is capped.

use serde::{Deserialize, Serialize};
pub use skein_model::command::{Command, CommandKind};
use skein_model::fsm::VehicleState;
use skein_model::geo::Ned;
use std::sync::Arc;
use std::sync::atomic::{AtomicI64, Ordering};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// A skew added to this process's wall clock, µs ([`skew_wall_clock`]).
static WALL_SKEW_US: AtomicI64 = AtomicI64::new(0);

/// Wall-clock time now, microseconds since the Unix epoch (0 if the clock is before it),
/// plus the skew a test gave this process ([`skew_wall_clock`]).
pub fn wall_us() -> u64 {
    let now = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as i64);
    (now + WALL_SKEW_US.load(Ordering::Relaxed)).max(0) as u64
}

/// Skews this process's wall clock ([`wall_us`]) by `skew_ms`, as a host whose clock is
/// off would be: for tests of the clock exchange (`--test-clock-skew-ms`, hidden), never
/// for flight.
pub fn skew_wall_clock(skew_ms: i64) {
    WALL_SKEW_US.store(skew_ms.saturating_mul(1000), Ordering::Relaxed);
}

/// Longest a slot target is moved on along its velocity by its age (the formation loop
/// sends one ten times a second); past this the vehicle holds where the target would be.
pub const TARGET_EXTRAPOLATION: Duration = Duration::from_millis(500);

/// Longest a report's position is moved on by its age (reports come at the control rate;
/// a vehicle at 5 m/s covers 1 m in this time).
pub const REPORT_EXTRAPOLATION: Duration = Duration::from_millis(200);

/// Age of a wall-clock stamp ([`wall_us`]) now; zero for a stamp from the future.
pub fn age_of(stamp_us: u64) -> Duration {
    Duration::from_micros(wall_us().saturating_sub(stamp_us))
}

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
    /// When `position` was computed, wall-clock µs ([`wall_us`]).
    pub stamp_us: u64,
}

/// Coordinator → vehicle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum ToVehicle {
    /// An operator command. The vehicle answers [`FromVehicle::CommandAck`] (accepted or
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
    /// A command for the payload in `slot`; answered by [`FromVehicle::PayloadResult`].
    PayloadCommand {
        /// Request id, echoed in the answer.
        request_id: u64,
        /// Payload slot (`"gimbal"`).
        slot: String,
        /// The payload's own command object.
        command: serde_json::Value,
    },
    /// Attach a payload slot at run time (it lasts until skein restarts); answered by
    /// [`FromVehicle::PayloadResult`] once its driver exists (the payload as listed), or
    /// with why not ([`PayloadCommandError::Invalid`] / [`PayloadCommandError::Conflict`]
    /// naming the field).
    AttachPayload {
        /// Request id, echoed in the answer.
        request_id: u64,
        /// The slot to add.
        spec: skein_payload::PayloadSpec,
    },
    /// Detach the payload in `slot`: its driver's `shutdown` runs, then the slot is gone;
    /// answered by [`FromVehicle::PayloadResult`].
    DetachPayload {
        /// Request id, echoed in the answer.
        request_id: u64,
        /// Payload slot.
        slot: String,
    },
}

/// Why a payload command has no answer from the payload.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum PayloadCommandError {
    /// No such vehicle or slot (HTTP 404).
    NotFound(String),
    /// The payload is not running: failed, disabled or restarting (HTTP 503).
    Unavailable(String),
    /// The payload refused the command; its message (HTTP 400).
    Refused(String),
    /// A request field is wrong (HTTP 400 naming it): an attach of an unknown kind or
    /// plugin, or a config the plugin refused.
    Invalid {
        /// The field at fault (`"kind"`, `"plugin"`, `"config"`, `"slot"`).
        field: String,
        /// Why.
        error: String,
    },
    /// The request conflicts with the vehicle's payloads (HTTP 409 naming the field): an
    /// attach to a slot that exists, a detach of a slot being stopped.
    Conflict {
        /// The field at fault (`"slot"`).
        field: String,
        /// Why.
        error: String,
    },
}

/// Vehicle → coordinator (events and answers; the vehicle's state is in
/// [`VehicleReport`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum FromVehicle {
    /// The FSM accepted (`Ok`) or refused (`Err`, naming the state) a command.
    CommandAck {
        /// Vehicle id.
        id: String,
        /// The command's id.
        command_id: u64,
        /// Accepted, or the reason of the refusal.
        result: Result<(), String>,
    },
    /// The FSM state changed.
    StateChanged {
        /// Vehicle id.
        id: String,
        /// Previous state.
        from: VehicleState,
        /// New state.
        to: VehicleState,
    },
    /// The payload's answer to [`ToVehicle::PayloadCommand`].
    PayloadResult {
        /// Vehicle id.
        id: String,
        /// The request's id.
        request_id: u64,
        /// The payload's answer, or why there is none.
        result: Result<serde_json::Value, PayloadCommandError>,
    },
}

impl FromVehicle {
    /// The vehicle that sent it.
    pub fn vehicle_id(&self) -> &str {
        match self {
            FromVehicle::CommandAck { id, .. }
            | FromVehicle::StateChanged { id, .. }
            | FromVehicle::PayloadResult { id, .. } => id,
        }
    }
}

/// What the formation engine needs of a vehicle, published by the vehicle at its control
/// rate (keep-last: only the newest matters).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct VehicleReport {
    /// FSM state.
    pub state: VehicleState,
    /// Swarm-frame position, NED metres, at `stamp_us`; `None` before position and home
    /// are known.
    pub position: Option<Ned>,
    /// Velocity, NED m/s.
    pub velocity: Ned,
    /// Heading, radians clockwise from north (`ATTITUDE.yaw`).
    pub heading_rad: f64,
    /// Time since the autopilot was last heard, seconds; `None` if never heard.
    pub link_silence_s: Option<f64>,
    /// Where skein is sending the vehicle (swarm frame), if it steers it.
    pub target: Option<Ned>,
    /// When this report was made, wall-clock µs ([`wall_us`]).
    pub stamp_us: u64,
    /// How long its agent flies it on its slot without hearing a coordinator, seconds
    /// (`skein agent`'s `coordinator_ride_through_s`); `None` for a vehicle of the
    /// reader's own process. A coordinator keeps a silent member's slot that long.
    #[serde(default)]
    pub ride_through_s: Option<f64>,
}

impl VehicleReport {
    /// A vehicle never heard from.
    pub fn disconnected() -> Self {
        VehicleReport {
            state: VehicleState::Disconnected,
            position: None,
            velocity: Ned::ZERO,
            heading_rad: 0.0,
            link_silence_s: None,
            target: None,
            stamp_us: 0,
            ride_through_s: None,
        }
    }

    /// The position moved on by the report's age (at most `cap`): where the vehicle is
    /// now if it kept its velocity.
    pub fn position_now(&self, cap: Duration) -> Option<Ned> {
        let age = age_of(self.stamp_us).min(cap).as_secs_f64();
        self.position.map(|p| p + self.velocity * age)
    }

    /// Link silence now (the report's value plus its age); `Duration::MAX` if never
    /// heard.
    pub fn silence_now(&self) -> Duration {
        match self.link_silence_s {
            Some(s) => Duration::from_secs_f64(s.max(0.0)) + age_of(self.stamp_us),
            None => Duration::MAX,
        }
    }
}

/// Sends [`ToVehicle`] to one vehicle, whatever carries it.
pub trait VehiclePort: Send + Sync {
    /// Sends; `Err` names why the vehicle cannot be reached (not running, link down).
    fn send(&self, msg: ToVehicle) -> Result<(), String>;
}

/// Where a vehicle's [`FromVehicle`] messages go (a closure, so the vehicle does not
/// know who listens).
pub type Uplink = Arc<dyn Fn(FromVehicle) + Send + Sync>;

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

    #[test]
    fn a_report_moves_on_by_its_age_up_to_the_cap() {
        let mut r = VehicleReport::disconnected();
        r.position = Some(Ned::new(0.0, 0.0, -10.0));
        r.velocity = Ned::new(5.0, 0.0, 0.0);
        r.stamp_us = wall_us() - 100_000; // 100 ms old
        let p = r.position_now(Duration::from_millis(200)).unwrap();
        assert!((0.5..0.6).contains(&p.north_m), "{p:?}");
        r.stamp_us = wall_us() - 2_000_000; // 2 s old: capped at 200 ms
        let p = r.position_now(Duration::from_millis(200)).unwrap();
        assert!((p.north_m - 1.0).abs() < 1e-9, "{p:?}");
        r.stamp_us = wall_us() + 1_000_000; // from the future: no extrapolation
        assert_eq!(r.position_now(Duration::from_millis(200)), r.position);
        assert_eq!(VehicleReport::disconnected().silence_now(), Duration::MAX);
    }
}
