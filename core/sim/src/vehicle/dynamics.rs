//! Vehicle dynamics, SIH-like (PX4's simulation-in-hardware quadrotor, `sihsim_quadx`): a
//! rigid body of `SIH_MASS` (1 kg) whose rotors produce up to twice its weight along the
//! body z axis, linear drag `SIH_KDV` (1 N/(m/s)) against the air-relative velocity, an
//! attitude that follows the position controller's thrust direction with a first-order lag
//! (PX4's attitude and rate loops on SIH's inertia), and a yaw rate loop (`MC_YAW_P`, rate
//! limit, rate lag) fitted to PX4's 90° yaw step. Also the auto-mode trajectory (PX4's
//! flight tasks, simplified to a speed- and acceleration-limited point), wind and gusts,
//! and the estimator noise.
//!
//! Physics is sub-stepped at [`MAX_SUBSTEP_S`] whatever the tick, so the response does
//! not depend on the telemetry profile's tick rate.

use super::position_control::{PosCtrlParams, PosCtrlSetpoint};
use super::*;

/// Longest physics sub-step, s (SIH runs at 250 Hz in lockstep).
pub(crate) const MAX_SUBSTEP_S: f64 = 0.004;
/// Time constant of the attitude following the commanded thrust direction, s (PX4
/// `MC_ROLL_P`/`MC_PITCH_P` 6.5 and the rate loop on SIH's inertia, fitted to the 10 m
/// step of the PX4 traces).
const ATTITUDE_TAU_S: f64 = 0.1;
/// Time constant of the yaw rate following its setpoint, s (fitted to the PX4 yaw step:
/// about 15° overshoot on 90°, 90 % in about 0.9 s).
const YAW_RATE_TAU_S: f64 = 0.37;
/// Cut-off of the acceleration estimate feeding the velocity D term, Hz (PX4
/// `MPC_VELD_LP`).
const ACC_LP_HZ: f64 = 5.0;
/// Maximum rotor thrust over weight at `SIH_MASS` = 1 kg (SIH: 4 × 5 N on 1 kg), so
/// hover needs normalised thrust 0.5.
const THRUST_TO_WEIGHT_AT_1KG: f64 = 2.0;
/// Estimator noise (on with `--estimator-noise`): standard deviation of the velocity
/// error per axis, m/s, its correlation time, s, and the leak of the position error, s.
/// Tuned so that the hover wanders about 0.2 m and 0.2 m/s, as PX4 SIH does.
const EST_VEL_NOISE_M_S: [f64; 3] = [0.2, 0.2, 0.05];
const EST_VEL_NOISE_TAU_S: f64 = 0.5;
const EST_POS_LEAK_TAU_S: f64 = 1.5;
/// Estimator noise: the slow bias of the vertical velocity estimate, m/s (standard
/// deviation) and its correlation time, s. PX4 SIH's EKF anchors its height to the
/// barometer but lets its vertical velocity drift by 0.1–0.3 m/s for several seconds
/// (the traces: `z` steady while `vz` reads 0.2 m/s). The position loop turns it into a
/// height offset of `bias / MPC_Z_P` (0.19–0.23 m after the 5 m steps) and a slower
/// approach to the target; it is not integrated into the position estimate.
const EST_VZ_BIAS_M_S: f64 = 0.15;
const EST_VZ_BIAS_TAU_S: f64 = 6.0;
/// Auto-mode trajectory: position gain pulling the moving setpoint to its target, 1/s.
const TRAJ_P: f64 = 2.0;

fn arr(v: Ned) -> [f64; 3] {
    [v.north_m, v.east_m, v.down_m]
}

fn ned(a: [f64; 3]) -> Ned {
    Ned::new(a[0], a[1], a[2])
}

/// `1 - exp(-dt / tau)`: the exact step of a first-order lag.
fn lag(dt: f64, tau: f64) -> f64 {
    if tau <= 0.0 {
        1.0
    } else {
        1.0 - (-dt / tau).exp()
    }
}

impl Vehicle {
    pub(super) fn wind_now(&self) -> Ned {
        Ned::new(
            self.env.wind.north_m_s + self.gust.north_m,
            self.env.wind.east_m_s + self.gust.east_m,
            0.0,
        )
    }

    /// Linear drag acceleration at the current velocity, NED m/s² (`SIH_KDV / SIH_MASS`).
    fn drag_acc(&self) -> Ned {
        let kdv = self.params.get(Param::SIH_KDV).max(0.0);
        let mass = self.params.get(Param::SIH_MASS).max(0.05);
        (self.wind_now() - self.vel) * (kdv / mass)
    }

