//! Missions on the coordinator: plans checked against the fence and the separation and
//! stored ([`store`]), started (groups resolved to vehicles, energy checked at each
//! vehicle's measured consumption, [`consumption`]), and flown by
//! a [`MissionRun`] ticked at [`MISSION_TICK`]: what it asks for goes to the vehicles as
//! the coordinator's own commands, to the formation engine as the operator's formation
//! and leader motion would. One mission flies at a time. Every change of a mission's
//! state or step is an event (`mission_*` on the stream). The active coordinator mirrors
//! the flying mission to the standbys, and one that takes the role flies it on
//! ([`takeover`]).

mod consumption;
mod rehearsal;
mod store;
mod takeover;

pub use rehearsal::rehearsal_swarm;
pub use store::MissionInfo;
pub use takeover::MissionMirror;

use super::CoordinatorState;
use super::messages::FieldError;
use super::observe::{ObserveRefusal, ObserveSpec};
use crate::events::SwarmEvent;
use crate::tracks::TrackStatus;
use ractor::RpcReplyPort;
use skein_mission::energy::{self, EnergyModel, Start};
use skein_mission::resolve::{self, Member};
use skein_mission::{
    Action, Limits, MissionPlan, MissionRun, RunState, Tick, TrackSeen, VehicleView,
};
use skein_model::command::Command;
use skein_model::fsm::VehicleState;
use skein_model::geo::Ned;
use std::collections::BTreeMap;
use std::time::Duration;

pub(crate) use store::Store;

/// How often a flying mission is ticked.
pub const MISSION_TICK: Duration = Duration::from_millis(500);

/// What can be done to a stored mission.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MissionControl {
    /// Resolve its groups, check its energy, fly it.
    Start,
    /// Hold its vehicles.
    Pause,
    /// Carry on.
    Resume,
    /// Hold everyone, then the plan's abort (return or land).
    Abort,
    /// End the step flown now; go on with the next.
    Skip,
}

/// Why a mission request was refused.
#[derive(Debug, Clone, PartialEq)]
pub enum MissionError {
    /// No mission of that id.
    NotFound(String),
    /// The plan does not fit the swarm as it is (a field and why): 400.
    Refused(FieldError),
    /// Not in a state that allows it: 409, why.
    Conflict(String),
}

/// Messages of the missions concept.
pub enum MissionMsg {
    /// Check and store a plan.
    Create(MissionPlan, RpcReplyPort<Result<MissionInfo, FieldError>>),
    /// Every mission.
    List(RpcReplyPort<Vec<MissionInfo>>),
    /// One mission.
    Get(String, RpcReplyPort<Option<MissionInfo>>),
    /// Start, pause, resume, abort or skip a mission.
    Control(
        String,
        MissionControl,
        RpcReplyPort<Result<MissionInfo, MissionError>>,
    ),
    /// What a rehearsal of a mission needs: its plan, its groups resolved, the swarm now.
    Rehearsal(
        String,
        RpcReplyPort<Result<skein_mission::swarm::RehearsalSetup, MissionError>>,
    ),
    /// The mission tick.
    Tick,
}

fn refused(e: skein_mission::PlanError) -> FieldError {
    FieldError {
        field: e.field,
        error: e.error,
    }
}

impl CoordinatorState {
    /// Handles a [`MissionMsg`].
    pub(super) fn handle_mission(&mut self, msg: MissionMsg) {
        match msg {
            MissionMsg::Create(plan, reply) => {
                let _ = reply.send(self.create_mission(plan));
            }
            MissionMsg::List(reply) => {
                let _ = reply.send(self.missions.infos());
            }
            MissionMsg::Get(id, reply) => {
                let _ = reply.send(self.missions.get(&id).map(|m| store::info(&id, m)));
            }
            MissionMsg::Control(id, what, reply) => {
                let _ = reply.send(self.control_mission(&id, what));
            }
            MissionMsg::Rehearsal(id, reply) => {
                let _ = reply.send(self.rehearsal_setup(&id));
            }
            MissionMsg::Tick => {
                self.mission_gate.done();
                self.measure_consumption();
                self.mission_tick();
            }
        }
    }

