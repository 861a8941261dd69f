//! Formation flight rehearsed in virtual time: the real [`FormationEngine`] and one real
//! [`SetpointShaper`] per vehicle, stepped as fast as the CPU allows and fully
//! deterministic.
//!
//! What runs is the code that flies: slot targets at the formation rate, extrapolated by
//! each vehicle between formation ticks as the Vehicle actor does, shaped against every
//! other vehicle's position and setpoint (planned between members, as `skein_swarm`'s neighbour view
//! marks them), and for a simulated PX4 the same slot correction (acceleration
//! feed-forward with a learnt drag term). What flies is chosen by
//! [`RehearsalConfig::airframe`] ([`airframe`]): skein's PX4-faithful simulated
//! multicopter (`skein bench formation`), or a kinder point mass for the seeded sweeps of
//! formation changes. Separation is measured on where the aircraft really are.

mod airframe;

pub use airframe::AirframeKind;

use airframe::Airframe;
use skein_model::geo::Ned;
use skein_model::safety::{Geofence, MotionLimits, Obstacle, SetpointShaper};
use skein_swarm::formation::{
    FormationEngine, FormationSpec, FormationStatus, Hazard, HazardConfig, LeaderMotion, Member,
};
use skein_swarm::vehicle::slot_correction::{SlotCorrection, SlotCorrectionGains};
use std::collections::BTreeMap;
use std::time::Duration;

/// How a rehearsal is set up.
#[derive(Debug, Clone)]
pub struct RehearsalConfig {
    /// Number of vehicles (ids `uav-1` …).
    pub vehicles: usize,
    /// Integration step, seconds (the control loop's period).
    pub dt_s: f64,
    /// Formation loop period, in integration steps.
    pub formation_every: usize,
    /// Every vehicle's limits.
    pub limits: MotionLimits,
    /// Geofence around the origin.
    pub fence: Geofence,
    /// Minimum separation to keep, metres (the setpoint separation adds `margin_m`).
    pub min_separation_m: f64,
    /// Tracking margin on top of the separation, metres.
    pub margin_m: f64,
    /// Vehicles start hovering on a grid this far apart, metres.
    pub spawn_spacing_m: f64,
    /// Altitude they start at, metres above the origin.
    pub spawn_altitude_m: f64,
    /// What flies (default: the point mass).
    pub airframe: AirframeKind,
}

impl RehearsalConfig {
    /// `vehicles` with skein's defaults: 50 Hz control, 10 Hz formation, the default
    /// limits and fence, 3 m separation with a 0.5 m margin, spawned 5.25 m apart at 10 m.
    pub fn new(vehicles: usize) -> Self {
        RehearsalConfig {
            vehicles,
            dt_s: 0.02,
            formation_every: 5,
            limits: MotionLimits::default(),
            fence: Geofence::default(),
            min_separation_m: 3.0,
            margin_m: 0.5,
            spawn_spacing_m: 5.25,
            spawn_altitude_m: 10.0,
            airframe: AirframeKind::PointMass,
        }
    }
}

/// What a rehearsal has seen so far.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RehearsalStats {
    /// Smallest distance between two vehicles at any step, metres.
    pub min_separation_m: f64,
    /// Steps at which some pair was closer than the minimum separation.
    pub separation_violations: u64,
    /// Vehicle-steps outside the geofence (radius, ceiling, or floor).
    pub fence_violations: u64,
    /// Setpoints the geofence clamped.
    pub fence_clamps: u64,
    /// Steps flown.
    pub steps: u64,
    /// Longest time the formation's pacing held a member, seconds (the engine plans the
    /// change again after `HazardConfig::replan_after_s`).
    pub max_stall_s: f64,
    /// The pair (indices, 0 = `uav-1`) at the smallest distance.
    pub min_pair: (usize, usize),
    /// Formation changes planned again because pacing held a member too long.
    pub replans: u64,
}

