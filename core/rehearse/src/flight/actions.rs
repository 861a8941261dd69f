//! The mission's actions in a rehearsal, carried out as the coordinator carries them out
//! (`skein_swarm::coordinator::missions`): commands to the vehicles (a refusal is noted),
//! the formation set with the hovering vehicles joining it, the leader's motion (a
//! refusal pauses the mission with the reason), the formation cleared with its members
//! holding, and observations: observers flown to the stations that fix the track best
//! (`skein_tracking::stations`, planned again every [`REPLAN_EVERY_S`]), holding when
//! it ends.

use super::Flight;
use skein_mission::Action;
use skein_model::command::{Command, GoTo};
use skein_model::fsm::VehicleState;
use skein_model::geo::Ned;
use skein_model::obstacles::Obstacle;
use skein_swarm::coordinator::stations::{
    CAMERA_FOV_DEG, DEFAULT_STANDOFF_M, FENCE_MARGIN_M, MAX_RANGE_M, REPLAN_EVERY_S, RESEND_M,
};
use skein_swarm::formation::LeaderMotion;
use skein_tracking::stations::{self, Observer, StationLimits};

/// One observation under way.
#[derive(Debug, Clone)]
pub(crate) struct Observation {
    vehicles: Vec<String>,
    /// Flown from stations (else with the gimbals only: nothing to fly).
    stations: bool,
    standoff_m: f64,
    /// Each observer's station, once planned.
    planned: Vec<(String, Ned)>,
    last_plan_s: f64,
}

/// The places of one other vehicle for a vehicle's separation: where it is (it gives way
/// when skein steers it) and, when steered, its setpoint.
pub(crate) fn obstacles(
    measured: Option<(Ned, Ned)>,
    steered: Option<(Ned, Ned)>,
    planned: bool,
    out: &mut Vec<Obstacle>,
) {
    if let Some((position, velocity)) = measured {
        out.push(Obstacle {
            position,
            velocity,
            reciprocal: steered.is_some(),
            planned,
        });
    }
    if let Some((position, velocity)) = steered {
        out.push(Obstacle {
            position,
            velocity,
            reciprocal: true,
            planned,
        });
    }
}

impl Flight {
    /// Carries out `actions`; a leader motion the formation engine refuses pauses the
    /// mission with the reason (its vehicles hold).
    pub(super) fn apply(&mut self, actions: Vec<Action>) {
        for a in actions {
            let refused = match a {
                Action::Command { vehicle, command } => {
                    self.command(&vehicle, &command);
                    None
                }
                Action::SetFormation(spec) => {
                    self.engine.set(spec);
                    self.join_hovering();
                    None
                }
                Action::LeaderMotion(m) => self.leader_motion(m).err(),
                Action::ClearFormation => {
                    self.clear_formation();
                    None
                }
                Action::Observe {
                    target,
                    vehicles,
                    stations,
                    standoff_m,
                } => {
                    self.observe(target, vehicles, stations, standoff_m);
                    None
                }
                Action::StopObserving { target } => {
                    self.stop_observing(&target);
                    None
                }
            };
            if let Some(why) = refused {
                for held in self.run.stop_on(format!("formation: {why}")) {
                    if let Action::Command { vehicle, command } = held {
                        self.command(&vehicle, &command);
                    }
                }
                return;
            }
        }
    }

    /// Vehicle `id` obeys `command` (a refusal is noted).
    pub(super) fn command(&mut self, id: &str, command: &Command) {
        let t = self.run.status().elapsed_s;
        let Some(a) = self.aircraft.iter_mut().find(|a| a.id == id) else {
            self.refusals.push(format!("{t:.1} s: no vehicle {id}"));
            return;
        };
        if let Err(e) = a.command(command) {
            self.refusals.push(format!("{t:.1} s: {id}: {e}"));
        }
    }

    fn join_hovering(&mut self) {
        let hovering: Vec<String> = self
            .aircraft
            .iter()
            .filter(|a| a.state == VehicleState::Hovering && !self.observes(&a.id))
            .map(|a| a.id.clone())
            .collect();
        for id in hovering {
            self.command(&id, &Command::JoinFormation);
        }
    }

