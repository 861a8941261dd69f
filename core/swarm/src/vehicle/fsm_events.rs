//! Operator commands and link events into the FSM: a command is checked against the FSM
//! (refused with a reason naming the state) and started; link events (observed
//! telemetry, loss, return, reboot) become FSM events. State changes go up to the
//! coordinator through the uplink.

use super::control::Target;
use super::procedures::Procedure;
use super::shared::Memory;
use super::{VehicleActorState, VehicleCore};
use crate::config::SwarmConfig;
use crate::events::SwarmEvent;
use crate::protocol::{Command, FromVehicle};
use ractor::ActorRef;
use skein_link::LinkCommand;
use skein_link::px4link::LinkEvent;
use skein_model::fsm::{self, Event, Observed, VehicleState};
use skein_model::geo::{Ned, NedFrame};
use skein_model::px4::Px4Mode;
use skein_model::safety::SetpointShaper;

use super::messages::VehicleMsg;

impl VehicleCore {
    pub(super) fn config(&self) -> &SwarmConfig {
        &self.context.config
    }

    pub(super) fn emit(&self, ev: SwarmEvent) {
        let _ = self.events.send(ev);
    }

    /// Applies an FSM event; emits and reports a state change.
    pub(super) fn apply(
        &self,
        mem: &mut Memory,
        event: Event,
    ) -> Result<VehicleState, fsm::Refusal> {
        let before = mem.state;
        let after = fsm::transition(before, event)?;
        if after != before {
            mem.state = after;
            self.on_state_change(mem, before, after);
        }
        Ok(after)
    }

    pub(super) fn on_state_change(&self, mem: &mut Memory, from: VehicleState, to: VehicleState) {
        tracing::info!(id = %self.shared.id, "{from} -> {to}");
        if to != VehicleState::InFormation {
            mem.slot = None;
            mem.slot_correction.reset();
        }
        if to != VehicleState::TakingOff {
            mem.offboard_engaged = false;
        }
        if to != VehicleState::GoTo {
            mem.goto_target = None;
        }
        self.emit(SwarmEvent::StateChanged {
            id: self.shared.id.clone(),
            from,
            to,
        });
        (self.uplink)(FromVehicle::StateChanged {
            id: self.shared.id.clone(),
            from,
            to,
        });
    }

    pub(super) fn observed(&self) -> Option<Observed> {
        self.shared.link.with_telemetry(|t| t.observed())
    }

    pub(super) fn swarm_frame(&self) -> Option<NedFrame> {
        self.context.frame().or_else(|| {
            let home = self.shared.link.with_telemetry(|t| t.home)?;
            Some(self.context.anchor(home.geo))
        })
    }

    /// Points the stream at `target`, re-anchoring the shaper at the current position when
    /// the vehicle was not being shaped.
    pub(super) fn set_target(&self, mem: &mut Memory, target: Target, current: Ned) {
        if mem.shaper.is_none() {
            let fence = self.setpoint_fence(mem);
            mem.shaper = Some(SetpointShaper::new(
                current,
                self.shared.model.limits,
                fence.fence.clone(),
                self.config().setpoint_separation_m(),
            ));
        }
        mem.target = Some(target);
    }
}

impl VehicleActorState {
    /// Obeys operator command `cmd` (`command_id` names its result event): checks what
    /// needs telemetry, applies it to the FSM, then starts its procedure or sets its
    /// target.
    ///
    /// # Errors
    /// The reason a check or the FSM refused it (the state unchanged).
    pub(super) fn command(
        &self,
        myself: &ActorRef<VehicleMsg>,
        cmd: Command,
        command_id: u64,
    ) -> Result<(), String> {
        let mut mem = self.shared.memory();
        let name = cmd.name();
        let current = self.swarm_frame().and_then(|f| self.shared.position(&f));
        // Checks that need telemetry, before the FSM: a clear reason, state unchanged.
        self.check_command(&cmd, current)?;
        self.apply(&mut mem, Event::Command(cmd.kind()))
            .map_err(|r| r.reason)?;
        let yaw = self
            .shared
            .link
            .with_telemetry(|t| t.attitude.map(|a| a.yaw_rad))
            .unwrap_or(0.0);
        match cmd {
            Command::Arm => self.start_procedure(
                myself,
                &mut mem,
                command_id,
                name,
                Procedure::Link(LinkCommand::Arm),
            ),
            Command::Disarm | Command::ForceDisarm(_) => self.start_procedure(
                myself,
                &mut mem,
                command_id,
                name,
                Procedure::Link(LinkCommand::Disarm {
                    force: matches!(cmd, Command::ForceDisarm(_)),
                }),
            ),
            Command::Land => self.start_procedure(
                myself,
                &mut mem,
                command_id,
                name,
                Procedure::Link(LinkCommand::Land),
            ),
            Command::Rtl => self.start_procedure(
                myself,
                &mut mem,
                command_id,
                name,
                Procedure::Link(LinkCommand::SetMode(Px4Mode::Rtl)),
            ),
            Command::Takeoff(skein_model::command::Takeoff { altitude_m }) => {
                let current = current.expect("checked above");
                mem.yaw_rad = yaw;
                mem.takeoff_altitude_m =
                    altitude_m.unwrap_or(self.config().default_takeoff_altitude_m);
                mem.shaper = None;
                self.set_target(&mut mem, Target::Hold(current), current);
                let armed = self.observed().is_some_and(|o| o.armed);
                self.start_procedure(
                    myself,
                    &mut mem,
                    command_id,
                    name,
                    Procedure::EnterOffboard { arm: !armed },
                );
            }
            Command::Hold | Command::GoTo(_) => {
                let current = current.expect("checked above");
                self.hold_or_go_to(myself, &mut mem, &cmd, command_id, current, yaw);
            }
            Command::JoinFormation => {
                // The slot arrives with the next formation tick; hold until then.
                self.emit_result(command_id, name, Ok(()));
            }
            Command::LeaveFormation => {
                let here = mem.shaper.as_ref().map(|s| s.carrot());
                if let (Some(here), Some(cur)) = (here, current) {
                    self.set_target(&mut mem, Target::Hold(here), cur);
                }
                self.emit_result(command_id, name, Ok(()));
            }
            // The FSM refused it above: the coordinator's command, not the vehicle's.
            Command::ClearHazard => return Err(format!("{name} is the coordinator's")),
        }
        Ok(())
    }

