//! The vehicle state machine (the paper's GenericUAVModel) as a pure transition function.
//!
//! States mix what skein commanded (taking off, holding, flying a formation, going to a
//! point) with what PX4 reports (armed flag, `custom_mode`, `EXTENDED_SYS_STATE.landed_state`).
//! Operator commands are checked against the state: a forbidden one is refused with a
//! [`Refusal`] naming the state. Telemetry never refuses; it moves the state to what the
//! vehicle is observed to do.
//!
//! Rules worth knowing:
//! - Commands that PX4 carries out itself (arm, disarm) do not change the state: the
//!   state follows the armed flag when telemetry reports it.
//! - In the offboard states ([`VehicleState::Hovering`], [`VehicleState::InFormation`],
//!   [`VehicleState::GoTo`]) a mode other than OFFBOARD that skein did not command means
//!   PX4 took over (offboard loss, RC, battery): [`VehicleState::Failsafe`].
//! - [`VehicleState::TakingOff`] ignores the armed flag: the takeoff procedure arms and
//!   reports its own failure ([`Event::ProcedureFailed`]).
//! - [`VehicleState::Failsafe`] means "airborne and not under skein's control".

pub use crate::command::CommandKind;
use crate::px4::{LandedState, Px4Mode};
use serde::{Deserialize, Serialize};

/// The state of one vehicle as skein sees it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, utoipa::ToSchema)]
pub enum VehicleState {
    /// Never heard from (configured but no heartbeat yet).
    Disconnected,
    /// On the ground, disarmed.
    Landed,
    /// On the ground, armed.
    Armed,
    /// Climbing to the takeoff altitude under skein's offboard control.
    TakingOff,
    /// Airborne, holding a position under skein's offboard control.
    Hovering,
    /// Airborne, tracking its formation slot.
    InFormation,
    /// Airborne, flying to an operator-given point.
    GoTo,
    /// Landing (PX4 LAND mode).
    Landing,
    /// Returning to launch (PX4 RTL mode).
    ReturnToLaunch,
    /// Airborne and not under skein's control: PX4 left the mode skein commanded
    /// (offboard loss, RC override, battery failsafe) or was found flying another mode.
    Failsafe,
    /// No valid message for the link timeout (3 s); state restored when it comes back.
    Lost,
}

impl VehicleState {
    /// Every state, for exhaustive tests and UIs.
    pub const ALL: [VehicleState; 11] = [
        VehicleState::Disconnected,
        VehicleState::Landed,
        VehicleState::Armed,
        VehicleState::TakingOff,
        VehicleState::Hovering,
        VehicleState::InFormation,
        VehicleState::GoTo,
        VehicleState::Landing,
        VehicleState::ReturnToLaunch,
        VehicleState::Failsafe,
        VehicleState::Lost,
    ];

    /// The state's name as the API shows it (`"InFormation"`).
    pub fn name(self) -> &'static str {
        match self {
            VehicleState::Disconnected => "Disconnected",
            VehicleState::Landed => "Landed",
            VehicleState::Armed => "Armed",
            VehicleState::TakingOff => "TakingOff",
            VehicleState::Hovering => "Hovering",
            VehicleState::InFormation => "InFormation",
            VehicleState::GoTo => "GoTo",
            VehicleState::Landing => "Landing",
            VehicleState::ReturnToLaunch => "ReturnToLaunch",
            VehicleState::Failsafe => "Failsafe",
            VehicleState::Lost => "Lost",
        }
    }

    /// True while skein is streaming offboard setpoints that PX4 should be following.
    pub fn is_offboard(self) -> bool {
        matches!(
            self,
            VehicleState::Hovering | VehicleState::InFormation | VehicleState::GoTo
        )
    }

    /// True for the states in which the vehicle is (or may be) in the air.
    pub fn is_airborne(self) -> bool {
        matches!(
            self,
            VehicleState::TakingOff
                | VehicleState::Hovering
                | VehicleState::InFormation
                | VehicleState::GoTo
                | VehicleState::Landing
                | VehicleState::ReturnToLaunch
                | VehicleState::Failsafe
        )
    }

    /// True when there is a live link (not `Disconnected` and not `Lost`).
    pub fn is_connected(self) -> bool {
        !matches!(self, VehicleState::Disconnected | VehicleState::Lost)
    }
}

