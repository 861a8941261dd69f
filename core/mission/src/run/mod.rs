//! A mission run: the plan flown step by step on ticks. Each tick the caller gives the
//! time and the vehicles as they are ([`Tick`]); the run answers with what to command
//! ([`Action`]) and keeps its state and progress ([`RunStatus`]). Time is the caller's
//! (seconds on any monotonic clock); a paused run's steps do not age.
//!
//! Control: [`MissionRun::pause`] holds the step's vehicles (a formation's leader), and
//! [`MissionRun::resume`] carries on where it was; [`MissionRun::skip`] ends the step
//! (its vehicles hold) and starts the next; [`MissionRun::abort`] holds every airborne
//! vehicle, then the plan's abort (return or land) one vehicle after the other.

mod intruder;
mod meet;
mod route;
mod step;
mod swap;
mod takeover;

pub use route::{ARRIVED_M, RESEND_S, Route, arrived};
pub use step::{StepProgress, TAKEOFF_TOLERANCE_M};
pub use swap::Reaction;

use crate::plan::{AbortAction, InTurn, MissionPlan, StepKind};
use serde::{Deserialize, Serialize};
use skein_formation::{FormationSpec, LeaderMotion};
use skein_model::command::Command;
use skein_model::fsm::VehicleState;
use skein_model::geo::Ned;
use std::collections::{BTreeMap, BTreeSet};
use step::Active;
use utoipa::ToSchema;

/// Seconds an abort holds everyone before its return or landing.
pub const ABORT_HOLD_S: f64 = 1.0;

/// A vehicle as a tick sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct VehicleView {
    /// Vehicle id.
    pub id: String,
    /// Its FSM state.
    pub state: VehicleState,
    /// Swarm-frame position, metres; `None` before one is known.
    pub position: Option<Ned>,
    /// Velocity, NED m/s; `None` when not known (a lane's start is then reached on the
    /// position alone).
    pub velocity: Option<Ned>,
    /// Height above its home, metres.
    pub relative_alt_m: Option<f64>,
    /// Battery, percent.
    pub battery_percent: Option<f64>,
    /// It carries a gimbal: it can observe a track.
    pub observer: bool,
}

/// A track as a tick sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackSeen {
    /// Track id (`track-N`).
    pub id: String,
    /// Its estimated position, swarm-frame NED, metres.
    pub position: Ned,
    /// Confirmed and being updated (not tentative, not lost).
    pub confirmed: bool,
}

/// What the run is given on a tick.
#[derive(Debug, Clone)]
pub struct Tick {
    /// Now, seconds on the caller's monotonic clock.
    pub now_s: f64,
    /// Every vehicle, by id.
    pub vehicles: BTreeMap<String, VehicleView>,
    /// The formation's reference point (its virtual leader), when one flies.
    pub reference: Option<Ned>,
    /// The tracks the swarm holds.
    pub tracks: Vec<TrackSeen>,
}

/// What the run asks the swarm to do.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    /// A command to one vehicle.
    Command {
        /// Vehicle id.
        vehicle: String,
        /// The command.
        command: Command,
    },
    /// Fly this formation (every airborne vehicle joins).
    SetFormation(FormationSpec),
    /// Move the formation's virtual leader.
    LeaderMotion(LeaderMotion),
    /// Stop flying the formation (its members hold).
    ClearFormation,
    /// Observe a track: the vehicles' gimbals follow it and, with `stations`, they fly to
    /// the stations that fix it best (the API's `POST /api/v1/tracks/{id}/observe`).
    Observe {
        /// The track (`track-N`).
        target: String,
        /// The observers.
        vehicles: Vec<String>,
        /// Fly them to observation stations.
        stations: bool,
        /// The stations' stand-off, metres (`None`: the swarm's default).
        standoff_m: Option<f64>,
    },
    /// Stop observing a track (its observers hold, then fly their routes on).
    StopObserving {
        /// The track.
        target: String,
    },
}

/// Where a run stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum RunState {
    /// Stored, not started.
    Ready,
    /// Flying its steps.
    Running,
    /// Paused by the operator (or stopped by a refused action: `error` says why).
    Paused,
    /// Every step done.
    Done,
    /// Aborted: its vehicles returned or landed.
    Aborted,
}