    /// What a plan is checked against: the fence in force, the separation kept, the
    /// slowest model's speed.
    fn mission_check(&self, plan: &MissionPlan) -> Result<(), FieldError> {
        check_plan(plan, &self.context.config, &self.context.geofence().fence).map_err(refused)
    }

    fn create_mission(&mut self, plan: MissionPlan) -> Result<MissionInfo, FieldError> {
        self.mission_check(&plan)?;
        let id = self.missions.add(plan);
        let m = self.missions.get(&id).expect("just added");
        Ok(store::info(&id, m))
    }

    fn control_mission(
        &mut self,
        id: &str,
        what: MissionControl,
    ) -> Result<MissionInfo, MissionError> {
        let m = self
            .missions
            .get(id)
            .ok_or_else(|| MissionError::NotFound(id.to_string()))?;
        if what == MissionControl::Start {
            let plan = m.plan.clone();
            let run = self.start_mission(id, plan)?;
            self.missions.get_mut(id).expect("found").run = Some(run);
            self.emit(SwarmEvent::MissionStarted { id: id.to_string() });
            self.mission_tick();
        } else {
            let airborne: Vec<String> = self
                .vehicles
                .iter()
                .filter(|(_, v)| v.state().is_airborne() && !goes_down(v.state()))
                .map(|(id, _)| id.clone())
                .collect();
            let run = self
                .missions
                .get_mut(id)
                .and_then(|m| m.run.as_mut())
                .ok_or_else(|| MissionError::Conflict(format!("mission {id} has not started")))?;
            let before = run.status().state;
            let actions = match what {
                MissionControl::Pause => run.pause(),
                MissionControl::Resume => run.resume(),
                MissionControl::Skip => run.skip(),
                MissionControl::Abort => run.abort(&airborne),
                MissionControl::Start => unreachable!("handled above"),
            };
            let after = run.status().state;
            let aborting = run.aborting();
            if before == after && actions.is_empty() && !aborting {
                return Err(MissionError::Conflict(format!(
                    "mission {id} is {}: it cannot be {what:?}ed now",
                    serde_json::to_string(&after)
                        .unwrap_or_default()
                        .trim_matches('"')
                )));
            }
            self.apply_mission(id, actions);
            self.emit(SwarmEvent::MissionControlled {
                id: id.to_string(),
                action: format!("{what:?}").to_lowercase(),
            });
        }
        let m = self.missions.get(id).expect("found");
        Ok(store::info(id, m))
    }

    /// Resolves `plan`'s groups against the swarm now, checks it again against the fence
    /// in force and each vehicle's battery; the run, started.
    fn start_mission(&mut self, id: &str, plan: MissionPlan) -> Result<MissionRun, MissionError> {
        if let Some((flying, _)) = self.missions.flying() {
            return Err(MissionError::Conflict(format!(
                "mission {flying} is flying: abort it first"
            )));
        }
        self.mission_check(&plan).map_err(MissionError::Refused)?;
        let snapshots: Vec<_> = self.vehicles.values().map(|v| v.snapshot()).collect();
        let members: Vec<Member> = snapshots
            .iter()
            .map(|s| Member {
                id: s.id.clone(),
                model: s.model.clone(),
            })
            .collect();
        let groups =
            resolve::groups(&plan, &members).map_err(|e| MissionError::Refused(refused(e)))?;
        let starts: BTreeMap<String, Start> = snapshots
            .iter()
            .map(|s| {
                let at = s.position.map_or([0.0, 0.0], |p| [p.north_m, p.east_m]);
                let battery_percent = s.battery.map(|b| b.percent).filter(|p| p.is_finite());
                (
                    s.id.clone(),
                    Start {
                        at,
                        battery_percent,
                        measured: self.measured_consumption(&s.id),
                    },
                )
            })
            .collect();
        let estimates = energy::estimate(&plan, &groups, &starts, &EnergyModel::default());
        energy::check(&estimates, &starts).map_err(|e| MissionError::Refused(refused(e)))?;
        tracing::info!("mission {id} `{}` starts", plan.name);
        let mut run = MissionRun::new(plan, groups);
        run.start();
        Ok(run)
    }