impl std::fmt::Display for VehicleState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// What telemetry says about the vehicle: armed flag and mode from `HEARTBEAT`, landed
/// state from `EXTENDED_SYS_STATE`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Observed {
    /// `HEARTBEAT.base_mode & MAV_MODE_FLAG_SAFETY_ARMED`.
    pub armed: bool,
    /// Decoded `HEARTBEAT.custom_mode`.
    pub mode: Px4Mode,
    /// `EXTENDED_SYS_STATE.landed_state`.
    pub landed: LandedState,
}

impl Observed {
    /// True when the vehicle is armed and the landed state says airborne. A disarmed
    /// multicopter is not flying whatever an older `EXTENDED_SYS_STATE` said (right after
    /// a link comes back, the landed state may still be the one from before the loss,
    /// while the fresh heartbeat already says disarmed).
    pub fn airborne(&self) -> bool {
        self.armed && self.landed.is_airborne()
    }
}

/// An input to the FSM.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Event {
    /// An operator command ([`crate::command::Command`]'s kind): may be refused.
    Command(CommandKind),
    /// Fresh telemetry.
    Observed(Observed),
    /// First heartbeat of a vehicle never heard from before.
    Connected(Observed),
    /// No valid message for the link timeout.
    LinkLost,
    /// Messages again after [`Event::LinkLost`].
    LinkRestored(Observed),
    /// The takeoff procedure reached its altitude.
    TakeoffComplete,
    /// The go-to procedure reached its point.
    GoToReached,
    /// A running procedure (takeoff, go-to, land …) failed; settle on what telemetry says.
    ProcedureFailed(Observed),
}

/// Why a command was refused: the state that forbids it and a sentence for the operator.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Refusal {
    /// The command that was refused.
    pub command: CommandKind,
    /// The state that refused it.
    pub state: VehicleState,
    /// Human-readable reason, naming the state.
    pub reason: String,
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.reason)
    }
}

impl std::error::Error for Refusal {}

/// The state telemetry alone implies, used when skein has no procedure running for the
/// vehicle (on connect, after a link loss, after a failed procedure).
pub fn settle(obs: Observed) -> VehicleState {
    if !obs.airborne() {
        return if obs.armed {
            VehicleState::Armed
        } else {
            VehicleState::Landed
        };
    }
    match obs.mode {
        Px4Mode::Offboard => VehicleState::Hovering,
        Px4Mode::Land | Px4Mode::Precland => VehicleState::Landing,
        Px4Mode::Rtl => VehicleState::ReturnToLaunch,
        _ => VehicleState::Failsafe,
    }
}

/// The transition function: the next state for `state` given `event`, or a [`Refusal`]
/// when `event` is a command the state forbids. Only commands are ever refused.
pub fn transition(state: VehicleState, event: Event) -> Result<VehicleState, Refusal> {
    use VehicleState as S;
    match event {
        Event::Command(cmd) => on_command(state, cmd),
        Event::Connected(obs) => Ok(match state {
            S::Disconnected => settle(obs),
            other => other,
        }),
        Event::LinkLost => Ok(match state {
            S::Disconnected => S::Disconnected,
            _ => S::Lost,
        }),
        Event::LinkRestored(obs) => Ok(match state {
            S::Lost => settle(obs),
            other => other,
        }),
        Event::TakeoffComplete => Ok(match state {
            S::TakingOff => S::Hovering,
            other => other,
        }),
        Event::GoToReached => Ok(match state {
            S::GoTo => S::Hovering,
            other => other,
        }),
        Event::ProcedureFailed(obs) => Ok(match state {
            S::Disconnected | S::Lost => state,
            _ => settle(obs),
        }),
        Event::Observed(obs) => Ok(on_observed(state, obs)),
    }
}