/// Where a step stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum StepState {
    /// Not reached yet.
    Pending,
    /// Being flown.
    Running,
    /// Done.
    Done,
    /// Ended by a skip or an abort.
    Skipped,
}

/// One step's record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct StepStatus {
    /// Its kind (`takeoff`, `survey`, ...).
    #[serde(deserialize_with = "takeover::step_kind")]
    #[schema(value_type = String)]
    pub kind: takeover::Name,
    /// Where it stands.
    pub state: StepState,
    /// Its vehicles (resolved at start), by id.
    pub vehicles: Vec<String>,
    /// Mission seconds when it started; `null` before.
    pub started_s: Option<f64>,
    /// Mission seconds when it ended; `null` before.
    pub ended_s: Option<f64>,
    /// How far along it is (the running step), or was.
    pub progress: Option<StepProgress>,
}

/// A run's state and progress (`GET /api/v1/missions/{id}`'s).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct RunStatus {
    /// Where it stands.
    pub state: RunState,
    /// The step being flown (index), or the last one flown.
    pub step: usize,
    /// Mission seconds flown (pauses not counted).
    pub elapsed_s: f64,
    /// Every step.
    pub steps: Vec<StepStatus>,
    /// Why it stopped, when something refused it.
    pub error: Option<String>,
    /// What the run did by itself (the plan's reactions), oldest first.
    pub reactions: Vec<Reaction>,
}

/// A plan being flown (see the module docs). Serialised whole, it is what the active
/// coordinator mirrors to the standbys ([`MissionRun::take_over`]).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MissionRun {
    plan: MissionPlan,
    status: RunStatus,
    active: Option<Active>,
    /// The caller's time at the last tick, and the mission seconds then.
    last_now_s: Option<f64>,
    aborting: Option<Abort>,
    /// The next step waits for vehicles sent home, its vehicles held.
    #[serde(default)]
    waiting: bool,
    swaps: Option<swap::Swaps>,
    intrusions: Option<intruder::Intrusions>,
}

/// An abort under way: every vehicle holding since `since_s`, then `kind` (return or
/// land) for `ids`.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Abort {
    since_s: f64,
    kind: StepKind,
    ids: Vec<String>,
    landing: Option<Active>,
}

impl MissionRun {
    /// A run of `plan` whose steps fly `groups` (each step's vehicles, from
    /// [`crate::resolve::groups`]), ready to start.
    pub fn new(plan: MissionPlan, groups: Vec<Vec<String>>) -> Self {
        let plan_swaps = plan.reactions.low_battery.clone().map(swap::Swaps::new);
        let intrusions = plan
            .reactions
            .intruder
            .clone()
            .map(intruder::Intrusions::new);
        let steps = plan
            .steps
            .iter()
            .zip(groups)
            .map(|(s, vehicles)| StepStatus {
                kind: s.kind.name(),
                state: StepState::Pending,
                vehicles,
                started_s: None,
                ended_s: None,
                progress: None,
            })
            .collect();
        MissionRun {
            plan,
            status: RunStatus {
                state: RunState::Ready,
                step: 0,
                elapsed_s: 0.0,
                steps,
                error: None,
                reactions: Vec::new(),
            },
            active: None,
            last_now_s: None,
            aborting: None,
            waiting: false,
            swaps: plan_swaps,
            intrusions,
        }
    }

    /// The plan.
    pub fn plan(&self) -> &MissionPlan {
        &self.plan
    }

    /// Its state and progress.
    pub fn status(&self) -> &RunStatus {
        &self.status
    }

    /// Starts flying (a run that is not ready is left alone).
    pub fn start(&mut self) {
        if self.status.state == RunState::Ready {
            self.status.state = RunState::Running;
        }
    }