#[derive(Debug)]
struct Aircraft {
    id: String,
    airframe: Airframe,
    /// Where skein measures it (at the start of the step), rehearsal frame.
    position: Ned,
    /// Its measured velocity, NED m/s.
    velocity: Ned,
    shaper: SetpointShaper,
    slot_correction: SlotCorrection,
    /// Slot target and velocity from the last formation tick (its age in `slot_age_s`).
    slot: Option<(Ned, Ned)>,
    slot_age_s: f64,
    setpoint: (Ned, Ned),
    /// Lost at this virtual time, seconds: it holds where it was (PX4's offboard-loss
    /// hold) and the formation plans around where it was last seen.
    lost_at_s: Option<f64>,
    /// Where it was when it was lost.
    last_seen: Ned,
}

/// A formation flown in virtual time (see the module docs).
#[derive(Debug)]
pub struct Rehearsal {
    config: RehearsalConfig,
    engine: FormationEngine,
    aircraft: Vec<Aircraft>,
    step: u64,
    stats: RehearsalStats,
    obstacles: Vec<Obstacle>,
}

impl Rehearsal {
    /// Vehicles hovering on a square grid around the origin.
    pub fn new(config: RehearsalConfig) -> Self {
        let cols = (config.vehicles as f64).sqrt().ceil().max(1.0) as usize;
        let aircraft = (0..config.vehicles)
            .map(|i| {
                let p = Ned::new(
                    (i / cols) as f64 * config.spawn_spacing_m,
                    (i % cols) as f64 * config.spawn_spacing_m,
                    -config.spawn_altitude_m,
                );
                let mut shaper = SetpointShaper::new(
                    p,
                    config.limits,
                    config.fence.clone(),
                    config.min_separation_m + config.margin_m,
                )
                .with_planned_separation(config.min_separation_m + 0.5 * config.margin_m);
                shaper.enforce_floor(true);
                Aircraft {
                    id: format!("uav-{}", i + 1),
                    airframe: Airframe::new(config.airframe, p, i as u64 + 1),
                    position: p,
                    velocity: Ned::ZERO,
                    shaper,
                    slot_correction: SlotCorrection::default(),
                    slot: None,
                    slot_age_s: 0.0,
                    setpoint: (p, Ned::ZERO),
                    lost_at_s: None,
                    last_seen: p,
                }
            })
            .collect();
        let separation_m = config.min_separation_m + config.margin_m;
        Rehearsal {
            config,
            engine: FormationEngine::new(separation_m),
            aircraft,
            step: 0,
            stats: RehearsalStats {
                min_separation_m: f64::INFINITY,
                ..RehearsalStats::default()
            },
            obstacles: Vec::new(),
        }
    }

    /// Flies `spec` from the next formation tick on.
    pub fn set_formation(&mut self, spec: FormationSpec) {
        self.engine.set(spec);
    }

    /// Loses vehicle `id` now, as a link that goes silent: it stops getting slots and
    /// holds where it is (PX4's offboard-loss action `Hold`), and from the next formation
    /// tick on it is a hazard at the place it was lost, its radius growing as
    /// [`HazardConfig::default`] says. Unknown ids are ignored.
    pub fn lose(&mut self, id: &str) {
        let t = self.time_s();
        if let Some(a) = self
            .aircraft
            .iter_mut()
            .find(|a| a.id == id && a.lost_at_s.is_none())
        {
            a.lost_at_s = Some(t);
            a.last_seen = a.position;
            a.slot = None;
            a.setpoint = (a.position, Ned::ZERO);
        }
    }

    /// Gives the reference point a motion.
    ///
    /// # Errors
    /// When no formation is flown yet.
    pub fn set_motion(&mut self, motion: LeaderMotion) -> Result<(), String> {
        self.engine.set_motion(motion)
    }

    /// Virtual time flown, seconds.
    pub fn time_s(&self) -> f64 {
        self.step as f64 * self.config.dt_s
    }

