//! Slot correction: PX4's position controller lags a moving setpoint. On PX4 v1.16
//! (SIH, default parameters) a point moving at 5 m/s with velocity feed-forward is
//! followed 1.25 m behind, and a 5 m/s circle is flown 1.7 m wide: the drag needs a tilt
//! that only the slow velocity integrator (`MPC_XY_VEL_I_ACC` 0.4) builds, and nothing
//! asks for the acceleration of a curve. A formation flown on raw slot targets carries
//! that as slot error.
//!
//! [`SlotCorrection`] adds what PX4's offboard setpoint can carry beyond position and
//! velocity: an acceleration feed-forward (SET_POSITION_TARGET_LOCAL_NED `afx/afy/afz`,
//! type_mask without the acceleration bits, which PX4 adds to its velocity controller's
//! output). It is the commanded path's own acceleration (the curve, the speed-ups) plus
//! a drag term `drag_per_s × velocity` that the correction learns from the measured
//! along-track error (where skein sends the vehicle minus where the vehicle is), so it
//! fits any airframe: the integrator PX4 would have to build over seconds is there from
//! the first metre. What remains across the track on a curve is integrated into a small
//! position offset. Both are bounded, frozen while the error is large (a transient, not
//! a lag), and the offset decays when the target stops.
//!
//! Vertically, PX4's estimate of the vertical velocity drifts by 0.1–0.3 m/s for seconds
//! at a time while its height stays anchored to the barometer (the PX4 traces), so PX4
//! holds its height estimate `bias / MPC_Z_P` (about 0.2 m) off the setpoint. That error
//! is visible in LOCAL_POSITION_NED: a slow integral of the measured height error
//! (`ki_z_per_s`, learnt in level flight, bounded by `max_height_m`) cancels it.

use skein_link::LocalSetpoint;
use skein_model::geo::{FrameTransform, Ned};
use skein_model::geofence::Geofence;
use skein_model::safety::ShapedSetpoint;

/// What a vehicle flying its formation slot adds to the shaped setpoint: its
/// [`SlotCorrection`], where it is (swarm-frame NED, m) and the control period (s).
pub struct OnSlot<'a> {
    /// The vehicle's correction state, updated by this step.
    pub correction: &'a mut SlotCorrection,
    /// The measured position, swarm-frame NED metres.
    pub measured: Ned,
    /// The control period, seconds.
    pub dt_s: f64,
}

/// The setpoint sent to PX4 (`SET_POSITION_TARGET_LOCAL_NED`, the vehicle's local NED
/// frame through `to_local`) for the shaped swarm-frame `sp`: on a slot, PX4's tracking
/// lag cancelled (the correction's offset, the point clamped into `fence` like any
/// other, and its acceleration feed-forward); otherwise position and velocity as shaped.
/// The Vehicle actor and the rehearsal both send exactly this.
pub fn local_setpoint(
    sp: &ShapedSetpoint,
    slot: Option<OnSlot<'_>>,
    fence: &Geofence,
    to_local: &FrameTransform,
) -> LocalSetpoint {
    match slot {
        Some(on) => {
            let c = on.correction.update(
                &SlotCorrectionGains::default(),
                sp.position,
                sp.velocity,
                on.measured,
                on.dt_s,
            );
            let (p, _) = fence.clamp(sp.position + c.offset, true);
            LocalSetpoint::position_velocity_acceleration(
                to_local.apply(p),
                sp.velocity,
                c.acceleration,
                sp.yaw_rad,
            )
        }
        None => {
            LocalSetpoint::position_velocity(to_local.apply(sp.position), sp.velocity, sp.yaw_rad)
        }
    }
}

/// Gains and bounds of [`SlotCorrection`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlotCorrectionGains {
    /// Adaptation rate of the drag term, (1/s) per second per metre of along-track
    /// error.
    pub drag_rate: f64,
    /// Largest drag term learnt, 1/s (SIH's linear drag on 1 kg is 1/s).
    pub max_drag_per_s: f64,
    /// Integral gain on the cross-track error, 1/s.
    pub ki_per_s: f64,
    /// Largest cross-track offset, metres.
    pub max_cross_m: f64,
    /// Integral gain on the height error in level flight, 1/s.
    pub ki_z_per_s: f64,
    /// Largest height offset, metres.
    pub max_height_m: f64,
    /// Largest acceleration feed-forward, m/s².
    pub max_acc_m_s2: f64,
    /// Errors above this are transients: the correction does not learn from them, metres.
    pub max_error_m: f64,
    /// Below this commanded speed nothing is learnt and the offset decays, m/s.
    pub moving_m_s: f64,
    /// Decay time constant of the offset while not moving, seconds.
    pub leak_s: f64,
}

impl Default for SlotCorrectionGains {
    fn default() -> Self {
        SlotCorrectionGains {
            drag_rate: 0.1,
            max_drag_per_s: 2.0,
            ki_per_s: 0.3,
            max_cross_m: 1.5,
            ki_z_per_s: 1.0,
            max_height_m: 1.0,
            max_acc_m_s2: 6.0,
            max_error_m: 3.0,
            moving_m_s: 0.5,
            leak_s: 1.0,
        }
    }
}

/// What to send on top of the commanded position and velocity.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Correction {
    /// Added to the position setpoint, NED metres.
    pub offset: Ned,
    /// Acceleration feed-forward, NED m/s².
    pub acceleration: Ned,
}

