//! Commands to a rehearsed vehicle and the procedures behind them, as the Vehicle actor
//! carries them out (`skein_swarm::vehicle::fsm_events`, `::procedures`): checked against
//! the telemetry and the FSM (a refusal leaves the state alone), then `land` and `rtl` as
//! one link command, `takeoff`, `hold` and `goto` as a target with OFFBOARD entered
//! first when PX4 is not in it (1.1 s of setpoints, arm if needed, `DO_SET_MODE`, seen
//! confirmed in the heartbeat).

use super::{Aircraft, Target};
use skein_link::LinkCommand;
use skein_mavlink::MavMessage;
use skein_mavlink::dialect::MavResult;
use skein_model::command::Command;
use skein_model::fsm::{Event, VehicleState, transition};
use skein_model::geo::Ned;
use skein_model::px4::Px4Mode;
use skein_model::safety::SetpointShaper;
use skein_swarm::vehicle::OFFBOARD_PRESTREAM;

/// Longest wait for the stream to start, or for OFFBOARD to be confirmed, seconds (the
/// Vehicle actor's link call timeout).
const PROCEDURE_TIMEOUT_S: f64 = 10.0;

/// A takeoff without an altitude climbs this high above home, metres
/// (`[swarm] default_takeoff_altitude_m`).
const DEFAULT_TAKEOFF_ALTITUDE_M: f64 = 10.0;

/// A multi-step operation under way.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Procedure {
    /// Arm before switching to OFFBOARD.
    arm: bool,
    /// When it began, virtual seconds.
    since_s: f64,
    /// When the mode (and arming) were asked for, once they were.
    asked_at_s: Option<f64>,
}

impl Aircraft {
    /// Obeys `cmd` (see the module docs).
    ///
    /// # Errors
    /// Why it was refused: no position yet, an altitude outside the fence, the FSM's
    /// reason, or a command a rehearsal does not fly.
    pub fn command(&mut self, cmd: &Command) -> Result<(), String> {
        let name = cmd.name();
        let current = self.measured.map(|m| m.0);
        let needs_position = matches!(cmd, Command::Takeoff(_) | Command::Hold | Command::GoTo(_));
        if needs_position && (current.is_none() || self.telemetry.local_frame().is_none()) {
            return Err(format!(
                "{name} refused: {} has no position and home yet",
                self.id
            ));
        }
        if let Command::Takeoff(t) = cmd
            && let Some(a) = t.altitude_m
            && !(a.is_finite() && a > 0.0 && a <= self.fence.max_altitude_m)
        {
            return Err(format!("takeoff refused: altitude_m {a} outside the fence"));
        }
        self.state = transition(self.state, Event::Command(cmd.kind())).map_err(|r| r.reason)?;
        let yaw = self.telemetry.attitude.map_or(0.0, |a| a.yaw_rad);
        let current = current.unwrap_or(Ned::ZERO);
        match cmd {
            Command::Land => {
                self.link(&LinkCommand::Land);
            }
            Command::Rtl => {
                self.link(&LinkCommand::SetMode(Px4Mode::Rtl));
            }
            Command::Takeoff(t) => {
                self.yaw_rad = yaw;
                self.takeoff_altitude_m = t.altitude_m.unwrap_or(DEFAULT_TAKEOFF_ALTITUDE_M);
                self.shaper = None;
                self.offboard_engaged = false;
                self.set_target(Target::Hold(current), current);
                let armed = self.observed().is_some_and(|o| o.armed);
                self.start_offboard(!armed);
            }
            Command::Hold | Command::GoTo(_) => self.hold_or_go_to(cmd, current, yaw),
            Command::JoinFormation => {}
            Command::LeaveFormation => {
                self.planned = false;
                if let Some(here) = self.shaper.as_ref().map(SetpointShaper::carrot) {
                    self.set_target(Target::Hold(here), current);
                }
            }
            other => return Err(format!("{} is not flown in a rehearsal", other.name())),
        }
        Ok(())
    }

    /// `hold` or `goto` from `current`: the target set, OFFBOARD entered when PX4 is not
    /// in it.
    fn hold_or_go_to(&mut self, cmd: &Command, current: Ned, yaw: f64) {
        let offboard = self.observed().is_some_and(|o| o.mode == Px4Mode::Offboard);
        if !offboard {
            self.shaper = None;
            self.yaw_rad = yaw;
        }
        self.planned = false;
        let target = match cmd {
            Command::GoTo(g) => {
                self.goto_target = Some(g.target());
                Target::Hold(g.target())
            }
            _ => Target::Hold(self.shaper.as_ref().map_or(current, SetpointShaper::carrot)),
        };
        self.set_target(target, current);
        if !offboard {
            self.start_offboard(false);
        }
    }