    /// Ticks the flying mission, if any (nothing is read while none flies).
    fn mission_tick(&mut self) {
        if self.missions.flying().is_none() {
            return;
        }
        let tick = self.mission_view();
        let Some((id, m)) = self.missions.flying() else {
            return;
        };
        let id = id.clone();
        let run = m.run.as_mut().expect("a flying mission has a run");
        let before = (run.status().state, run.status().step);
        let reacted = run.status().reactions.len();
        let actions = run.tick(&tick);
        let after = (run.status().state, run.status().step);
        self.apply_mission(&id, actions);
        // Reactions of the tick, and refusals of what it asked for.
        let reactions: Vec<String> = self
            .missions
            .get(&id)
            .and_then(|m| m.run.as_ref())
            .map(|r| {
                r.status().reactions[reacted..]
                    .iter()
                    .map(|r| r.detail.clone())
                    .collect()
            })
            .unwrap_or_default();
        for detail in reactions {
            tracing::info!("mission {id}: {detail}");
            self.emit(SwarmEvent::MissionReaction {
                id: id.clone(),
                detail,
            });
        }
        if before != after {
            self.emit(SwarmEvent::MissionStep {
                id,
                state: after.0,
                step: after.1,
            });
        }
    }

    /// The vehicles, the formation's reference and the tracks as a mission tick sees them.
    fn mission_view(&self) -> Tick {
        let tracks = self
            .tracking
            .shared()
            .tracks()
            .into_iter()
            .map(|t| TrackSeen {
                confirmed: t.status == TrackStatus::Confirmed,
                position: Ned::new(t.position.north_m, t.position.east_m, t.position.down_m),
                id: t.id,
            })
            .collect();
        let vehicles = self
            .vehicles
            .iter()
            .map(|(id, v)| {
                let s = v.snapshot();
                let view = VehicleView {
                    id: id.clone(),
                    state: v.state(),
                    position: s.position.map(|p| p.ned()),
                    velocity: s.position.map(|_| {
                        let v = s.velocity;
                        Ned::new(v.north_m_s, v.east_m_s, v.down_m_s)
                    }),
                    relative_alt_m: s.position.map(|p| p.relative_alt_m),
                    battery_percent: s.battery.map(|b| b.percent),
                    observer: self.gimbal_slot(id).is_some(),
                };
                (id.clone(), view)
            })
            .collect();
        Tick {
            now_s: self.started.elapsed().as_secs_f64(),
            vehicles,
            reference: self.formation_status().reference.map(|r| r.position),
            tracks,
        }
    }

    /// The intruder reaction of mission `id`: observes `target` with `vehicles`, from
    /// stations when asked and possible (else with the gimbals only); a refusal sends the
    /// observers back to their routes.
    fn mission_observe(
        &mut self,
        id: &str,
        target: String,
        vehicles: Vec<String>,
        stations: bool,
        standoff_m: Option<f64>,
    ) {
        let spec = ObserveSpec {
            target: target.clone(),
            vehicles: Some(vehicles),
            stations,
            standoff_m,
        };
        let mut result = self.observe(spec.clone());
        if stations && let Err(ObserveRefusal::NoStations(why)) = &result {
            tracing::info!("mission {id}: no stations for {target} ({why}): gimbals only");
            result = self.observe(ObserveSpec {
                stations: false,
                ..spec
            });
        }
        if let Err(e) = result
            && let Some(run) = self.missions.get_mut(id).and_then(|m| m.run.as_mut())
        {
            tracing::warn!("mission {id}: {target} not observed: {}", e.message());
            run.observation_refused(&target, e.message());
        }
    }