    /// Advances the physics by `dt` (sub-stepped at [`MAX_SUBSTEP_S`]).
    pub(super) fn physics(&mut self, dt: f64) {
        let prev_roll = self.roll_rad;
        let prev_pitch = self.pitch_rad;
        let n = (dt / MAX_SUBSTEP_S).ceil().max(1.0);
        let h = dt / n;
        for _ in 0..n as usize {
            self.physics_substep(h);
        }
        // Attitude from the thrust direction and the heading.
        let on_ground_idle = !matches!(self.goal, Goal::Track(_)) && self.pos.down_m >= 0.0;
        if on_ground_idle || matches!(self.goal, Goal::FreeFall) {
            self.roll_rad = 0.0;
            self.pitch_rad = 0.0;
        } else {
            let (s, c) = self.yaw_rad.sin_cos();
            let (tn, te) = (self.tilt_up[0], self.tilt_up[1]);
            let up = (1.0 - tn * tn - te * te).max(0.0).sqrt().max(1e-3);
            let fwd = c * tn + s * te;
            let right = -s * tn + c * te;
            self.pitch_rad = (-fwd).atan2(up);
            self.roll_rad = right.atan2(up.hypot(fwd));
        }
        if dt > 0.0 {
            self.roll_rate_rad_s = (self.roll_rad - prev_roll) / dt;
            self.pitch_rate_rad_s = (self.pitch_rad - prev_pitch) / dt;
        }
    }

    fn physics_substep(&mut self, dt: f64) {
        match self.goal {
            Goal::Idle => {
                self.vel = Ned::ZERO;
                self.pos.down_m = 0.0;
                self.thrust_acc = Ned::new(0.0, 0.0, -GRAVITY_M_S2);
                self.tilt_up = [0.0; 2];
                self.acc_filt = Ned::ZERO;
                self.yaw_rate_rad_s = 0.0;
                self.pos_ctrl.reset();
                self.traj_valid = false;
                self.vel_sp_smooth = Ned::ZERO;
                self.ctrl_pos_sp = self.pos;
                self.ctrl_vel_sp = Ned::ZERO;
                self.ctrl_yaw_sp = self.yaw_rad;
            }
            Goal::FreeFall => {
                let drag = self.drag_acc();
                let acc = Ned::new(drag.north_m, drag.east_m, GRAVITY_M_S2 + drag.down_m);
                self.vel = self.vel + acc * dt;
                self.pos = self.pos + self.vel * dt;
                self.thrust_acc = Ned::ZERO;
                self.ctrl_vel_sp = Ned::ZERO;
                self.traj_valid = false;
            }
            Goal::Track(t) => self.fly(t, dt),
        }
        // Ground contact (flat ground at the local origin's altitude).
        if self.pos.down_m >= 0.0 {
            self.pos.down_m = 0.0;
            if self.vel.down_m > 0.0 {
                self.vel.down_m = 0.0;
            }
            if !matches!(self.goal, Goal::Track(_)) || self.ctrl_vel_sp.down_m >= -0.05 {
                self.vel.north_m = 0.0;
                self.vel.east_m = 0.0;
            }
        }
    }