    /// The checks of `cmd` that need telemetry: a position and home for the commands that
    /// fly somewhere (`current`: the swarm-frame position), a takeoff altitude under the
    /// fence's ceiling.
    fn check_command(&self, cmd: &Command, current: Option<Ned>) -> Result<(), String> {
        let name = cmd.name();
        let needs_position = matches!(cmd, Command::Takeoff(_) | Command::Hold | Command::GoTo(_));
        let has_local_frame = self
            .shared
            .link
            .with_telemetry(|t| t.local_frame().is_some());
        if needs_position && (current.is_none() || !has_local_frame) {
            return Err(format!(
                "{name} refused: vehicle {} has no position and home yet (waiting for GLOBAL_POSITION_INT and HOME_POSITION)",
                self.shared.id
            ));
        }
        if let Command::Takeoff(skein_model::command::Takeoff {
            altitude_m: Some(a),
        }) = *cmd
            && !(a.is_finite() && a > 0.0 && a <= self.context.geofence().fence.max_altitude_m)
        {
            return Err(format!(
                "takeoff refused: altitude_m {a} outside (0, {}] m",
                self.context.geofence().fence.max_altitude_m
            ));
        }
        Ok(())
    }

    /// `hold` or `goto` from `current`: the target set (a go-to's point, or where the
    /// setpoint is now), done at once in OFFBOARD, else after entering it.
    fn hold_or_go_to(
        &self,
        myself: &ActorRef<VehicleMsg>,
        mem: &mut Memory,
        cmd: &Command,
        command_id: u64,
        current: Ned,
        yaw: f64,
    ) {
        let name = cmd.name();
        let offboard = self.observed().is_some_and(|o| o.mode == Px4Mode::Offboard);
        if !offboard {
            mem.shaper = None;
            mem.yaw_rad = yaw;
        }
        let target = match cmd {
            Command::GoTo(g) => {
                let target = g.target();
                mem.goto_target = Some(target);
                Target::Hold(target)
            }
            _ => {
                // Hold where the setpoint is now (no jump back), or here.
                let here = mem.shaper.as_ref().map_or(current, |s| s.carrot());
                Target::Hold(here)
            }
        };
        self.set_target(mem, target, current);
        if offboard {
            self.emit_result(command_id, name, Ok(()));
        } else {
            self.start_procedure(
                myself,
                mem,
                command_id,
                name,
                Procedure::EnterOffboard { arm: false },
            );
        }
    }
}

impl VehicleCore {
    pub(super) fn emit_result(&self, command_id: u64, command: &str, result: Result<(), String>) {
        if command_id == 0 {
            return; // internal command (the coordinator's formation joins)
        }
        self.emit(SwarmEvent::CommandResult {
            command_id,
            id: self.shared.id.clone(),
            command: command.to_string(),
            ok: result.is_ok(),
            error: result.err(),
        });
    }

    pub(super) fn on_link_event(&self, ev: LinkEvent) {
        let mut mem = self.shared.memory();
        let id = self.shared.id.clone();
        match ev {
            LinkEvent::Observed(o) => {
                if leaving_for_offboard(&mem, &o) {
                    return;
                }
                let event = if mem.state == VehicleState::Disconnected {
                    Event::Connected(o)
                } else {
                    Event::Observed(o)
                };
                let _ = self.apply(&mut mem, event);
            }
            LinkEvent::Lost => {
                let _ = self.apply(&mut mem, Event::LinkLost);
                self.emit(SwarmEvent::LinkLost { id });
            }
            LinkEvent::Restored(o) => {
                let _ = self.apply(&mut mem, Event::LinkRestored(o));
                self.emit(SwarmEvent::LinkRestored { id });
            }
            LinkEvent::Rebooted => {
                if let Some(o) = self.observed() {
                    let _ = self.apply(&mut mem, Event::ProcedureFailed(o));
                }
                self.emit(SwarmEvent::Rebooted { id });
            }
            LinkEvent::StatusText { severity, text } => {
                self.emit(SwarmEvent::StatusText { id, severity, text });
            }
        }
    }
}

/// PX4 still in the mode a hold or go-to is bringing it out of (a LAND, an RTL, a HOLD)
/// while the procedure that switches it to OFFBOARD runs (the setpoint stream's warm-up,
/// the mode command's acknowledgement): the state the command set stands; the procedure
/// reports a failure itself.
fn leaving_for_offboard(mem: &Memory, o: &Observed) -> bool {
    mem.entering_offboard.is_some()
        && matches!(
            mem.state,
            VehicleState::Hovering | VehicleState::GoTo | VehicleState::InFormation
        )
        && o.mode != Px4Mode::Offboard
        && o.airborne()
}
