//! The control loop: every tick ([`crate::SwarmConfig::control_rate_hz`]) the current
//! target is shaped by the [`SetpointShaper`] (speed and acceleration limits, geofence,
//! separation from the neighbours), converted from the swarm frame to the vehicle's own
//! local NED frame through geodetic coordinates, and handed to the setpoint stream.
//! Formation slot targets arrive stamped and move on by their age.
//!
//! The step runs on the process's control clock, one direct call per vehicle per period
//! (see [`super::VehicleCore`]), with what the step keeps between periods in its
//! [`ControlClock`].

use super::VehicleCore;
use super::shared::Memory;
use super::slot_correction::{OnSlot, local_setpoint};
use crate::context::LiveFence;
use crate::events::SwarmEvent;
use crate::load::ShedWork;
use crate::protocol::{SlotTarget, age_of, extrapolate_target};
use skein_link::LocalSetpoint;
use skein_model::fsm::{Event, VehicleState};
use skein_model::geo::{Ned, NedFrame};
use skein_model::px4::Px4Mode;
use skein_model::safety::{SetpointShaper, ShapedSetpoint};
use std::sync::atomic::Ordering;
use std::time::Instant;

/// Distance to a takeoff altitude or go-to point that counts as arrived, metres.
pub const ARRIVAL_TOLERANCE_M: f64 = 0.5;

/// What the streamed setpoint is aiming at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Target {
    /// Hold a point.
    Hold(Ned),
    /// Track a moving point (formation slot), known at `at`: between the formation's
    /// updates it moves on at its velocity.
    Track {
        position: Ned,
        velocity: Ned,
        at: Instant,
    },
}

impl Target {
    pub(super) fn position(&self) -> Ned {
        match self {
            Target::Hold(p) => *p,
            Target::Track { position, .. } => *position,
        }
    }

    /// Position and velocity feed-forward now (a slot moved on by its age).
    fn now(&self, now: Instant) -> (Ned, Ned) {
        match *self {
            Target::Hold(p) => (p, Ned::ZERO),
            Target::Track {
                position,
                velocity,
                at,
            } => extrapolate_target(position, velocity, now.saturating_duration_since(at)),
        }
    }
}

/// What one vehicle's control step keeps from one period to the next.
#[derive(Debug)]
pub(super) struct ControlClock {
    last_tick: Instant,
    ticks: u64,
}

impl ControlClock {
    pub(super) fn new() -> Self {
        ControlClock {
            last_tick: Instant::now(),
            ticks: 0,
        }
    }

    /// Counts a step at `now`: the time since the last one (s, at most 0.2) and the
    /// steps so far.
    fn advance(&mut self, now: Instant) -> (f64, u64) {
        let dt = now
            .duration_since(self.last_tick)
            .as_secs_f64()
            .clamp(0.0, 0.2);
        self.last_tick = now;
        self.ticks += 1;
        (dt, self.ticks)
    }
}

impl VehicleCore {
    pub(super) fn on_slot(&self, slot: Option<SlotTarget>) {
        let mut mem = self.shared.memory();
        if mem.state != VehicleState::InFormation {
            return;
        }
        mem.slot = slot;
        if let Some(s) = slot {
            let current = self
                .swarm_frame()
                .and_then(|f| self.shared.position(&f))
                .unwrap_or(s.position);
            mem.yaw_rad = s.yaw_rad;
            self.set_target(
                &mut mem,
                Target::Track {
                    position: s.position,
                    velocity: s.velocity,
                    at: Instant::now()
                        .checked_sub(age_of(s.stamp_us))
                        .unwrap_or_else(Instant::now),
                },
                current,
            );
        }
    }

    /// One control step (see the module docs).
    pub(super) fn tick(&self, clock: &mut ControlClock) {
        self.injected_control_panic();
        let now = Instant::now();
        let (dt, ticks) = clock.advance(now);
        let Some(frame) = self.swarm_frame() else {
            self.shared.publish(None, None, &self.supervision);
            self.shared.publish_report(None);
            return;
        };
        let fix = self.shared.fix(&frame, now);
        let mut mem = self.shared.memory();
        let state = mem.state;
        // Where this vehicle is, for the others' separation (the setpoint is added below
        // when skein steers it; a Lost vehicle stays where it was last seen).
        let measured = fix.measured();
        let step = Step {
            frame: &frame,
            local: fix.local_frame,
            current: fix.position,
            now,
            dt,
            state,
            // A member flying its slot (the leader vehicle included) is on the formation's
            // transition plan.
            planned: state == VehicleState::InFormation && mem.slot.is_some(),
        };
        // Where skein sends it, when it steers it.
        let steered = self.stream_step(&mut mem, &step);
        let slot = mem.slot;
        let left = (mem.state, mem.target);
        drop(mem);
        self.position.set(measured, steered, step.planned);
        self.shared
            .publish_measured(measured, fix.heading_rad, left, now);
        let publish_every = (self.config().control_rate_hz / 10.0).round().max(1.0) as u64;
        if ticks.is_multiple_of(publish_every) {
            self.watch_fence(measured.map(|(p, _)| p), state);
            // The API's snapshot is optional work: a fifth of its rate while short of CPU.
            if self
                .supervision
                .load
                .keep(ShedWork::Snapshots, ticks / publish_every)
            {
                self.shared.publish(Some(frame), slot, &self.supervision);
            }
        }
    }

    /// Panics when a fault was injected into the control step (`POST /api/v1/faults`).
    fn injected_control_panic(&self) {
        // A load first: the step does not write the flag's line unless a fault is set.
        if self.control_fault.load(Ordering::Relaxed)
            && self.control_fault.swap(false, Ordering::AcqRel)
        {
            panic!("injected panic in the control step of {}", self.shared.id);
        }
    }

