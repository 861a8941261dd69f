//! The simulated GNSS receiver, a u-blox F9P-like RTK receiver behind PX4 v1.16's GPS
//! driver: the RTK corrections in ([`rtcm`]: `GPS_RTCM_DATA` → uORB `gps_inject_data` →
//! the receiver's RTCM3 framer), the fix they drive ([`fix`]), the position error of each
//! fix ([`error`], with `--gnss-wander`) and the EKF's copy of it, which the estimate and
//! so the controller carry.

mod error;
mod fix;
mod rtcm;
#[cfg(test)]
mod tests;

pub use error::{CONVERGE_TAU_S, FixFigures};
pub use fix::{GnssFix, RTK_MAX_BASELINE_M, RtkTiming};
pub use rtcm::{GPS_DRIVER_CYCLE, GPS_RTCM_DATA_LEN, INJECT_QUEUE_LENGTH, RtcmCounts};

use serde::Serialize;
use skein_mavlink::dialect::GPS_RTCM_DATA_DATA;
use skein_model::geo::Ned;
use std::time::{Duration, Instant};

/// Time constant of PX4 EKF2's position estimate following a change of the GNSS
/// position (GNSS fused at 5–10 Hz with `EKF2_GPS_P_NOISE` 0.5 m, `EKF2_GPS_DELAY`
/// 110 ms; `EKF2_HGT_REF` GNSS by default, so the height follows too), s.
pub const EKF_GNSS_LAG_S: f64 = 1.0;

/// The receiver's state in the ground truth (`SimTruth::gnss`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GnssTruth {
    /// `GPS_RAW_INT.fix_type` now: 1 (no fix, before the EKF's first fix), 3 (3D),
    /// 5 (RTK float) or 6 (RTK fixed).
    pub fix_type: u8,
    /// Seconds since the last good RTCM frame carrying observations; `null` when none
    /// ever came.
    pub corrections_age_s: Option<f64>,
    /// The receiver's position error now (its fix minus the truth), north, east, down,
    /// m; zero without `gnss_wander`.
    pub error_ned_m: [f64; 3],
}

/// One vehicle's receiver.
#[derive(Debug)]
pub(crate) struct Gnss {
    wander: bool,
    inject: rtcm::InjectQueue,
    stream: rtcm::RtcmStream,
    rtk: fix::RtkState,
    error: error::ErrorModel,
    /// The EKF's copy of the receiver's error (lagged), NED m.
    est_error: Ned,
}

impl Gnss {
    /// A receiver with a 3D fix, its antenna at `antenna_ecef_m` (the vehicle's spawn
    /// point), its error process seeded with `seed` and run only when `wander`.
    pub fn new(timing: RtkTiming, wander: bool, antenna_ecef_m: [f64; 3], seed: u64) -> Gnss {
        let error = error::ErrorModel::new(seed);
        // PX4's EKF starts on the receiver's first fix: its copy of the error is whole.
        let est_error = if wander { error.error() } else { Ned::ZERO };
        Gnss {
            wander,
            inject: rtcm::InjectQueue::default(),
            stream: rtcm::RtcmStream::default(),
            rtk: fix::RtkState::new(timing, antenna_ecef_m),
            error,
            est_error,
        }
    }

    /// A `GPS_RTCM_DATA` for the vehicle (it has no target: every vehicle takes it), as
    /// PX4's MAVLink receiver publishes it; one with `len` over 180 is counted and
    /// dropped (PX4 would clip it to 180 and pass on a corrupt chunk).
    pub fn on_rtcm_data(&mut self, msg: &GPS_RTCM_DATA_DATA, counts: &mut RtcmCounts) {
        let len = usize::from(msg.len);
        if len > GPS_RTCM_DATA_LEN {
            counts.gps_rtcm_data_malformed += 1;
            return;
        }
        counts.gps_rtcm_data += 1;
        self.inject.publish(&msg.data[..len], counts);
    }

    /// One simulation step of `dt_s` at `now`: the GPS driver writes what is queued to
    /// the receiver when its cycle is due, the fix follows the corrections, and (with
    /// wander) the error and the EKF's copy of it move on.
    pub fn step(&mut self, now: Instant, dt_s: f64, counts: &mut RtcmCounts) {
        for chunk in self.inject.drain_due(now) {
            for c in self.stream.push(&chunk, counts) {
                match c {
                    rtcm::Correction::Observations => self.rtk.on_observations(now),
                    rtcm::Correction::BasePosition(ecef) => self.rtk.on_base(now, ecef),
                }
            }
        }
        let fix = self.rtk.update(now);
        if self.wander {
            let baseline = self.rtk.baseline_m().unwrap_or(0.0);
            self.error.step(dt_s, fix, baseline);
            let k = 1.0 - (-dt_s / EKF_GNSS_LAG_S).exp();
            self.est_error = self.est_error + (self.error.error() - self.est_error) * k;
        }
    }

    /// The receiver's fix now.
    pub fn fix(&self) -> GnssFix {
        self.rtk.fix()
    }

    /// What the receiver reports of its accuracy in its fix now.
    pub fn figures(&self) -> FixFigures {
        FixFigures::of(self.fix(), self.rtk.baseline_m().unwrap_or(0.0))
    }

    /// Age of the corrections at `now`.
    pub fn corrections_age(&self, now: Instant) -> Option<Duration> {
        self.rtk.age(now)
    }

    /// True when the error model runs (`gnss_wander`).
    pub fn wanders(&self) -> bool {
        self.wander
    }

    /// The receiver's position error now, NED m (zero without wander).
    pub fn error(&self) -> Ned {
        if self.wander {
            self.error.error()
        } else {
            Ned::ZERO
        }
    }

    /// The EKF's copy of the receiver's error (zero without wander), NED m.
    pub fn est_error(&self) -> Ned {
        self.est_error
    }

    /// The receiver's error plus the white noise of one reported fix, NED m (zero
    /// without wander).
    pub fn fix_error(&mut self) -> Ned {
        if self.wander {
            self.error.error() + self.error.white()
        } else {
            Ned::ZERO
        }
    }
}