    /// One tick (see [`Tick`]): advances the mission clock while running, and answers
    /// what to command.
    pub fn tick(&mut self, tick: &Tick) -> Vec<Action> {
        let dt = self.last_now_s.map_or(0.0, |t| (tick.now_s - t).max(0.0));
        self.last_now_s = Some(tick.now_s);
        let mut out = Vec::new();
        if self.status.state != RunState::Running {
            return out;
        }
        self.status.elapsed_s += dt;
        let t = self.clock(tick);
        if self.aborting.is_some() {
            self.tick_abort(&t, &mut out);
            return out;
        }
        loop {
            let i = self.status.step;
            if self.active.is_none() && self.status.steps[i].vehicles.is_empty() {
                // Every vehicle of the step was sent home before it began.
                self.status.steps[i].started_s = Some(t.now_s);
                self.end_step(StepState::Skipped, t.now_s, &mut out);
                if self.status.state != RunState::Running {
                    return out;
                }
                continue;
            }
            if self.active.is_none() && self.returning(&t) {
                self.hold_while_waiting(i, &t, &mut out);
                return out;
            }
            self.waiting = false;
            if self.active.is_none() {
                let (active, start) =
                    Active::start(&self.plan.steps[i].kind, &self.status.steps[i].vehicles, &t);
                out.extend(start);
                self.active = Some(active);
                self.status.steps[i].state = StepState::Running;
                self.status.steps[i].started_s = Some(t.now_s);
            }
            let active = self.active.as_mut().expect("a running step");
            if let Some(swaps) = &mut self.swaps {
                let took = swaps.tick(
                    active,
                    &self.status.steps[i].vehicles,
                    &t,
                    &mut out,
                    &mut self.status.reactions,
                );
                // A reserve flies the rest of the mission in the low vehicle's place.
                for (low, reserve) in took {
                    for step in &mut self.status.steps[i..] {
                        for v in step.vehicles.iter_mut().filter(|v| **v == low) {
                            v.clone_from(&reserve);
                        }
                    }
                }
                // One sent home with none in its place flies no later step.
                for id in swaps.retired() {
                    for step in &mut self.status.steps[i + 1..] {
                        step.vehicles.retain(|v| v != id);
                    }
                }
            }
            if let Some(intrusions) = &mut self.intrusions {
                intrusions.tick(
                    active,
                    &self.status.steps[i].vehicles,
                    &t,
                    &mut out,
                    &mut self.status.reactions,
                );
            }
            let done = active.tick(&t, &mut out);
            self.status.steps[i].progress = Some(active.progress(t.now_s));
            if !done {
                return out;
            }
            active.end(&mut out);
            self.end_step(StepState::Done, t.now_s, &mut out);
            if self.status.state != RunState::Running {
                return out;
            }
        }
    }

    /// A vehicle the low-battery reaction sent home is still in the air: the next step
    /// waits for it. Its return is PX4's (RTL), which skein does not deconflict, and a
    /// step's start sends many vehicles across the area at once (a rehearsal saw one
    /// flying to its station pass 1.5 m from one landing at home).
    fn returning(&self, t: &Tick) -> bool {
        self.swaps.as_ref().is_some_and(|s| {
            s.sent_home()
                .iter()
                .any(|id| t.vehicles.get(id).is_some_and(|v| v.state.is_airborne()))
        })
    }

    /// Holds the vehicles of step `i` still flying their last step's way, once, while it
    /// waits (a patrol's vehicles would fly on to their next corners).
    fn hold_while_waiting(&mut self, i: usize, t: &Tick, out: &mut Vec<Action>) {
        if std::mem::replace(&mut self.waiting, true) {
            return;
        }
        for id in &self.status.steps[i].vehicles {
            if t.vehicles
                .get(id)
                .is_some_and(|v| v.state == VehicleState::GoTo)
            {
                out.push(Action::Command {
                    vehicle: id.clone(),
                    command: Command::Hold,
                });
            }
        }
    }

    /// `tick` on the mission clock.
    fn clock(&self, tick: &Tick) -> Tick {
        Tick {
            now_s: self.status.elapsed_s,
            ..tick.clone()
        }
    }

    fn end_step(&mut self, state: StepState, now_s: f64, out: &mut Vec<Action>) {
        if let Some(intrusions) = &mut self.intrusions {
            intrusions.end_all(out);
        }
        let i = self.status.step;
        self.status.steps[i].state = state;
        self.status.steps[i].ended_s = Some(now_s);
        self.active = None;
        if i + 1 == self.status.steps.len() {
            self.status.state = RunState::Done;
        } else {
            self.status.step = i + 1;
        }
    }

    /// Holds the step's vehicles; a running run only.
    pub fn pause(&mut self) -> Vec<Action> {
        self.pause_because(None)
    }

    /// Pauses because an action was refused (`why`), holding the step's vehicles.
    pub fn stop_on(&mut self, why: String) -> Vec<Action> {
        self.pause_because(Some(why))
    }