    /// What has been seen so far.
    pub fn stats(&self) -> RehearsalStats {
        self.stats
    }

    /// The formation status of the last tick (positions of all vehicles as airborne).
    pub fn status(&self) -> FormationStatus {
        let positions: Vec<Ned> = self.aircraft.iter().map(|a| a.airframe.truth()).collect();
        self.engine.status(&positions)
    }

    /// Sends the virtual leader to `target` at `speed_m_s` and flies until it stops there
    /// (at most 120 s); returns the formation's RMS slot error at every formation tick
    /// while the reference cruised at full speed, past the first quarter of them (the
    /// formation catching up with the acceleration), metres.
    ///
    /// # Errors
    /// When no formation is flown.
    pub fn cruise_to(&mut self, target: Ned, speed_m_s: f64) -> Result<Vec<f64>, String> {
        self.set_motion(LeaderMotion::GoTo { target, speed_m_s })?;
        let mut samples = Vec::new();
        self.run_until(120.0, |r| {
            let s = r.status();
            let Some(reference) = s.reference else {
                return true;
            };
            if reference.velocity.horizontal_norm() > speed_m_s - 0.01 {
                samples.push(s.rms_error_m.unwrap_or(f64::NAN));
            }
            (reference.position - target).horizontal_norm() < 0.5 && reference.velocity.norm() < 0.1
        });
        Ok(samples.split_off(samples.len() / 4))
    }

    /// Orbits the virtual leader around `centre` (radius `radius_m`, clockwise) at
    /// `speed_m_s` for `seconds` once on the circle, then holds; returns the RMS slot
    /// errors while it orbited at full speed, past the first quarter, metres.
    ///
    /// # Errors
    /// When no formation is flown.
    pub fn orbit(
        &mut self,
        centre: Ned,
        radius_m: f64,
        speed_m_s: f64,
        seconds: f64,
    ) -> Result<Vec<f64>, String> {
        self.set_motion(LeaderMotion::Orbit {
            centre,
            radius_m,
            speed_m_s,
            clockwise: true,
        })?;
        let mut samples = Vec::new();
        let mut orbiting_s = 0.0;
        let tick_s = self.config.dt_s * self.config.formation_every as f64;
        self.run_until(seconds + 60.0, |r| {
            let s = r.status();
            if s.reference
                .is_some_and(|p| p.velocity.horizontal_norm() > speed_m_s - 0.01)
            {
                samples.push(s.rms_error_m.unwrap_or(f64::NAN));
                orbiting_s += tick_s;
            }
            orbiting_s >= seconds
        });
        self.set_motion(LeaderMotion::Hold)?;
        Ok(samples.split_off(samples.len() / 4))
    }

    /// Steps until `done` holds (checked after every formation tick) or `max_s` of
    /// virtual time passed; returns whether `done` held.
    pub fn run_until(&mut self, max_s: f64, mut done: impl FnMut(&Rehearsal) -> bool) -> bool {
        let end = self.time_s() + max_s;
        while self.time_s() < end {
            self.advance();
            if self.step.is_multiple_of(self.config.formation_every as u64) && done(self) {
                return true;
            }
        }
        false
    }

