//! Multicopter position control as PX4 v1.16's `mc_pos_control` does it
//! (`PositionControl.cpp`): a P loop on position (`MPC_XY_P`, `MPC_Z_P`) whose output,
//! plus the setpoint's velocity feed-forward, is limited to `MPC_XY_VEL_MAX` /
//! `MPC_Z_VEL_MAX_UP` / `MPC_Z_VEL_MAX_DN` (horizontal limit prioritising the position
//! term, `ControlMath::constrainXY`); a PID loop on velocity in acceleration units
//! (`MPC_*_VEL_P/I/D_ACC`, D on the measured acceleration) with PX4's anti-windup
//! (vertical clamp on thrust saturation, horizontal tracking anti-windup); and the
//! conversion of the acceleration setpoint into a thrust vector with the tilt limit
//! (`MPC_TILTMAX_AIR`), hover thrust (`MPC_THR_HOVER`), thrust limits (`MPC_THR_MIN`,
//! `MPC_THR_MAX`) and the horizontal thrust margin (`MPC_THR_XY_MARG`), horizontal and
//! vertical acceleration decoupled (`MPC_ACC_DECOUPLE` = 1).
//!
//! Like PX4, the controller knows nothing about drag: the velocity integrator has to
//! find it, which is why PX4 reaches only about 2.4 m/s of a 3 m/s velocity setpoint
//! after 5 s on SIH (drag 1 N/(m/s) on 1 kg).

use crate::px4_params::{Param, Params};
use crate::vehicle::GRAVITY_M_S2;

/// Gains and limits of one controller update, read from the parameter table (live, so a
/// PARAM_SET applies at the next update).
#[derive(Debug, Clone, Copy)]
pub(crate) struct PosCtrlParams {
    /// Position P gains (x, y, z), 1/s: `MPC_XY_P`, `MPC_Z_P`.
    pub pos_p: [f64; 3],
    /// Velocity P gains, (m/s²)/(m/s): `MPC_XY_VEL_P_ACC`, `MPC_Z_VEL_P_ACC`.
    pub vel_p: [f64; 3],
    /// Velocity I gains, (m/s²)/m: `MPC_XY_VEL_I_ACC`, `MPC_Z_VEL_I_ACC`.
    pub vel_i: [f64; 3],
    /// Velocity D gains, (m/s²)/(m/s²): `MPC_XY_VEL_D_ACC`, `MPC_Z_VEL_D_ACC`.
    pub vel_d: [f64; 3],
    /// Maximum tilt, rad: `MPC_TILTMAX_AIR`.
    pub tilt_max_rad: f64,
    /// Normalised hover thrust: `MPC_THR_HOVER`.
    pub thr_hover: f64,
    /// Normalised minimum / maximum collective thrust: `MPC_THR_MIN`, `MPC_THR_MAX`.
    pub thr_min: f64,
    /// See `thr_min`.
    pub thr_max: f64,
    /// Horizontal thrust kept free when vertical control saturates: `MPC_THR_XY_MARG`.
    pub thr_xy_margin: f64,
}

impl PosCtrlParams {
    /// The current values of `params`.
    pub fn from_params(p: &Params) -> PosCtrlParams {
        let xy_p = p.get(Param::MPC_XY_P);
        let xy_vp = p.get(Param::MPC_XY_VEL_P_ACC);
        let xy_vi = p.get(Param::MPC_XY_VEL_I_ACC);
        let xy_vd = p.get(Param::MPC_XY_VEL_D_ACC);
        PosCtrlParams {
            pos_p: [xy_p, xy_p, p.get(Param::MPC_Z_P)],
            vel_p: [xy_vp, xy_vp, p.get(Param::MPC_Z_VEL_P_ACC)],
            vel_i: [xy_vi, xy_vi, p.get(Param::MPC_Z_VEL_I_ACC)],
            vel_d: [xy_vd, xy_vd, p.get(Param::MPC_Z_VEL_D_ACC)],
            tilt_max_rad: p.get(Param::MPC_TILTMAX_AIR).clamp(1.0, 89.0).to_radians(),
            thr_hover: p.get(Param::MPC_THR_HOVER).clamp(0.05, 0.95),
            thr_min: p.get(Param::MPC_THR_MIN).clamp(0.0, 1.0),
            thr_max: p.get(Param::MPC_THR_MAX).clamp(0.05, 1.0),
            thr_xy_margin: p.get(Param::MPC_THR_XY_MARG).clamp(0.0, 1.0),
        }
    }
}