    /// Points the stream at `target`, anchoring a new shaper at `current` when none runs.
    pub(super) fn set_target(&mut self, target: Target, current: Ned) {
        if self.shaper.is_none() {
            self.shaper = Some(SetpointShaper::new(
                current,
                self.limits,
                self.fence.clone(),
                self.separation_m,
            ));
        }
        self.target = Some(target);
    }

    fn start_offboard(&mut self, arm: bool) {
        self.procedure = Some(Procedure {
            arm,
            since_s: self.time_s(),
            asked_at_s: None,
        });
    }

    /// One step of the procedure under way: after 1.1 s of setpoints, arm (leaving a
    /// landing mode first) and ask for OFFBOARD; once the heartbeat shows it, a takeoff
    /// climbs to its altitude above home.
    pub(super) fn procedure_step(&mut self) {
        let Some(p) = self.procedure else {
            return;
        };
        let now = self.time_s();
        match p.asked_at_s {
            None => {
                let streamed = self.stream.map(|(_, since)| now - since);
                if streamed.is_some_and(|s| s >= OFFBOARD_PRESTREAM.as_secs_f64()) {
                    let asked = self.leave_landing_modes()
                        && (!p.arm || self.link(&LinkCommand::Arm))
                        && self.link(&LinkCommand::SetMode(Px4Mode::Offboard));
                    self.procedure = asked.then_some(Procedure {
                        asked_at_s: Some(now),
                        ..p
                    });
                } else if now - p.since_s > PROCEDURE_TIMEOUT_S {
                    self.procedure_failed();
                }
            }
            Some(at) => {
                let o = self.observed();
                if o.is_some_and(|o| o.mode == Px4Mode::Offboard && (o.armed || !p.arm)) {
                    self.procedure = None;
                    self.offboard_engaged_now();
                } else if now - at > PROCEDURE_TIMEOUT_S {
                    self.procedure_failed();
                }
            }
        }
    }

    /// OFFBOARD is confirmed: a takeoff climbs from where the vehicle is to its altitude
    /// above home.
    fn offboard_engaged_now(&mut self) {
        if self.state != VehicleState::TakingOff {
            return;
        }
        let home_down = self
            .telemetry
            .home
            .map(|h| self.swarm.to_ned(&h.geo).down_m);
        match (home_down, self.target) {
            (Some(home_down), Some(t)) => {
                let mut p = t.position();
                p.down_m = home_down - self.takeoff_altitude_m;
                self.target = Some(Target::Hold(p));
                self.offboard_engaged = true;
            }
            _ => self.procedure_failed(),
        }
    }

    /// PX4 stays in LAND or RTL on the ground and refuses to arm there: HOLD first.
    fn leave_landing_modes(&mut self) -> bool {
        let stuck = self.observed().is_some_and(|o| {
            !o.airborne() && matches!(o.mode, Px4Mode::Land | Px4Mode::Rtl | Px4Mode::Precland)
        });
        !stuck || self.link(&LinkCommand::SetMode(Px4Mode::Hold))
    }

    /// Sends `cmd`; true when PX4 accepted it (its `COMMAND_ACK`), else the procedure
    /// fails (the FSM settles on what telemetry says).
    fn link(&mut self, cmd: &LinkCommand) -> bool {
        let answers = self.sim.send(&cmd.encode(1, 1, 0));
        let accepted = answers.iter().any(|(_, m)| {
            matches!(m, MavMessage::COMMAND_ACK(a)
                if a.command == cmd.mav_cmd() && a.result == MavResult::MAV_RESULT_ACCEPTED)
        });
        if !accepted {
            self.procedure_failed();
        }
        accepted
    }

    /// The procedure failed: the FSM settles on what telemetry says.
    fn procedure_failed(&mut self) {
        self.procedure = None;
        if let Some(o) = self.observed() {
            self.apply(Event::ProcedureFailed(o));
        }
    }
}

impl Target {
    /// The point aimed at (a slot's where it was given).
    pub(crate) fn position(&self) -> Ned {
        match self {
            Target::Hold(p) => *p,
            Target::Track { position, .. } => *position,
        }
    }
}