    /// One integration step.
    pub fn advance(&mut self) {
        let dt = self.config.dt_s;
        for a in &mut self.aircraft {
            (a.position, a.velocity) = a.airframe.measured();
        }
        if self.step.is_multiple_of(self.config.formation_every as u64) {
            let now = self.time_s();
            let hazards: Vec<Hazard> = self
                .aircraft
                .iter()
                .filter_map(|a| {
                    let unseen_s = now - a.lost_at_s?;
                    Some(Hazard {
                        id: a.id.clone(),
                        position: a.last_seen,
                        radius_m: HazardConfig::default().radius_m(unseen_s),
                        unseen_s,
                        reason: "Lost".into(),
                    })
                })
                .collect();
            self.engine.set_hazards(hazards);
            let members: BTreeMap<String, Member> = self
                .aircraft
                .iter()
                .filter(|a| a.lost_at_s.is_none())
                .map(|a| {
                    let heading = a.velocity.east_m.atan2(a.velocity.north_m);
                    (
                        a.id.clone(),
                        Member {
                            position: a.position,
                            velocity: a.velocity,
                            heading_rad: heading,
                            silence: Duration::ZERO,
                            target: Some(a.setpoint.0),
                            ride_through: skein_swarm::formation::LEADER_SILENCE,
                        },
                    )
                })
                .collect();
            let period = dt * self.config.formation_every as f64;
            let slots = self.engine.tick(&members, period, &self.config.fence);
            self.stats.max_stall_s = self.stats.max_stall_s.max(self.engine.stalled_s());
            self.stats.replans += self.engine.take_replans().len() as u64;
            for a in &mut self.aircraft {
                if let Some(s) = slots.get(&a.id) {
                    a.slot = Some((s.position, s.velocity));
                    a.slot_age_s = 0.0;
                }
            }
        }
        // Shape every vehicle's setpoint against the others (as of the previous step).
        let n = self.aircraft.len();
        for i in 0..n {
            let Some((slot_p, slot_v)) = self.aircraft[i].slot else {
                continue;
            };
            self.obstacles.clear();
            for (j, o) in self.aircraft.iter().enumerate() {
                if j == i {
                    continue;
                }
                let planned = o.slot.is_some();
                if o.lost_at_s.is_some() {
                    // Nobody steers it: it does not give way (no reciprocity).
                    self.obstacles.push(Obstacle {
                        position: o.position,
                        velocity: o.velocity,
                        reciprocal: false,
                        planned: false,
                    });
                    continue;
                }
                for (position, velocity) in [(o.position, o.velocity), o.setpoint] {
                    self.obstacles.push(Obstacle {
                        position,
                        velocity,
                        reciprocal: true,
                        planned,
                    });
                }
            }
            let a = &mut self.aircraft[i];
            // The Vehicle actor extrapolates the slot between formation ticks.
            let target = slot_p + slot_v * a.slot_age_s;
            a.slot_age_s += dt;
            let sp = a.shaper.step(target, slot_v, 0.0, dt, &self.obstacles);
            if sp.fence.is_some() {
                self.stats.fence_clamps += 1;
            }
            a.setpoint = (sp.position, sp.velocity);
        }
        // Fly: a member flying its slot on a simulated PX4 adds the slot correction,
        // as the Vehicle actor does; a lost one gets nothing.
        let gains = SlotCorrectionGains::default();
        for a in &mut self.aircraft {
            let (sp, ff) = a.setpoint;
            let setpoint = if a.lost_at_s.is_some() {
                None
            } else if a.slot.is_some() && a.airframe.is_px4() {
                let c = a.slot_correction.update(&gains, sp, ff, a.position, dt);
                Some((sp + c.offset, ff, c.acceleration))
            } else {
                Some((sp, ff, Ned::ZERO))
            };
            a.airframe.fly(setpoint, dt);
            if !self.config.fence.contains(a.airframe.truth()) {
                self.stats.fence_violations += 1;
            }
        }
        let mut min = f64::INFINITY;
        let mut pair = (0, 0);
        let truth: Vec<Ned> = self.aircraft.iter().map(|a| a.airframe.truth()).collect();
        for (i, a) in truth.iter().enumerate() {
            for (j, b) in truth.iter().enumerate().skip(i + 1) {
                let d = (*a - *b).norm();
                if d < min {
                    min = d;
                    pair = (i, j);
                }
            }
        }
        if min < self.stats.min_separation_m {
            self.stats.min_separation_m = min;
            self.stats.min_pair = pair;
        }
        if min < self.config.min_separation_m {
            self.stats.separation_violations += 1;
        }
        self.step += 1;
        self.stats.steps = self.step;
    }
}