    fn pause_because(&mut self, why: Option<String>) -> Vec<Action> {
        let mut out = Vec::new();
        if self.status.state != RunState::Running || self.aborting.is_some() {
            return out;
        }
        self.status.state = RunState::Paused;
        self.status.error = why;
        if let Some(a) = &self.active {
            a.hold(&self.status.steps[self.status.step].vehicles, &mut out);
        }
        out
    }

    /// Carries on after a pause.
    pub fn resume(&mut self) -> Vec<Action> {
        let mut out = Vec::new();
        if self.status.state != RunState::Paused {
            return out;
        }
        self.status.state = RunState::Running;
        self.status.error = None;
        if let Some(a) = &mut self.active {
            a.resume(&mut out);
        }
        out
    }

    /// Ends the step being flown (its vehicles hold) and goes on with the next; a running
    /// or paused run only.
    pub fn skip(&mut self) -> Vec<Action> {
        let mut out = Vec::new();
        if !matches!(self.status.state, RunState::Running | RunState::Paused)
            || self.aborting.is_some()
        {
            return out;
        }
        if let Some(a) = self.active.take() {
            a.hold(&self.status.steps[self.status.step].vehicles, &mut out);
            a.end(&mut out);
        }
        let paused = self.status.state == RunState::Paused;
        self.end_step(StepState::Skipped, self.status.elapsed_s, &mut out);
        if paused && self.status.state != RunState::Done {
            self.status.state = RunState::Running;
        }
        out
    }

    /// Holds every airborne vehicle of the plan, then returns or lands them (the plan's
    /// `abort`); a run not done or aborted yet only. `airborne` are the vehicles in the
    /// air now.
    pub fn abort(&mut self, airborne: &[String]) -> Vec<Action> {
        let mut out = Vec::new();
        if matches!(self.status.state, RunState::Done | RunState::Aborted)
            || self.aborting.is_some()
        {
            return out;
        }
        if let Some(intrusions) = &mut self.intrusions {
            intrusions.end_all(&mut out);
        }
        if let Some(a) = self.active.take() {
            a.end(&mut out);
            let i = self.status.step;
            self.status.steps[i].state = StepState::Skipped;
            self.status.steps[i].ended_s = Some(self.status.elapsed_s);
        }
        for id in airborne {
            out.push(Action::Command {
                vehicle: id.clone(),
                command: Command::Hold,
            });
        }
        let kind = match self.plan.abort {
            AbortAction::Return => StepKind::Return(InTurn { interval_s: 2.0 }),
            AbortAction::Land => StepKind::Land(InTurn { interval_s: 2.0 }),
        };
        self.aborting = Some(Abort {
            since_s: self.status.elapsed_s,
            kind,
            ids: airborne.to_vec(),
            landing: None,
        });
        self.status.state = RunState::Running;
        self.status.error = None;
        out
    }

    fn tick_abort(&mut self, t: &Tick, out: &mut Vec<Action>) {
        let Some(a) = self.aborting.as_mut() else {
            return;
        };
        if a.landing.is_none() {
            if t.now_s - a.since_s < ABORT_HOLD_S {
                return;
            }
            let (active, start) = Active::start(&a.kind, &a.ids, t);
            out.extend(start);
            a.landing = Some(active);
        }
        if a.landing.as_mut().expect("landing").tick(t, out) {
            self.status.state = RunState::Aborted;
        }
    }

    /// The swarm refused an [`Action::Observe`] of `target` (`why`): its observers go
    /// back to their routes, and the refusal is one of the run's reactions.
    pub fn observation_refused(&mut self, target: &str, why: &str) {
        let now_s = self.status.elapsed_s;
        if let Some(intrusions) = &mut self.intrusions {
            intrusions.refused(
                target,
                why,
                self.active.as_mut(),
                now_s,
                &mut self.status.reactions,
            );
        }
    }

    /// The vehicles observing a track for the run's intruder reaction now.
    pub fn observers(&self) -> BTreeSet<String> {
        self.intrusions
            .as_ref()
            .map(intruder::Intrusions::observers)
            .unwrap_or_default()
    }

    /// The run is aborting (holding or bringing its vehicles down).
    pub fn aborting(&self) -> bool {
        self.aborting.is_some() && self.status.state == RunState::Running
    }
}
#[cfg(test)]
mod tests;