/// One update's setpoint: PX4's `trajectory_setpoint` (position and velocity per axis,
/// `None` = NaN = not controlled) with the speed limits of the active mode.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PosCtrlSetpoint {
    /// Position setpoint, local NED, m.
    pub pos_m: [Option<f64>; 3],
    /// Velocity setpoint or feed-forward, NED, m/s.
    pub vel_m_s: [Option<f64>; 3],
    /// Acceleration feed-forward, NED, m/s² (PX4's `trajectory_setpoint.acceleration`).
    pub acc_m_s2: [Option<f64>; 3],
    /// Horizontal speed limit, m/s.
    pub vel_xy_max_m_s: f64,
    /// Climb / descent speed limits, m/s (positive).
    pub vel_up_max_m_s: f64,
    /// See `vel_up_max_m_s`.
    pub vel_dn_max_m_s: f64,
}

/// What the controller commands.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct PosCtrlOutput {
    /// Normalised thrust vector in NED (body z axis times collective thrust; hover is
    /// about (0, 0, -`MPC_THR_HOVER`)).
    pub thrust_ned: [f64; 3],
    /// The velocity setpoint after the position loop and the limits, NED, m/s.
    pub vel_sp_m_s: [f64; 3],
}

/// State of the velocity PID (PX4's `_vel_int`, in acceleration units).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct PositionControl {
    vel_int: [f64; 3],
}

/// Scales `v` so that its (x, y) norm is at most `max`.
fn limit_xy(v: &mut [f64; 3], max: f64) {
    let n = v[0].hypot(v[1]);
    if n > max && n > 0.0 {
        v[0] *= max / n;
        v[1] *= max / n;
    }
}

/// PX4 `ControlMath::constrainXY`: `v0 + v1` limited to `max`, keeping as much of `v0`
/// (the position-loop term) as possible.
fn constrain_xy(v0: [f64; 2], v1: [f64; 2], max: f64) -> [f64; 2] {
    let sum = [v0[0] + v1[0], v0[1] + v1[1]];
    let n_sum = sum[0].hypot(sum[1]);
    if n_sum <= max {
        return sum;
    }
    let n0 = v0[0].hypot(v0[1]);
    if n0 >= max {
        return [v0[0] / n0 * max, v0[1] / n0 * max];
    }
    let n1 = v1[0].hypot(v1[1]);
    if n1 < 1e-9 {
        return [0.0, 0.0];
    }
    // Find s >= 0 with |v0 + s * u1| = max, u1 = v1 / |v1|.
    let u1 = [v1[0] / n1, v1[1] / n1];
    let m = v0[0] * u1[0] + v0[1] * u1[1];
    let c = n0 * n0 - max * max;
    let s = -m + (m * m - c).max(0.0).sqrt();
    [v0[0] + u1[0] * s, v0[1] + u1[1] * s]
}

impl PositionControl {
    /// Clears the integrator (PX4 resets it on arming and when a controller takes over).
    pub fn reset(&mut self) {
        self.vel_int = [0.0; 3];
    }

    /// One update: `pos_m` / `vel_m_s` the estimate, `acc_m_s2` the filtered measured
    /// acceleration (for the D term), all NED; `dt_s` the step.
    pub fn update(
        &mut self,
        k: &PosCtrlParams,
        sp: &PosCtrlSetpoint,
        pos_m: [f64; 3],
        vel_m_s: [f64; 3],
        acc_m_s2: [f64; 3],
        dt_s: f64,
    ) -> PosCtrlOutput {
        let vel_sp = velocity_setpoint(k, sp, pos_m);
        // Velocity PID → acceleration setpoint.
        self.vel_int[2] = self.vel_int[2].clamp(-GRAVITY_M_S2, GRAVITY_M_S2);
        let mut vel_err = [0.0; 3];
        let mut acc_sp = [0.0; 3];
        for i in 0..3 {
            vel_err[i] = vel_sp[i] - vel_m_s[i];
            acc_sp[i] = vel_err[i] * k.vel_p[i] + self.vel_int[i] - acc_m_s2[i] * k.vel_d[i]
                + sp.acc_m_s2[i].unwrap_or(0.0);
        }
        let mut thr = thrust_of(k, acc_sp);
        // Vertical anti-windup.
        if (thr[2] >= -k.thr_min && vel_err[2] >= 0.0)
            || (thr[2] <= -k.thr_max && vel_err[2] <= 0.0)
        {
            vel_err[2] = 0.0;
        }
        prioritise_vertical(k, &mut thr);
        self.integrate(k, acc_sp, thr, vel_err, dt_s);
        PosCtrlOutput {
            thrust_ned: thr,
            vel_sp_m_s: vel_sp,
        }
    }