    /// The controller's setpoint for `t`: the raw setpoint (offboard) or a moving point
    /// that approaches it with the mode's speed and acceleration limits (auto modes).
    fn trajectory(&mut self, t: &Track, dt: f64) -> PosCtrlSetpoint {
        let mut sp = PosCtrlSetpoint {
            pos_m: t.pos,
            vel_m_s: t.vel,
            acc_m_s2: t.acc,
            vel_xy_max_m_s: t.xy_max_m_s,
            vel_up_max_m_s: t.up_max_m_s,
            vel_dn_max_m_s: t.down_max_m_s,
        };
        if !t.smooth {
            self.traj_valid = false;
            return sp;
        }
        if !self.traj_valid {
            self.traj_pos = self.est_pos();
            self.vel_sp_smooth = self.est_vel();
            self.traj_valid = true;
        }
        let p = &self.params;
        let acc_hor = p.get(Param::MPC_ACC_HOR).max(0.1);
        let acc_up = p.get(Param::MPC_ACC_UP_MAX).max(0.1);
        let acc_dn = p.get(Param::MPC_ACC_DOWN_MAX).max(0.1);
        // Speed toward the target: limited by the mode's speed, by braking at half the
        // acceleration limit, and by a P gain near the target.
        let approach = |dist: f64, vmax: f64, acc: f64| -> f64 {
            vmax.max(0.0)
                .min((acc * dist.abs()).sqrt())
                .min(TRAJ_P * dist.abs())
        };
        let mut want = Ned::ZERO;
        if let (Some(n), Some(e)) = (t.pos[0], t.pos[1]) {
            let d = Ned::new(n - self.traj_pos.north_m, e - self.traj_pos.east_m, 0.0);
            let dist = d.horizontal_norm();
            if dist > 1e-9 {
                let v = approach(dist, t.xy_max_m_s, acc_hor);
                want.north_m = d.north_m / dist * v;
                want.east_m = d.east_m / dist * v;
            }
            want.north_m += t.vel[0].unwrap_or(0.0);
            want.east_m += t.vel[1].unwrap_or(0.0);
        } else {
            want.north_m = t.vel[0].unwrap_or(0.0);
            want.east_m = t.vel[1].unwrap_or(0.0);
        }
        want.down_m = match (t.pos[2], t.vel[2]) {
            (Some(z), ff) => {
                let d = z - self.traj_pos.down_m;
                let acc = if d < 0.0 { acc_up } else { acc_dn };
                let max = if d < 0.0 {
                    t.up_max_m_s
                } else {
                    t.down_max_m_s
                };
                d.signum() * approach(d, max, acc) + ff.unwrap_or(0.0)
            }
            (None, Some(v)) => v,
            (None, None) => 0.0,
        };
        limit_horizontal(&mut want, t.xy_max_m_s.max(0.0));
        want.down_m = want
            .down_m
            .clamp(-t.up_max_m_s.max(0.0), t.down_max_m_s.max(0.0));
        let mut dv = want - self.vel_sp_smooth;
        limit_horizontal(&mut dv, acc_hor * dt);
        dv.down_m = dv.down_m.clamp(-acc_up * dt, acc_dn * dt);
        self.vel_sp_smooth = self.vel_sp_smooth + dv;
        self.traj_pos = self.traj_pos + self.vel_sp_smooth * dt;
        for i in 0..3 {
            if t.pos[i].is_some() {
                sp.pos_m[i] = Some(axis(&self.traj_pos, i));
                sp.vel_m_s[i] = Some(axis(&self.vel_sp_smooth, i));
            } else {
                set_axis(&mut self.traj_pos, i, axis(&self.pos, i));
                sp.vel_m_s[i] = t.vel[i].map(|_| axis(&self.vel_sp_smooth, i));
            }
        }
        // The moving point already respects the limits; leave the controller room to
        // catch up with it.
        sp.vel_xy_max_m_s = p.get(Param::MPC_XY_VEL_MAX).max(t.xy_max_m_s);
        sp.vel_up_max_m_s = p.get(Param::MPC_Z_VEL_MAX_UP).max(t.up_max_m_s);
        sp.vel_dn_max_m_s = p.get(Param::MPC_Z_VEL_MAX_DN).max(t.down_max_m_s);
        sp
    }

    /// One sub-step of controlled flight: position control, attitude, forces, yaw.
    fn fly(&mut self, t: Track, dt: f64) {
        let sp = self.trajectory(&t, dt);
        let k = PosCtrlParams::from_params(&self.params);
        let est_pos = self.est_pos();
        let est_vel = self.est_vel();
        let out = self
            .pos_ctrl
            .update(&k, &sp, arr(est_pos), arr(est_vel), arr(self.acc_filt), dt);
        // Attitude: the thrust direction follows the commanded one with a lag.
        let thr = out.thrust_ned;
        let collective = (thr[0] * thr[0] + thr[1] * thr[1] + thr[2] * thr[2]).sqrt();
        let a = lag(dt, ATTITUDE_TAU_S);
        if collective > 1e-6 {
            self.tilt_up[0] += (thr[0] / collective - self.tilt_up[0]) * a;
            self.tilt_up[1] += (thr[1] / collective - self.tilt_up[1]) * a;
        }
        let h = self.tilt_up[0].hypot(self.tilt_up[1]);
        if h > 0.999 {
            self.tilt_up[0] *= 0.999 / h;
            self.tilt_up[1] *= 0.999 / h;
        }
        let up = (1.0 - self.tilt_up[0].powi(2) - self.tilt_up[1].powi(2)).sqrt();
        // Forces: rotor thrust along the body axis, gravity, drag.
        let mass = self.params.get(Param::SIH_MASS).max(0.05);
        let thrust_acc = collective * THRUST_TO_WEIGHT_AT_1KG * GRAVITY_M_S2 / mass;
        self.thrust_acc = Ned::new(
            self.tilt_up[0] * thrust_acc,
            self.tilt_up[1] * thrust_acc,
            -up * thrust_acc,
        );
        let acc = self.thrust_acc + Ned::new(0.0, 0.0, GRAVITY_M_S2) + self.drag_acc();
        self.vel = self.vel + acc * dt;
        self.pos = self.pos + self.vel * dt;
        self.acc_filt = self.acc_filt
            + (acc - self.acc_filt) * lag(dt, 1.0 / (std::f64::consts::TAU * ACC_LP_HZ));
        // Yaw: P on the heading error, rate limit, rate loop lag.
        let rate_sp = match t.yaw {
            YawGoal::Heading(target) => {
                self.ctrl_yaw_sp = target;
                self.params.get(Param::MC_YAW_P) * wrap_pi(target - self.yaw_rad)
            }
            YawGoal::Rate(r) => {
                self.ctrl_yaw_sp = self.yaw_rad;
                r
            }
        }
        .clamp(-t.yaw_rate_max_rad_s, t.yaw_rate_max_rad_s);
        self.yaw_rate_rad_s += (rate_sp - self.yaw_rate_rad_s) * lag(dt, YAW_RATE_TAU_S);
        self.yaw_rad = wrap_pi(self.yaw_rad + self.yaw_rate_rad_s * dt);
        self.ctrl_pos_sp = Ned::new(
            sp.pos_m[0].unwrap_or(self.pos.north_m),
            sp.pos_m[1].unwrap_or(self.pos.east_m),
            sp.pos_m[2].unwrap_or(self.pos.down_m),
        );
        self.ctrl_vel_sp = ned(out.vel_sp_m_s);
    }

