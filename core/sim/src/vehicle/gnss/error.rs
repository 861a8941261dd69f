//! The receiver's position error (`--gnss-wander`): per axis a first-order Gauss-Markov
//! process whose standard deviation and time constant are the fix state's, plus a small
//! white noise on each reported fix. On a change of state the error converges to the new
//! state's process within seconds (what is left of the old error decays with
//! [`CONVERGE_TAU_S`]), so there is no jump an EKF could not follow.
//!
//! The figures ([`FixFigures::of`]), u-blox ZED-F9P in the open: 1.5 m CEP without
//! corrections (data sheet, "PVT"), standalone errors correlated over minutes
//! (ionosphere, orbits); RTK 0.01 m + 1 ppm CEP horizontally and 0.01 m + 1 ppm R50
//! vertically (data sheet), taken 40–50 % worse than the data sheet, as field logs are,
//! within the 1–2 cm / 2–3 cm of RTK fixed in practice; float in between, decimetres.

use super::fix::GnssFix;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use skein_model::geo::Ned;

/// Time constant of the convergence from one state's error to the next one's, s.
pub const CONVERGE_TAU_S: f64 = 2.0;
/// CEP over the standard deviation per axis of a circular normal error.
const CEP_PER_SIGMA: f64 = 1.1774;
/// R50 (median of a one-axis error) over its standard deviation.
const R50_PER_SIGMA: f64 = 0.6745;

/// What the receiver delivers in one fix state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixFigures {
    /// Standard deviation of the slow error per horizontal axis, m.
    pub sigma_h_m: f64,
    /// Standard deviation of the slow vertical error, m.
    pub sigma_v_m: f64,
    /// Correlation time of the slow error, s.
    pub tau_s: f64,
    /// Standard deviation of the white noise of each fix, per horizontal axis, m.
    pub white_h_m: f64,
    /// Standard deviation of the white noise of each fix, vertical, m.
    pub white_v_m: f64,
}

impl FixFigures {
    /// The figures of `fix` with a base `baseline_m` away (RTK fixed: 1 ppm of it).
    pub fn of(fix: GnssFix, baseline_m: f64) -> FixFigures {
        match fix {
            // Data sheet 1.5 m CEP; vertical 1.5 times worse, as usual for GNSS.
            GnssFix::Fix3d => FixFigures {
                sigma_h_m: 1.5 / CEP_PER_SIGMA,
                sigma_v_m: 1.5 * 1.5 / CEP_PER_SIGMA,
                tau_s: 300.0,
                white_h_m: 0.05,
                white_v_m: 0.1,
            },
            GnssFix::RtkFloat => FixFigures {
                sigma_h_m: 0.25,
                sigma_v_m: 0.4,
                tau_s: 60.0,
                white_h_m: 0.02,
                white_v_m: 0.04,
            },
            // Data sheet 0.01 m + 1 ppm CEP / R50, taken as 1.4 / 1.5 cm + 1 ppm.
            GnssFix::RtkFixed => {
                let ppm = 1e-6 * baseline_m.max(0.0);
                FixFigures {
                    sigma_h_m: (0.014 + ppm) / CEP_PER_SIGMA,
                    sigma_v_m: (0.015 + ppm) / R50_PER_SIGMA,
                    tau_s: 30.0,
                    white_h_m: 0.003,
                    white_v_m: 0.006,
                }
            }
        }
    }

    /// `GPS_RAW_INT.h_acc`: the horizontal accuracy the receiver reports (u-blox `hAcc`),
    /// the RMS of the horizontal error, mm.
    pub fn h_acc_mm(&self) -> u32 {
        (std::f64::consts::SQRT_2 * self.sigma_h_m * 1e3).round() as u32
    }

    /// `GPS_RAW_INT.v_acc`: the vertical accuracy (u-blox `vAcc`), mm.
    pub fn v_acc_mm(&self) -> u32 {
        (self.sigma_v_m * 1e3).round() as u32
    }
}

/// Box-Muller standard normal sample.
fn gaussian(rng: &mut SmallRng) -> f64 {
    let u1: f64 = rng.random::<f64>().max(1e-12);
    let u2: f64 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// A draw of `sigma_h`, `sigma_h`, `sigma_v` per axis.
fn draw(rng: &mut SmallRng, sigma_h: f64, sigma_v: f64) -> Ned {
    Ned::new(
        sigma_h * gaussian(rng),
        sigma_h * gaussian(rng),
        sigma_v * gaussian(rng),
    )
}

/// The receiver's error process, seeded.
#[derive(Debug, Clone)]
pub(crate) struct ErrorModel {
    /// The slow error's generator (stepped at the physics step, so the same seed and the
    /// same inputs give the same trajectory).
    rng: SmallRng,
    /// The white noise's generator (drawn per reported fix, at the telemetry rate).
    white_rng: SmallRng,
    /// The current state's Gauss-Markov error, NED m.
    slow: Ned,
    /// What is left of the previous states' error, decaying, NED m.
    offset: Ned,
    fix: GnssFix,
    figures: FixFigures,
}

impl ErrorModel {
    /// A receiver with a 3D fix whose error is already a draw of that state's (a
    /// receiver is never exact at boot), from `seed`.
    pub fn new(seed: u64) -> ErrorModel {
        let mut rng = SmallRng::seed_from_u64(seed);
        let white_rng = SmallRng::seed_from_u64(seed ^ 0x0057_4817_E000_0000);
        let figures = FixFigures::of(GnssFix::Fix3d, 0.0);
        let slow = draw(&mut rng, figures.sigma_h_m, figures.sigma_v_m);
        ErrorModel {
            rng,
            white_rng,
            slow,
            offset: Ned::ZERO,
            fix: GnssFix::Fix3d,
            figures,
        }
    }

    /// Advances by `dt_s` in `fix` with a base `baseline_m` away.
    pub fn step(&mut self, dt_s: f64, fix: GnssFix, baseline_m: f64) {
        self.figures = FixFigures::of(fix, baseline_m);
        let f = self.figures;
        if fix != self.fix {
            let error = self.error();
            self.slow = draw(&mut self.rng, f.sigma_h_m, f.sigma_v_m);
            self.offset = error - self.slow;
            self.fix = fix;
        }
        let a = (-dt_s / f.tau_s).exp();
        let s = (1.0 - a * a).sqrt();
        let w = draw(&mut self.rng, f.sigma_h_m * s, f.sigma_v_m * s);
        self.slow = self.slow * a + w;
        self.offset = self.offset * (-dt_s / CONVERGE_TAU_S).exp();
    }

    /// The error of the receiver's position now, NED m.
    pub fn error(&self) -> Ned {
        self.slow + self.offset
    }

    /// The white noise of one reported fix, NED m.
    pub fn white(&mut self) -> Ned {
        let f = self.figures;
        draw(&mut self.white_rng, f.white_h_m, f.white_v_m)
    }
}