    /// The velocity integrator's step, with the horizontal tracking anti-windup: the
    /// error is reduced by the acceleration the thrust limit left out.
    fn integrate(
        &mut self,
        k: &PosCtrlParams,
        acc_sp: [f64; 3],
        thr: [f64; 3],
        mut vel_err: [f64; 3],
        dt_s: f64,
    ) {
        let produced = [
            thr[0] * GRAVITY_M_S2 / k.thr_hover,
            thr[1] * GRAVITY_M_S2 / k.thr_hover,
        ];
        let arw_gain = if k.vel_p[0] > 0.0 {
            2.0 / k.vel_p[0]
        } else {
            0.0
        };
        let (acc_xy_sq, prod_sq) = (
            acc_sp[0] * acc_sp[0] + acc_sp[1] * acc_sp[1],
            produced[0] * produced[0] + produced[1] * produced[1],
        );
        let limited = if acc_xy_sq > prod_sq {
            produced
        } else {
            [acc_sp[0], acc_sp[1]]
        };
        vel_err[0] -= arw_gain * (acc_sp[0] - limited[0]);
        vel_err[1] -= arw_gain * (acc_sp[1] - limited[1]);
        for ((int, err), ki) in self.vel_int.iter_mut().zip(vel_err).zip(k.vel_i) {
            if err.is_finite() {
                *int += err * ki * dt_s;
            }
        }
    }
}

/// The position P loop's velocity setpoint, with the feed-forward velocity added where
/// both exist, limited horizontally (the position part first) and vertically.
fn velocity_setpoint(k: &PosCtrlParams, sp: &PosCtrlSetpoint, pos_m: [f64; 3]) -> [f64; 3] {
    let mut vel_sp = [None; 3];
    let mut vel_sp_position = [0.0; 3];
    for i in 0..3 {
        let p = sp.pos_m[i].map(|target| (target - pos_m[i]) * k.pos_p[i]);
        vel_sp_position[i] = p.unwrap_or(0.0);
        vel_sp[i] = match (sp.vel_m_s[i], p) {
            (Some(v), Some(p)) => Some(v + p),
            (Some(v), None) => Some(v),
            (None, p) => p,
        };
    }
    let vs = [
        vel_sp[0].unwrap_or(0.0),
        vel_sp[1].unwrap_or(0.0),
        vel_sp[2].unwrap_or(0.0),
    ];
    let xy = constrain_xy(
        [vel_sp_position[0], vel_sp_position[1]],
        [vs[0] - vel_sp_position[0], vs[1] - vel_sp_position[1]],
        sp.vel_xy_max_m_s.max(0.0),
    );
    [
        xy[0],
        xy[1],
        vs[2].clamp(-sp.vel_up_max_m_s.max(0.0), sp.vel_dn_max_m_s.max(0.0)),
    ]
}