    /// Sends a command of mission `id` to `vehicle`, but a hold to a vehicle climbing to
    /// its takeoff altitude, landing or returning: it finishes that first (holding a
    /// climb or a PX4 landing half-way is what a pause, skip or abort must not do; the
    /// mission's own step logic waits for it either way).
    fn mission_command(&mut self, id: &str, vehicle: &str, command: Command) {
        let state = self.vehicles.get(vehicle).map(|v| v.state());
        if matches!(command, Command::Hold)
            && state.is_some_and(|s| s == VehicleState::TakingOff || goes_down(s))
        {
            tracing::info!("mission {id}: {vehicle} is {state:?}: not held");
            return;
        }
        self.internal_command(vehicle, command);
    }

    /// Carries out what mission `id` asked for; a formation or leader motion the
    /// coordinator refuses pauses the mission with the reason.
    fn apply_mission(&mut self, id: &str, actions: Vec<Action>) {
        let mut refusal = None;
        for a in actions {
            let result = match a {
                Action::Command { vehicle, command } => {
                    self.mission_command(id, &vehicle, command);
                    Ok(())
                }
                Action::SetFormation(spec) => self.set_formation(spec).map(drop),
                Action::LeaderMotion(m) => self.leader_motion(m).map(drop),
                Action::ClearFormation => {
                    self.clear_formation();
                    Ok(())
                }
                Action::Observe {
                    target,
                    vehicles,
                    stations,
                    standoff_m,
                } => {
                    self.mission_observe(id, target, vehicles, stations, standoff_m);
                    Ok(())
                }
                Action::StopObserving { target } => {
                    self.stop_observing(&target);
                    Ok(())
                }
            };
            if let Err(e) = result {
                refusal = Some(format!("{}: {}", e.field, e.error));
                break;
            }
        }
        let Some(why) = refusal else {
            return;
        };
        tracing::warn!("mission {id} paused: {why}");
        let held = self
            .missions
            .get_mut(id)
            .and_then(|m| m.run.as_mut())
            .map(|r| r.stop_on(why.clone()))
            .unwrap_or_default();
        for a in held {
            if let Action::Command { vehicle, command } = a {
                self.mission_command(id, &vehicle, command);
            }
        }
        self.emit(SwarmEvent::MissionStep {
            id: id.to_string(),
            state: RunState::Paused,
            step: self
                .missions
                .get(id)
                .and_then(|m| m.run.as_ref())
                .map_or(0, |r| r.status().step),
        });
    }
}

/// Checks `plan` against the swarm's settings `config` and geofence `fence` (see
/// [`skein_mission::validate`]: the fence with its buffer, the setpoint separation, the
/// formation slots' spacing, the slowest model's speed).
///
/// # Errors
/// The first field at fault.
pub fn check_plan(
    plan: &MissionPlan,
    config: &crate::SwarmConfig,
    fence: &skein_model::geofence::Geofence,
) -> Result<(), skein_mission::validate::PlanError> {
    let max_speed_m_s = config
        .models
        .values()
        .map(|m| m.limits.max_speed_m_s)
        .fold(f64::INFINITY, f64::min);
    let limits = Limits {
        fence,
        fence_margin_m: skein_formation::FENCE_BUFFER_M,
        separation_m: config.setpoint_separation_m(),
        min_slot_distance_m: config.min_slot_distance_m(),
        max_speed_m_s,
    };
    skein_mission::validate::check(plan, &limits)
}

/// A vehicle on its way down under PX4's own control (LAND or RTL): an abort or a pause
/// leaves it to finish.
fn goes_down(state: VehicleState) -> bool {
    matches!(state, VehicleState::Landing | VehicleState::ReturnToLaunch)
}