    /// Points without an altitude keep the formation's; then the engine's motion.
    fn leader_motion(&mut self, mut motion: LeaderMotion) -> Result<(), String> {
        if let Some(down) = self.engine.status(&[]).reference.map(|r| r.position.down_m) {
            let fill = |p: &mut Ned| {
                if p.down_m.is_nan() {
                    p.down_m = down;
                }
            };
            match &mut motion {
                LeaderMotion::GoTo { target, .. } => fill(target),
                LeaderMotion::Waypoints { points, .. } => points.iter_mut().for_each(fill),
                LeaderMotion::Orbit { centre, .. } => fill(centre),
                _ => {}
            }
        }
        self.engine.set_motion(motion)
    }

    fn clear_formation(&mut self) {
        self.engine.deactivate();
        let members: Vec<String> = self
            .aircraft
            .iter()
            .filter(|a| a.state == VehicleState::InFormation)
            .map(|a| a.id.clone())
            .collect();
        for id in members {
            self.command(&id, &Command::LeaveFormation);
        }
    }

    /// True while vehicle `id` observes a track.
    pub(super) fn observes(&self, id: &str) -> bool {
        self.observing
            .values()
            .any(|o| o.vehicles.iter().any(|v| v == id))
    }

    fn observe(
        &mut self,
        target: String,
        vehicles: Vec<String>,
        stations: bool,
        standoff_m: Option<f64>,
    ) {
        let o = Observation {
            vehicles,
            stations,
            standoff_m: standoff_m.unwrap_or(DEFAULT_STANDOFF_M),
            planned: Vec::new(),
            last_plan_s: f64::NEG_INFINITY,
        };
        self.observing.insert(target, o);
        self.observe_tick();
    }

    fn stop_observing(&mut self, target: &str) {
        if let Some(o) = self.observing.remove(target)
            && o.stations
        {
            for v in o.vehicles {
                self.command(&v, &Command::Hold);
            }
        }
    }

    /// Plans the stations of every observation from stations again where due, and sends
    /// the observers that are not on theirs.
    pub(super) fn observe_tick(&mut self) {
        let now_s = self.run.status().elapsed_s;
        let tracks = self.tracks.seen(now_s);
        let targets: Vec<String> = self.observing.keys().cloned().collect();
        for target in targets {
            let o = self.observing[&target].clone();
            if !o.stations || now_s - o.last_plan_s < REPLAN_EVERY_S {
                continue;
            }
            let Some(track) = tracks.iter().find(|t| t.id == target) else {
                continue;
            };
            let planned = self.plan_stations(&o, track.position);
            let o = self.observing.get_mut(&target).expect("listed");
            o.last_plan_s = now_s;
            match planned {
                Some(p) => o.planned = p,
                None if o.planned.is_empty() => o.stations = false,
                None => {}
            }
            let sends: Vec<(String, Ned)> = o.planned.clone();
            for (v, station) in sends {
                let away = self
                    .aircraft
                    .iter()
                    .find(|a| a.id == v)
                    .and_then(|a| a.measured)
                    .is_none_or(|m| (m.0 - station).norm() > RESEND_M);
                if away {
                    self.command(&v, &Command::GoTo(GoTo::from(station)));
                }
            }
        }
    }

    /// The stations of `o`'s observers around a target at `at`, if any meet the limits.
    fn plan_stations(&self, o: &Observation, at: Ned) -> Option<Vec<(String, Ned)>> {
        let observers: Vec<Observer> = o
            .vehicles
            .iter()
            .filter_map(|v| {
                let a = self.aircraft.iter().find(|a| a.id == *v)?;
                Some(Observer {
                    id: v.clone(),
                    position: a.measured?.0,
                })
            })
            .collect();
        let others: Vec<Ned> = self
            .aircraft
            .iter()
            .filter(|a| !o.vehicles.contains(&a.id) && a.state.is_airborne())
            .filter_map(|a| a.measured.map(|m| m.0))
            .collect();
        let limits = StationLimits {
            standoff_m: o.standoff_m,
            max_range_m: MAX_RANGE_M,
            min_separation_m: std::f64::consts::SQRT_2 * self.swarm.setpoint_separation_m(),
            fov_deg: CAMERA_FOV_DEG,
            bearing_sigma_rad: skein_tracking::TrackerConfig::default()
                .bearing_sigma_deg
                .to_radians(),
            fence: self.swarm.fence.clone(),
            fence_margin_m: FENCE_MARGIN_M,
        };
        stations::plan(&observers, &[at], &[at], &others, &limits)
            .ok()
            .map(|p| p.stations)
    }
}