/// Acceleration → thrust vector in NED (PositionControl::_accelerationControl,
/// decoupled): the body z axis tilted at most `tilt_max_rad`, times the collective.
fn thrust_of(k: &PosCtrlParams, acc_sp: [f64; 3]) -> [f64; 3] {
    let mut body_z = [-acc_sp[0], -acc_sp[1], GRAVITY_M_S2];
    let n = (body_z[0] * body_z[0] + body_z[1] * body_z[1] + body_z[2] * body_z[2]).sqrt();
    for c in &mut body_z {
        *c /= n;
    }
    // body_z is the body z axis (down when level); limit its angle to the vertical.
    let tilt = body_z[0].hypot(body_z[1]).atan2(body_z[2]);
    if tilt > k.tilt_max_rad {
        let h = body_z[0].hypot(body_z[1]);
        let (s, c) = k.tilt_max_rad.sin_cos();
        body_z = [body_z[0] / h * s, body_z[1] / h * s, c];
    }
    let thrust_ned_z = acc_sp[2] * (k.thr_hover / GRAVITY_M_S2) - k.thr_hover;
    let collective = (thrust_ned_z / body_z[2]).min(-k.thr_min);
    // Thrust vector in NED: body z axis (pointing down) times collective (negative).
    [
        body_z[0] * collective,
        body_z[1] * collective,
        body_z[2] * collective,
    ]
}

/// Limits the thrust to `thr_max`, vertical first, keeping a horizontal margin.
fn prioritise_vertical(k: &PosCtrlParams, thr: &mut [f64; 3]) {
    let thr_xy_norm = thr[0].hypot(thr[1]);
    let thr_max_sq = k.thr_max * k.thr_max;
    let allocated_xy = thr_xy_norm.min(k.thr_xy_margin);
    let thr_z_max_sq = thr_max_sq - allocated_xy * allocated_xy;
    thr[2] = thr[2].max(-thr_z_max_sq.max(0.0).sqrt());
    let thr_max_xy = (thr_max_sq - thr[2] * thr[2]).max(0.0).sqrt();
    if thr_xy_norm > thr_max_xy {
        limit_xy(thr, thr_max_xy);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constrain_xy_prefers_the_position_term() {
        let v = constrain_xy([3.0, 0.0], [0.0, 10.0], 5.0);
        assert!((v[0] - 3.0).abs() < 1e-9 && (v[1] - 4.0).abs() < 1e-9);
        let v = constrain_xy([10.0, 0.0], [0.0, 1.0], 5.0);
        assert!((v[0] - 5.0).abs() < 1e-9 && v[1].abs() < 1e-9);
        let v = constrain_xy([1.0, 1.0], [1.0, 0.0], 5.0);
        assert!((v[0] - 2.0).abs() < 1e-9 && (v[1] - 1.0).abs() < 1e-9);
    }

    #[test]
    fn hover_thrust_when_at_rest_on_target() {
        let (params, _) = Params::new(1, &[]);
        let k = PosCtrlParams::from_params(&params);
        let mut pc = PositionControl::default();
        let sp = PosCtrlSetpoint {
            pos_m: [Some(0.0), Some(0.0), Some(-10.0)],
            vel_m_s: [None; 3],
            acc_m_s2: [None; 3],
            vel_xy_max_m_s: 12.0,
            vel_up_max_m_s: 3.0,
            vel_dn_max_m_s: 1.5,
        };
        let out = pc.update(&k, &sp, [0.0, 0.0, -10.0], [0.0; 3], [0.0; 3], 0.01);
        assert!(out.thrust_ned[0].abs() < 1e-9 && out.thrust_ned[1].abs() < 1e-9);
        assert!((out.thrust_ned[2] + k.thr_hover).abs() < 1e-9);
    }

    #[test]
    fn tilt_is_limited() {
        let (params, _) = Params::new(1, &[]);
        let k = PosCtrlParams::from_params(&params);
        let mut pc = PositionControl::default();
        let sp = PosCtrlSetpoint {
            pos_m: [Some(100.0), Some(0.0), Some(-10.0)],
            vel_m_s: [None; 3],
            acc_m_s2: [None; 3],
            vel_xy_max_m_s: 12.0,
            vel_up_max_m_s: 3.0,
            vel_dn_max_m_s: 1.5,
        };
        let out = pc.update(&k, &sp, [0.0, 0.0, -10.0], [0.0; 3], [0.0; 3], 0.01);
        let t = out.thrust_ned;
        let tilt = t[0].hypot(t[1]).atan2(-t[2]);
        assert!(tilt <= k.tilt_max_rad + 1e-9, "{tilt}");
        assert!((out.vel_sp_m_s[0] - 12.0).abs() < 1e-9);
    }
}
