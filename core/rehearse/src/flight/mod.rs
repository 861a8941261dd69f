//! The rehearsal's loop, on one virtual clock: every control period each aircraft's
//! control step (against every other's position and setpoint) and its simulator; at the
//! formation rate the real [`FormationEngine`] with its slots to the members; at the
//! coordinator's mission tick ([`MISSION_TICK`]) the real [`MissionRun`], whose actions
//! are carried out as the coordinator carries them out ([`actions`]); the intruders of
//! the scenario seen as tracks ([`crate::tracks`]); the figures noted as it flies
//! ([`crate::record`]).
//!
//! - [`actions`]: the mission's actions: commands, formation, observation.

mod actions;

use crate::aircraft::Aircraft;
use crate::record::Record;
use crate::tracks::Tracks;
use skein_mission::plan::StepKind;
use skein_mission::swarm::SwarmSetup;
use skein_mission::{MissionRun, RunState, Tick, VehicleView};
use skein_model::fsm::VehicleState;
use skein_model::geo::Ned;
use skein_sim::intruders::Intruders;
use skein_swarm::coordinator::missions::MISSION_TICK;
use skein_swarm::formation::{FormationEngine, LEADER_SILENCE, Member};
use std::collections::BTreeMap;
use std::time::Duration;

/// Longest wait for every simulated vehicle to boot (home, position), virtual seconds.
const BOOT_S: f64 = 60.0;
/// Longest wait after the mission ended for every vehicle to be down, virtual seconds.
const SETTLE_S: f64 = 120.0;
/// Coverage is sampled every this many control steps.
const COVERAGE_EVERY: u64 = 10;

/// Where one aircraft is for the others' separation: measured (position, velocity),
/// steered (setpoint, velocity), and whether it flies a formation slot.
type Place = (Option<(Ned, Ned)>, Option<(Ned, Ned)>, bool);

/// The intruders of a rehearsal and when their paths start (mission seconds).
pub(crate) struct Intrusion {
    pub intruders: Intruders,
    pub start_s: f64,
}

/// A rehearsal under way (see the module docs).
pub(crate) struct Flight {
    pub aircraft: Vec<Aircraft>,
    engine: FormationEngine,
    pub run: MissionRun,
    swarm: SwarmSetup,
    dt_s: f64,
    formation_every: u64,
    mission_every: u64,
    step: u64,
    intrusion: Option<Intrusion>,
    tracks: Tracks,
    observing: BTreeMap<String, actions::Observation>,
    pub record: Record,
    /// Commands a vehicle refused, in words.
    pub refusals: Vec<String>,
    /// Vehicle states at the last step (to see one start hovering).
    states: BTreeMap<String, VehicleState>,
}

impl Flight {
    /// `run` (started) to be flown by the vehicles of `swarm`; `seed` seeds their
    /// simulators.
    pub fn new(
        run: MissionRun,
        swarm: &SwarmSetup,
        intrusion: Option<Intrusion>,
        seed: u64,
    ) -> Self {
        let aircraft = swarm
            .vehicles
            .iter()
            .enumerate()
            .map(|(i, v)| Aircraft::new(v, swarm, seed.wrapping_mul(1000) + i as u64 + 1))
            .collect();
        let dt_s = 1.0 / swarm.control_rate_hz.max(1.0);
        let every = |period_s: f64| ((period_s / dt_s).round() as u64).max(1);
        let mut record = Record::default();
        for (i, s) in run.plan().steps.iter().enumerate() {
            if let StepKind::Survey(survey) = &s.kind {
                record
                    .coverage
                    .insert(i, crate::coverage::Coverage::new(survey));
            }
        }
        Flight {
            aircraft,
            engine: FormationEngine::new(swarm.setpoint_separation_m()),
            run,
            swarm: swarm.clone(),
            dt_s,
            formation_every: every(1.0 / swarm.formation_rate_hz.max(1.0)),
            mission_every: every(MISSION_TICK.as_secs_f64()),
            step: 0,
            intrusion,
            tracks: Tracks::default(),
            observing: BTreeMap::new(),
            record,
            refusals: Vec::new(),
            states: BTreeMap::new(),
        }
    }

    /// The geofence flown in.
    pub fn fence(&self) -> &skein_model::geofence::Geofence {
        &self.swarm.fence
    }

    /// Virtual seconds since the vehicles booted.
    pub fn time_s(&self) -> f64 {
        self.step as f64 * self.dt_s
    }

    /// Boots the vehicles; false when one did not get a home and a position in time.
    pub fn boot(&mut self) -> bool {
        while self.time_s() < BOOT_S {
            self.advance_aircraft();
            if self.aircraft.iter().all(Aircraft::ready) {
                return true;
            }
        }
        false
    }

    /// Flies the mission until it is done or aborted and everyone is down, a refusal
    /// stopped it, or `max_s` of mission time passed; `progress` follows the mission
    /// time flown.
    pub fn fly(&mut self, max_s: f64, progress: &crate::Progress) {
        let mut ended_at: Option<f64> = None;
        loop {
            self.tick();
            let status = self.run.status();
            progress.set_mission_s(status.elapsed_s);
            match status.state {
                RunState::Done | RunState::Aborted => {
                    let t = *ended_at.get_or_insert(self.time_s());
                    let down = self.aircraft.iter().all(|a| !a.state.is_airborne());
                    if down || self.time_s() - t > SETTLE_S {
                        return;
                    }
                }
                RunState::Paused | RunState::Ready => return,
                RunState::Running if status.elapsed_s > max_s => return,
                RunState::Running => {}
            }
        }
    }