    pub(super) fn update_noise(&mut self, dt: f64) {
        if self.env.wind.gust_m_s > 0.0 {
            let a = (-dt / GUST_TAU_S).exp();
            let s = self.env.wind.gust_m_s * (1.0 - a * a).sqrt();
            self.gust = Ned::new(
                self.gust.north_m * a + s * gaussian(&mut self.rng),
                self.gust.east_m * a + s * gaussian(&mut self.rng),
                0.0,
            );
        }
        if self.env.estimator_noise {
            // PX4 SIH's hover wander: the EKF's velocity error is a coloured noise (SIH's
            // strong accelerometer noise through the filter) and its position error the
            // leaky integral of it. The controller flies on the estimate, so the truth
            // wanders too; LOCAL_POSITION_NED reports the estimate.
            let a = (-dt / EST_VEL_NOISE_TAU_S).exp();
            let s = (1.0 - a * a).sqrt();
            let sigma = [
                EST_VEL_NOISE_M_S[0] * s,
                EST_VEL_NOISE_M_S[1] * s,
                EST_VEL_NOISE_M_S[2] * s,
            ];
            self.est_vel_noise = Ned::new(
                self.est_vel_noise.north_m * a + sigma[0] * gaussian(&mut self.rng),
                self.est_vel_noise.east_m * a + sigma[1] * gaussian(&mut self.rng),
                self.est_vel_noise.down_m * a + sigma[2] * gaussian(&mut self.rng),
            );
            let leak = self.est_noise * (1.0 / EST_POS_LEAK_TAU_S);
            self.est_noise = self.est_noise + (self.est_vel_noise - leak) * dt;
            let b = (-dt / EST_VZ_BIAS_TAU_S).exp();
            self.est_vz_bias_m_s = self.est_vz_bias_m_s * b
                + EST_VZ_BIAS_M_S * (1.0 - b * b).sqrt() * gaussian(&mut self.rng);
        } else if self.env.gps_noise_m > 0.0 {
            // The EKF smooths GPS: a slow random walk of about half the GPS noise.
            let a = (-dt / EST_NOISE_TAU_S).exp();
            let s = 0.5 * self.env.gps_noise_m * (1.0 - a * a).sqrt();
            self.est_noise = Ned::new(
                self.est_noise.north_m * a + s * gaussian(&mut self.rng),
                self.est_noise.east_m * a + s * gaussian(&mut self.rng),
                self.est_noise.down_m * a + 1.5 * s * gaussian(&mut self.rng),
            );
        }
    }

    /// White GPS receiver noise on top of the estimator error, m (GPS_RAW_INT only).
    pub fn gps_white_noise(&mut self) -> Ned {
        if self.env.gps_noise_m > 0.0 {
            let s = 0.5 * self.env.gps_noise_m;
            Ned::new(
                s * gaussian(&mut self.rng),
                s * gaussian(&mut self.rng),
                1.5 * s * gaussian(&mut self.rng),
            )
        } else {
            Ned::ZERO
        }
    }
}