fn on_observed(state: VehicleState, obs: Observed) -> VehicleState {
    use VehicleState as S;
    let landed_disarmed = !obs.armed && !obs.airborne();
    match state {
        // Telemetry alone does not connect or restore a vehicle: those are link events.
        S::Disconnected | S::Lost => state,
        S::Landed | S::Armed => settle(obs),
        // The takeoff procedure owns arming and mode entry; it reports failure itself.
        // PX4 switching to LAND or RTL on its own during the climb is a failsafe.
        S::TakingOff => match obs.mode {
            Px4Mode::Land | Px4Mode::Rtl | Px4Mode::Precland if obs.armed => S::Failsafe,
            _ => S::TakingOff,
        },
        S::Hovering | S::InFormation | S::GoTo => {
            if landed_disarmed {
                S::Landed
            } else if obs.mode == Px4Mode::Offboard {
                state
            } else {
                S::Failsafe
            }
        }
        S::Landing => {
            if landed_disarmed {
                S::Landed
            } else {
                match obs.mode {
                    // OFFBOARD until the LAND command shows up in the next heartbeat.
                    Px4Mode::Land | Px4Mode::Precland | Px4Mode::Offboard => S::Landing,
                    Px4Mode::Rtl => S::ReturnToLaunch,
                    _ if !obs.airborne() => S::Landing,
                    _ => S::Failsafe,
                }
            }
        }
        S::ReturnToLaunch => {
            if landed_disarmed {
                S::Landed
            } else {
                match obs.mode {
                    Px4Mode::Rtl | Px4Mode::Land | Px4Mode::Offboard => S::ReturnToLaunch,
                    _ if !obs.airborne() => S::ReturnToLaunch,
                    _ => S::Failsafe,
                }
            }
        }
        S::Failsafe => {
            if landed_disarmed {
                S::Landed
            } else if !obs.airborne() && obs.armed {
                S::Armed
            } else {
                S::Failsafe
            }
        }
    }
}

