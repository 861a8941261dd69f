//! The control step of a rehearsed vehicle, as the Vehicle actor's
//! (`skein_swarm::vehicle::control`): in a state skein steers, the target (moved on by
//! its age for a slot) is shaped by the [`SetpointShaper`] against the others, a slot
//! gets the slot correction, and the setpoint goes into the stream in the vehicle's
//! local frame; while PX4 flies (landing, RTL, failsafe) the stream holds where the
//! vehicle is; on the ground it stops.

use super::{Aircraft, Target};
use skein_link::LocalSetpoint;
use skein_model::fsm::{Event, VehicleState};
use skein_model::geo::{Ned, NedFrame};
use skein_model::obstacles::Obstacle;
use skein_model::px4::Px4Mode;
use skein_model::safety::SetpointShaper;
use skein_swarm::protocol::extrapolate_target;
use skein_swarm::vehicle::ARRIVAL_TOLERANCE_M;
use skein_swarm::vehicle::slot_correction::{OnSlot, local_setpoint};
use std::time::Duration;

impl Target {
    /// Position and velocity feed-forward at `now_s` (a slot moved on by its age, as
    /// the Vehicle actor's).
    fn now(&self, now_s: f64) -> (Ned, Ned) {
        match *self {
            Target::Hold(p) => (p, Ned::ZERO),
            Target::Track {
                position,
                velocity,
                at_s,
            } => extrapolate_target(
                position,
                velocity,
                Duration::from_secs_f64((now_s - at_s).max(0.0)),
            ),
        }
    }
}

impl Aircraft {
    /// A formation slot (swarm-frame position, velocity, yaw) for a member flying in
    /// the formation; ignored in any other state.
    pub fn on_slot(&mut self, position: Ned, velocity: Ned, yaw_rad: f64) {
        if self.state != VehicleState::InFormation {
            return;
        }
        let current = self.measured.map_or(position, |m| m.0);
        self.yaw_rad = yaw_rad;
        self.planned = true;
        let at_s = self.time_s();
        self.set_target(
            Target::Track {
                position,
                velocity,
                at_s,
            },
            current,
        );
    }

    /// One control step of `dt_s` against `others` (every other vehicle's position and
    /// setpoint): what the stream carries next (see the module docs).
    pub fn control(&mut self, dt_s: f64, others: &[Obstacle]) {
        self.steered = None;
        if self.state != VehicleState::InFormation {
            self.planned = false;
        }
        if let (Some(local), Some((cur, _))) = (self.telemetry.local_frame(), self.measured) {
            match self.state {
                VehicleState::TakingOff
                | VehicleState::Hovering
                | VehicleState::InFormation
                | VehicleState::GoTo => {
                    if let Some(target) = self.target {
                        self.steer(target, &local, cur, dt_s, others);
                    }
                }
                VehicleState::Landing | VehicleState::ReturnToLaunch | VehicleState::Failsafe => {
                    // PX4 flies; the stream holds where the vehicle is.
                    if let Some(s) = self.shaper.as_mut() {
                        s.reset(cur);
                    }
                    let here = self.swarm.transform_to(&local).apply(cur);
                    let hold = LocalSetpoint::position(here, self.yaw_rad);
                    if let Some((_, since)) = self.stream {
                        self.stream = Some((hold, since));
                    }
                }
                VehicleState::Lost => {}
                VehicleState::Landed | VehicleState::Armed | VehicleState::Disconnected => {
                    self.stream = None;
                    self.shaper = None;
                    self.target = None;
                }
            }
        }
        self.procedure_step();
    }

    /// Steers towards `target` from `cur`: the shaped setpoint into the stream (local
    /// frame `local`), then the procedure's progress.
    fn steer(
        &mut self,
        target: Target,
        local: &NedFrame,
        cur: Ned,
        dt_s: f64,
        others: &[Obstacle],
    ) {
        let to_local = self.swarm.transform_to(local);
        let (tp, tv) = target.now(self.time_s());
        if self.shaper.is_none() {
            self.shaper = Some(
                SetpointShaper::new(cur, self.limits, self.fence.clone(), self.separation_m)
                    .with_planned_separation(self.planned_separation_m),
            );
        }
        let shaper = self.shaper.as_mut().expect("made above");
        // The floor binds where the vehicle is meant to fly, not on the way up.
        shaper.enforce_floor(self.state != VehicleState::TakingOff);
        let others: Vec<Obstacle> = others
            .iter()
            .map(|o| Obstacle {
                planned: o.planned && self.planned,
                ..*o
            })
            .collect();
        let sp = shaper.step(tp, tv, self.yaw_rad, dt_s, &others);
        let slot = self.planned.then_some(OnSlot {
            correction: &mut self.slot_correction,
            measured: cur,
            dt_s,
        });
        let setpoint = local_setpoint(&sp, slot, &self.fence, &to_local);
        let since = self.stream.map_or(self.time_s(), |(_, s)| s);
        self.stream = Some((setpoint, since));
        self.steered = Some((sp.position, sp.velocity));
        self.progress(cur, tp);
    }

    /// A takeoff done at its altitude (failed: PX4 left OFFBOARD), a go-to at its point.
    fn progress(&mut self, cur: Ned, tp: Ned) {
        let mode = self.observed().map(|o| o.mode);
        if self.state == VehicleState::TakingOff && self.offboard_engaged {
            if mode.is_some_and(|m| m != Px4Mode::Offboard) {
                if let Some(o) = self.observed() {
                    self.apply(Event::ProcedureFailed(o));
                }
            } else if (cur.down_m - tp.down_m).abs() < ARRIVAL_TOLERANCE_M {
                self.apply(Event::TakeoffComplete);
            }
        }
        if self.state == VehicleState::GoTo
            && self
                .goto_target
                .is_some_and(|g| (cur - g).norm() < ARRIVAL_TOLERANCE_M)
        {
            self.apply(Event::GoToReached);
        }
    }
}