    /// What the setpoint stream carries in `step.state`; returns where skein steers the
    /// vehicle (swarm-frame position and velocity), when it does.
    fn stream_step(&self, mem: &mut Memory, step: &Step) -> Option<(Ned, Ned)> {
        let stream = self.shared.link.stream();
        match step.state {
            VehicleState::TakingOff
            | VehicleState::Hovering
            | VehicleState::InFormation
            | VehicleState::GoTo => {
                if let (Some(target), Some(local), Some(cur)) =
                    (mem.target, step.local, step.current)
                {
                    return Some(self.steer(mem, step, target, &local, cur));
                }
            }
            VehicleState::Landing | VehicleState::ReturnToLaunch | VehicleState::Failsafe => {
                // PX4 flies; keep a hold at the current position in the stream so that
                // a switch back to OFFBOARD holds where the vehicle is.
                if let (Some(local), Some(cur)) = (step.local, step.current) {
                    if let Some(s) = mem.shaper.as_mut() {
                        s.reset(cur);
                    }
                    if stream.current().is_some() {
                        stream.set(Some(LocalSetpoint::position(
                            self.shared
                                .transforms(step.frame, &local)
                                .to_local
                                .apply(cur),
                            mem.yaw_rad,
                        )));
                    }
                }
            }
            VehicleState::Lost => {} // keep streaming the last setpoint
            VehicleState::Landed | VehicleState::Armed | VehicleState::Disconnected => {
                if stream.current().is_some() {
                    stream.set(None);
                }
                mem.shaper = None;
                mem.target = None;
            }
        }
        None
    }

    /// Steers a flying vehicle at `cur` towards `target`: the shaped setpoint, in its
    /// local frame `local`, into the stream, then the running procedure's progress.
    /// Returns the shaped swarm-frame position and velocity.
    fn steer(
        &self,
        mem: &mut Memory,
        step: &Step,
        target: Target,
        local: &NedFrame,
        cur: Ned,
    ) -> (Ned, Ned) {
        let to_local = self.shared.transforms(step.frame, local).to_local;
        let (tp, tv) = target.now(step.now);
        let fence = self.setpoint_fence(mem);
        let sp = self.shape(mem, step, &fence, cur, (tp, tv));
        // Flying a slot: cancel PX4's tracking lag (see `slot_correction`).
        let slot = step.planned.then_some(OnSlot {
            correction: &mut mem.slot_correction,
            measured: cur,
            dt_s: step.dt,
        });
        let setpoint = local_setpoint(&sp, slot, &fence.fence, &to_local);
        self.shared.link.stream().set(Some(setpoint));
        self.procedure_progress(mem, step.state, cur, tp);
        (sp.position, sp.velocity)
    }

    /// The target (position, velocity) shaped by the vehicle's limits, the `fence` and
    /// its neighbours (the shaper made on the first step); a new fence violation is an
    /// event.
    fn shape(
        &self,
        mem: &mut Memory,
        step: &Step,
        fence: &LiveFence,
        cur: Ned,
        (tp, tv): (Ned, Ned),
    ) -> ShapedSetpoint {
        let others = self.neighbours.around(step.planned, step.now);
        let yaw = mem.yaw_rad;
        let limits = self.shared.model.limits;
        let config = &self.context.config;
        let shaper = mem.shaper.get_or_insert_with(|| {
            SetpointShaper::new(
                cur,
                limits,
                fence.fence.clone(),
                config.setpoint_separation_m(),
            )
            .with_planned_separation(config.planned_separation_m())
        });
        // The floor binds where the vehicle is meant to fly, not on the way up.
        shaper.enforce_floor(step.state != VehicleState::TakingOff);
        let sp = shaper.step(tp, tv, yaw, step.dt, &others);
        if let Some(v) = sp.fence
            && mem.last_fence != sp.fence
        {
            self.emit(SwarmEvent::GeofenceClamp {
                id: self.shared.id.clone(),
                violation: v.name().into(),
            });
        }
        mem.last_fence = sp.fence;
        sp
    }

    /// A takeoff done at the target altitude `tp` (or failed: PX4 left OFFBOARD), a
    /// go-to at its point.
    fn procedure_progress(&self, mem: &mut Memory, state: VehicleState, cur: Ned, tp: Ned) {
        let mode = self.observed().map(|o| o.mode);
        if state == VehicleState::TakingOff && mem.offboard_engaged {
            if mode.is_some_and(|m| m != Px4Mode::Offboard) {
                if let Some(o) = self.observed() {
                    let _ = self.apply(mem, Event::ProcedureFailed(o));
                }
            } else if (cur.down_m - tp.down_m).abs() < ARRIVAL_TOLERANCE_M {
                let _ = self.apply(mem, Event::TakeoffComplete);
            }
        }
        if state == VehicleState::GoTo
            && mem
                .goto_target
                .is_some_and(|g| (cur - g).norm() < ARRIVAL_TOLERANCE_M)
        {
            let _ = self.apply(mem, Event::GoToReached);
        }
    }
}

/// What one control step works from.
struct Step<'a> {
    /// The swarm frame.
    frame: &'a NedFrame,
    /// The vehicle's local NED frame (its EKF origin), once known.
    local: Option<NedFrame>,
    /// The vehicle's swarm-frame position, once known.
    current: Option<Ned>,
    /// Now.
    now: Instant,
    /// Time since the last step, s (at most 0.2).
    dt: f64,
    /// The FSM state at the step's start.
    state: VehicleState,
    /// Whether the vehicle flies its formation slot (on the transition plan).
    planned: bool,
}