fn on_command(state: VehicleState, cmd: CommandKind) -> Result<VehicleState, Refusal> {
    use CommandKind as C;
    use VehicleState as S;
    let refuse = |why: &str| {
        Err(Refusal {
            command: cmd,
            state,
            reason: format!("{} refused: vehicle is {state} ({why})", cmd.name()),
        })
    };
    if cmd == C::ClearHazard {
        return refuse("clear_hazard is the coordinator's: it changes the formation's hazards");
    }
    if !state.is_connected() {
        return refuse("no link to the vehicle");
    }
    match cmd {
        C::Arm => match state {
            S::Landed => Ok(S::Landed),
            S::Armed => refuse("already armed"),
            _ => refuse("already airborne"),
        },
        C::ForceDisarm => Ok(state),
        C::Disarm => match state {
            S::Armed => Ok(S::Armed),
            S::Landed => refuse("already disarmed"),
            _ => refuse("airborne: land first, or force_disarm in an emergency"),
        },
        C::Takeoff => match state {
            S::Landed | S::Armed => Ok(S::TakingOff),
            S::TakingOff => refuse("already taking off"),
            _ => refuse("already airborne"),
        },
        C::Land => match state {
            S::TakingOff
            | S::Hovering
            | S::InFormation
            | S::GoTo
            | S::ReturnToLaunch
            | S::Failsafe => Ok(S::Landing),
            S::Landing => refuse("already landing"),
            _ => refuse("on the ground"),
        },
        C::Rtl => match state {
            S::TakingOff | S::Hovering | S::InFormation | S::GoTo | S::Landing | S::Failsafe => {
                Ok(S::ReturnToLaunch)
            }
            S::ReturnToLaunch => refuse("already returning"),
            _ => refuse("on the ground"),
        },
        C::Hold => match state {
            S::TakingOff
            | S::Hovering
            | S::InFormation
            | S::GoTo
            | S::Landing
            | S::ReturnToLaunch
            | S::Failsafe => Ok(S::Hovering),
            _ => refuse("on the ground"),
        },
        C::GoTo => match state {
            S::Hovering | S::InFormation | S::GoTo | S::Failsafe => Ok(S::GoTo),
            S::TakingOff => refuse("still taking off"),
            S::Landing | S::ReturnToLaunch => refuse("landing or returning: hold first"),
            _ => refuse("on the ground: take off first"),
        },
        C::JoinFormation => match state {
            S::Hovering | S::InFormation | S::GoTo => Ok(S::InFormation),
            S::TakingOff => refuse("still taking off: it joins when the climb completes"),
            S::Failsafe => refuse("PX4 has control: hold first"),
            S::Landing | S::ReturnToLaunch => refuse("landing or returning: hold first"),
            _ => refuse("on the ground: take off first"),
        },
        C::LeaveFormation => match state {
            S::InFormation => Ok(S::Hovering),
            _ => refuse("not in formation"),
        },
        C::ClearHazard => unreachable!("refused above"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use VehicleState as S;
    use strum::IntoEnumIterator;

    fn obs(armed: bool, mode: Px4Mode, landed: LandedState) -> Observed {
        Observed {
            armed,
            mode,
            landed,
        }
    }

    fn all_observations() -> Vec<Observed> {
        let mut v = Vec::new();
        for armed in [false, true] {
            for mode in Px4Mode::ALL
                .into_iter()
                .chain([Px4Mode::Unknown(0x0909_0000)])
            {
                for landed in [
                    LandedState::Undefined,
                    LandedState::OnGround,
                    LandedState::InAir,
                    LandedState::Takeoff,
                    LandedState::Landing,
                ] {
                    v.push(obs(armed, mode, landed));
                }
            }
        }
        v
    }

    fn all_events() -> Vec<Event> {
        let mut v: Vec<Event> = CommandKind::iter().map(Event::Command).collect();
        v.extend([Event::LinkLost, Event::TakeoffComplete, Event::GoToReached]);
        for o in all_observations() {
            v.extend([
                Event::Observed(o),
                Event::Connected(o),
                Event::LinkRestored(o),
                Event::ProcedureFailed(o),
            ]);
        }
        v
    }

    /// The expected command table, written out independently of `on_command`:
    /// `Some(next)` = accepted, `None` = refused.
    fn expected_command(state: S, cmd: CommandKind) -> Option<S> {
        use CommandKind as C;
        let airborne_cmds_from = [
            S::TakingOff,
            S::Hovering,
            S::InFormation,
            S::GoTo,
            S::Landing,
            S::ReturnToLaunch,
            S::Failsafe,
        ];
        if matches!(state, S::Disconnected | S::Lost) {
            return None;
        }
        match (cmd, state) {
            (C::Arm, S::Landed) => Some(S::Landed),
            (C::Arm, _) => None,
            (C::ForceDisarm, s) => Some(s),
            (C::Disarm, S::Armed) => Some(S::Armed),
            (C::Disarm, _) => None,
            (C::Takeoff, S::Landed | S::Armed) => Some(S::TakingOff),
            (C::Takeoff, _) => None,
            (C::Land, S::Landing) => None,
            (C::Land, s) if airborne_cmds_from.contains(&s) => Some(S::Landing),
            (C::Land, _) => None,
            (C::Rtl, S::ReturnToLaunch) => None,
            (C::Rtl, s) if airborne_cmds_from.contains(&s) => Some(S::ReturnToLaunch),
            (C::Rtl, _) => None,
            (C::Hold, s) if airborne_cmds_from.contains(&s) => Some(S::Hovering),
            (C::Hold, _) => None,
            (C::GoTo, S::Hovering | S::InFormation | S::GoTo | S::Failsafe) => Some(S::GoTo),
            (C::GoTo, _) => None,
            (C::JoinFormation, S::Hovering | S::InFormation | S::GoTo) => Some(S::InFormation),
            (C::JoinFormation, _) => None,
            (C::LeaveFormation, S::InFormation) => Some(S::Hovering),
            (C::LeaveFormation, _) => None,
            // The coordinator's, never the vehicle's.
            (C::ClearHazard, _) => None,
        }
    }

    #[test]
    fn every_state_times_every_command_matches_the_table() {
        for state in S::ALL {
            for cmd in CommandKind::iter() {
                let got = transition(state, Event::Command(cmd));
                match (expected_command(state, cmd), got) {
                    (Some(next), Ok(s)) => assert_eq!(s, next, "{state} + {cmd:?}"),
                    (None, Err(refusal)) => {
                        assert_eq!(refusal.state, state);
                        assert_eq!(refusal.command, cmd);
                        assert!(
                            refusal.reason.contains(state.name()),
                            "reason must name the state: {}",
                            refusal.reason
                        );
                        assert!(refusal.reason.starts_with(cmd.name()));
                    }
                    (want, got) => panic!("{state} + {cmd:?}: expected {want:?}, got {got:?}"),
                }
            }
        }
    }

    #[test]
    fn every_state_times_every_event_is_defined_and_only_commands_refuse() {
        let events = all_events();
        assert_eq!(events.len(), 11 + 3 + 4 * 2 * 15 * 5);
        for state in S::ALL {
            for &ev in &events {
                let r = transition(state, ev);
                if !matches!(ev, Event::Command(_)) {
                    let next = r.unwrap_or_else(|e| panic!("{state} + {ev:?} refused: {e}"));
                    // Telemetry never invents a connection.
                    if matches!(state, S::Disconnected) {
                        assert!(
                            matches!(ev, Event::Connected(_)) || next == S::Disconnected,
                            "{state} + {ev:?} -> {next}"
                        );
                    }
                    if matches!(ev, Event::LinkLost) && state != S::Disconnected {
                        assert_eq!(next, S::Lost);
                    }
                }
            }
        }
    }

    #[test]
    fn landed_and_disarmed_always_ends_in_landed_except_during_takeoff() {
        for state in S::ALL {
            for mode in Px4Mode::ALL {
                let next = transition(
                    state,
                    Event::Observed(obs(false, mode, LandedState::OnGround)),
                )
                .unwrap();
                match state {
                    S::Disconnected | S::Lost | S::TakingOff => assert_eq!(next, state),
                    _ => assert_eq!(next, S::Landed, "{state} in {mode}"),
                }
            }
        }
    }

    #[test]
    fn offboard_states_fall_to_failsafe_when_px4_leaves_offboard() {
        for state in [S::Hovering, S::InFormation, S::GoTo] {
            for mode in Px4Mode::ALL {
                let next = transition(state, Event::Observed(obs(true, mode, LandedState::InAir)))
                    .unwrap();
                if mode == Px4Mode::Offboard {
                    assert_eq!(next, state);
                } else {
                    assert_eq!(next, S::Failsafe, "{state} in {mode}");
                }
            }
        }
    }

    #[test]
    fn a_whole_flight() {
        let ground = obs(false, Px4Mode::Hold, LandedState::OnGround);
        let mut s = S::Disconnected;
        let step = |s: &mut S, e: Event| *s = transition(*s, e).unwrap();
        step(&mut s, Event::Connected(ground));
        assert_eq!(s, S::Landed);
        step(&mut s, Event::Command(CommandKind::Takeoff));
        assert_eq!(s, S::TakingOff);
        // Still disarmed on the ground while the procedure arms: no bounce to Landed.
        step(&mut s, Event::Observed(ground));
        assert_eq!(s, S::TakingOff);
        step(
            &mut s,
            Event::Observed(obs(true, Px4Mode::Offboard, LandedState::InAir)),
        );
        step(&mut s, Event::TakeoffComplete);
        assert_eq!(s, S::Hovering);
        step(&mut s, Event::Command(CommandKind::JoinFormation));
        assert_eq!(s, S::InFormation);
        step(&mut s, Event::Command(CommandKind::Land));
        assert_eq!(s, S::Landing);
        step(
            &mut s,
            Event::Observed(obs(true, Px4Mode::Offboard, LandedState::InAir)),
        );
        assert_eq!(s, S::Landing, "LAND not yet in the heartbeat");
        step(
            &mut s,
            Event::Observed(obs(true, Px4Mode::Land, LandedState::Landing)),
        );
        step(
            &mut s,
            Event::Observed(obs(true, Px4Mode::Land, LandedState::OnGround)),
        );
        assert_eq!(s, S::Landing);
        step(
            &mut s,
            Event::Observed(obs(false, Px4Mode::Land, LandedState::OnGround)),
        );
        assert_eq!(s, S::Landed);
    }

    #[test]
    fn lost_and_restored() {
        let flying = obs(true, Px4Mode::Offboard, LandedState::InAir);
        let s = transition(S::InFormation, Event::LinkLost).unwrap();
        assert_eq!(s, S::Lost);
        assert_eq!(
            transition(s, Event::Observed(flying)).unwrap(),
            S::Lost,
            "only a link event restores"
        );
        assert_eq!(
            transition(s, Event::LinkRestored(flying)).unwrap(),
            S::Hovering
        );
        let rtl = obs(true, Px4Mode::Rtl, LandedState::InAir);
        assert_eq!(
            transition(s, Event::LinkRestored(rtl)).unwrap(),
            S::ReturnToLaunch
        );
        // Landed by its failsafe while unseen: the fresh heartbeat says disarmed (and, as
        // PX4 v1.16 does after a disarm, OFFBOARD) while the landed state is still the
        // one from before the loss. Disarmed is on the ground.
        let landed_unseen = obs(false, Px4Mode::Offboard, LandedState::InAir);
        assert_eq!(
            transition(s, Event::LinkRestored(landed_unseen)).unwrap(),
            S::Landed
        );
    }

    #[test]
    fn settle_covers_ground_and_air() {
        assert_eq!(
            settle(obs(false, Px4Mode::Hold, LandedState::OnGround)),
            S::Landed
        );
        assert_eq!(
            settle(obs(true, Px4Mode::Hold, LandedState::OnGround)),
            S::Armed
        );
        assert_eq!(
            settle(obs(true, Px4Mode::Hold, LandedState::InAir)),
            S::Failsafe
        );
        assert_eq!(
            settle(obs(true, Px4Mode::Land, LandedState::Landing)),
            S::Landing
        );
        assert_eq!(
            settle(obs(true, Px4Mode::Offboard, LandedState::InAir)),
            S::Hovering
        );
    }
}