    /// One control period (see the module docs).
    fn tick(&mut self) {
        let now_s = self.run.status().elapsed_s;
        if self.step.is_multiple_of(self.formation_every) {
            self.formation_tick();
        }
        if self.step.is_multiple_of(self.mission_every) {
            let intruders = self.intruders_now();
            let eyes: Vec<Ned> = self
                .aircraft
                .iter()
                .filter(|a| a.observer && a.state.is_airborne())
                .map(Aircraft::truth)
                .collect();
            self.tracks.update(now_s, &intruders, &eyes);
            self.mission_tick();
            self.observe_tick();
            if self.step.is_multiple_of(self.mission_every * 2) {
                self.record.trail(&self.aircraft, &intruders);
            }
        }
        self.advance_aircraft();
        let now_s = self.run.status().elapsed_s;
        self.record.note(&self.aircraft, &self.swarm.fence, now_s);
        if self.step.is_multiple_of(COVERAGE_EVERY) {
            self.sample_coverage();
        }
        self.join_new_hoverers();
    }

    /// Every aircraft's control step, then its simulator on to the next period.
    fn advance_aircraft(&mut self) {
        let places: Vec<Place> = self
            .aircraft
            .iter()
            .map(|a| (a.measured, a.steered, a.planned))
            .collect();
        let mut others = Vec::with_capacity(2 * places.len());
        for (i, a) in self.aircraft.iter_mut().enumerate() {
            others.clear();
            for (j, (measured, steered, planned)) in places.iter().enumerate() {
                if i != j {
                    actions::obstacles(*measured, *steered, *planned, &mut others);
                }
            }
            a.control(self.dt_s, &others);
        }
        self.step += 1;
        let t = self.time_s();
        for a in &mut self.aircraft {
            a.advance(t);
        }
    }

    /// The formation engine's tick: members flying it, their slots sent.
    fn formation_tick(&mut self) {
        if !self.engine.is_active() {
            return;
        }
        let members: BTreeMap<String, Member> = self
            .aircraft
            .iter()
            .filter(|a| a.state == VehicleState::InFormation)
            .filter_map(|a| {
                let (position, velocity) = a.measured?;
                Some((
                    a.id.clone(),
                    Member {
                        position,
                        velocity,
                        heading_rad: a.heading_rad(),
                        silence: Duration::ZERO,
                        target: a.steered.map(|s| s.0),
                        ride_through: LEADER_SILENCE,
                    },
                ))
            })
            .collect();
        let period = self.dt_s * self.formation_every as f64;
        let slots = self.engine.tick(&members, period, &self.swarm.fence);
        for a in &mut self.aircraft {
            if let Some(s) = slots.get(&a.id) {
                a.on_slot(s.position, s.velocity, s.yaw_rad);
            }
        }
    }

    /// The mission run's tick on the vehicles as they are.
    fn mission_tick(&mut self) {
        let vehicles = self
            .aircraft
            .iter()
            .map(|a| {
                let view = VehicleView {
                    id: a.id.clone(),
                    state: a.state,
                    position: a.measured.map(|m| m.0),
                    velocity: a.measured.map(|m| m.1),
                    relative_alt_m: a.relative_alt_m(),
                    battery_percent: a.battery_percent(),
                    observer: a.observer,
                };
                (a.id.clone(), view)
            })
            .collect();
        let tick = Tick {
            now_s: self.time_s(),
            vehicles,
            reference: self.engine.status(&[]).reference.map(|r| r.position),
            tracks: self.tracks.seen(self.run.status().elapsed_s),
        };
        let actions = self.run.tick(&tick);
        self.apply(actions);
    }

    /// The intruders' truth now (swarm frame), none before their start.
    fn intruders_now(&self) -> Vec<(String, Ned)> {
        let Some(i) = &self.intrusion else {
            return Vec::new();
        };
        let t = self.run.status().elapsed_s - i.start_s;
        if t < 0.0 {
            return Vec::new();
        }
        i.intruders
            .truth_at(t)
            .into_iter()
            .map(|x| (x.id, x.home_ned_m))
            .collect()
    }

    /// The survey flown now sees what its vehicles fly over.
    fn sample_coverage(&mut self) {
        let status = self.run.status();
        let i = status.step;
        if status.state != RunState::Running {
            return;
        }
        let Some(c) = self.record.coverage.get_mut(&i) else {
            return;
        };
        for id in &status.steps[i].vehicles {
            if let Some(a) = self.aircraft.iter().find(|a| a.id == *id) {
                c.sample(id, a.truth());
            }
        }
    }

    /// A vehicle that starts hovering joins an active formation, unless it observes (the
    /// coordinator's rule).
    fn join_new_hoverers(&mut self) {
        for i in 0..self.aircraft.len() {
            let (id, state) = (self.aircraft[i].id.clone(), self.aircraft[i].state);
            let before = self.states.insert(id.clone(), state);
            if state == VehicleState::Hovering
                && before != Some(VehicleState::Hovering)
                && self.engine.is_active()
                && !self.observes(&id)
            {
                self.command(&id, &skein_model::command::Command::JoinFormation);
            }
        }
    }
}