/// The correction's state (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SlotCorrection {
    /// Learnt drag: the acceleration needed per m/s of horizontal speed, 1/s.
    pub drag_per_s: f64,
    /// Integral of the horizontal error across the commanded velocity (positive to the
    /// right of the direction of travel), metres.
    pub cross_m: f64,
    /// Integral of the height error (down positive: the vehicle sits too high), metres.
    pub height_m: f64,
    /// The commanded velocity at the last update (for its derivative), NED m/s.
    last_velocity: Option<Ned>,
    /// The commanded acceleration, low-pass filtered, NED m/s².
    acceleration: Ned,
}

/// Time constant of the commanded acceleration's low-pass filter, seconds.
const ACC_FILTER_S: f64 = 0.1;

impl SlotCorrection {
    /// Forgets the path (keeps the learnt drag, a property of the airframe).
    pub fn reset(&mut self) {
        *self = SlotCorrection {
            drag_per_s: self.drag_per_s,
            ..SlotCorrection::default()
        };
    }

    /// Learns from one control period of `dt_s` seconds: `commanded` and
    /// `commanded_velocity` are where skein means the vehicle to be and how fast that
    /// moves (before the correction), `measured` where it is (all swarm-frame NED).
    pub fn update(
        &mut self,
        g: &SlotCorrectionGains,
        commanded: Ned,
        commanded_velocity: Ned,
        measured: Ned,
        dt_s: f64,
    ) -> Correction {
        if dt_s <= 0.0 {
            return self.correction(g, commanded_velocity);
        }
        let raw_acc = self
            .last_velocity
            .map_or(Ned::ZERO, |v| (commanded_velocity - v) * (1.0 / dt_s));
        self.last_velocity = Some(commanded_velocity);
        let k = (dt_s / ACC_FILTER_S).min(1.0);
        self.acceleration = self.acceleration + (raw_acc - self.acceleration) * k;
        let error = commanded - measured;
        let h = commanded_velocity.horizontal_norm();
        if h >= g.moving_m_s {
            if error.norm() <= g.max_error_m {
                let (n, e) = (
                    commanded_velocity.north_m / h,
                    commanded_velocity.east_m / h,
                );
                let along = error.north_m * n + error.east_m * e;
                let across = -error.north_m * e + error.east_m * n;
                self.drag_per_s =
                    (self.drag_per_s + g.drag_rate * along * dt_s).clamp(0.0, g.max_drag_per_s);
                self.cross_m = (self.cross_m + g.ki_per_s * across * dt_s)
                    .clamp(-g.max_cross_m, g.max_cross_m);
            }
        } else {
            self.cross_m *= (-dt_s / g.leak_s).exp();
        }
        if commanded_velocity.down_m.abs() < g.moving_m_s && error.down_m.abs() <= g.max_error_m {
            self.height_m = (self.height_m + g.ki_z_per_s * error.down_m * dt_s)
                .clamp(-g.max_height_m, g.max_height_m);
        }
        self.correction(g, commanded_velocity)
    }

    /// The correction for a target moving at `commanded_velocity` now.
    pub fn correction(&self, g: &SlotCorrectionGains, commanded_velocity: Ned) -> Correction {
        let h = commanded_velocity.horizontal_norm();
        let mut offset = Ned::new(0.0, 0.0, self.height_m);
        if h > 1e-6 {
            // Right of the direction of travel: (−v_e, v_n)/|v|.
            let right = Ned::new(
                -commanded_velocity.east_m / h,
                commanded_velocity.north_m / h,
                0.0,
            );
            offset = offset + right * self.cross_m;
        }
        let mut drag = commanded_velocity * self.drag_per_s;
        drag.down_m = 0.0;
        let mut acceleration = self.acceleration + drag;
        let n = acceleration.norm();
        if n > g.max_acc_m_s2 {
            acceleration = acceleration * (g.max_acc_m_s2 / n);
        }
        Correction {
            offset,
            acceleration,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A vehicle that holds its height estimate `bias_m` above the setpoint (PX4's
    /// vertical velocity bias): the height offset converges to cancel it, within bounds,
    /// and nothing is learnt while the target climbs.
    #[test]
    fn the_height_offset_cancels_a_steady_height_error_in_level_flight() {
        let g = SlotCorrectionGains::default();
        let mut c = SlotCorrection::default();
        let target = Ned::new(0.0, 0.0, -10.0);
        let bias_m = -0.2;
        let dt = 0.02;
        for _ in 0..(20.0 / dt) as usize {
            // The vehicle flies to setpoint + offset, and sits `bias_m` off it.
            let measured = target + c.correction(&g, Ned::ZERO).offset + Ned::new(0.0, 0.0, bias_m);
            c.update(&g, target, Ned::ZERO, measured, dt);
        }
        let measured = target + c.correction(&g, Ned::ZERO).offset + Ned::new(0.0, 0.0, bias_m);
        assert!((measured - target).norm() < 0.01, "{measured:?}");
        assert!((c.height_m - 0.2).abs() < 0.01, "{}", c.height_m);

        let before = c.height_m;
        let climbing = Ned::new(0.0, 0.0, -2.0);
        c.update(&g, target, climbing, target + Ned::new(0.0, 0.0, 1.0), dt);
        assert_eq!(c.height_m, before, "learnt during a climb");

        let mut far = SlotCorrection::default();
        for _ in 0..1000 {
            far.update(&g, target, Ned::ZERO, target + Ned::new(0.0, 0.0, -2.5), dt);
        }
        assert!(
            (far.height_m - g.max_height_m).abs() < 1e-9,
            "{}",
            far.height_m
        );
    }
}
