//! The receiver's fix state, driven by the RTK corrections: a 3D fix without them, RTK
//! float once corrections with a base position have streamed for a while, RTK fixed once
//! the ambiguities are resolved, back to float when the corrections stop, to 3D when
//! they are too old to use. Timed on the simulator's clock (`now`), like PX4's other
//! timers.
//!
//! Where the numbers come from (u-blox ZED-F9P, PX4 with an F9P): float within a few
//! seconds of the first corrections with a base position, fixed after 10–30 s in the open
//! (the F9P data sheet says RTK convergence < 10 s; field logs behind PX4 show 10–30 s):
//! defaults 5 s and a further 15 s. The F9P holds its fixed ambiguities only for a few
//! seconds of missing corrections (5 s) and keeps using corrections up to
//! `CFG-NAVSPG-CONSTR_DGNSSTO`, 60 s by default, before it falls back to a plain 3D fix.

use serde::{Deserialize, Serialize};
use skein_mavlink::dialect::GpsFixType;
use std::time::{Duration, Instant};

/// A base farther than this from the vehicle is not used: single-base RTK does not
/// resolve its ambiguities that far out (u-blox quote RTK figures for baselines of
/// 10–20 km, accuracy 1 ppm of the baseline), m.
pub const RTK_MAX_BASELINE_M: f64 = 50_000.0;
/// A base position moved by more than this is a new base: the RTK solution starts over, m.
const BASE_MOVED_M: f64 = 1.0;

/// The receiver's RTK timing (`SimConfig::rtk`), seconds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct RtkTiming {
    /// Corrections with a base position streaming this long give RTK float (u-blox F9P:
    /// a few seconds), s.
    pub rtk_float_after_s: f64,
    /// Then this much longer in float gives RTK fixed (F9P data sheet < 10 s in the open,
    /// 10–30 s in the field), s.
    pub rtk_fixed_after_s: f64,
    /// Fixed falls back to float when the corrections are older than this, s.
    pub rtk_hold_s: f64,
    /// Float falls back to a 3D fix when the corrections are older than this (u-blox
    /// `CFG-NAVSPG-CONSTR_DGNSSTO`, 60 s by default), s.
    pub dgnss_timeout_s: f64,
}

impl Default for RtkTiming {
    fn default() -> Self {
        RtkTiming {
            rtk_float_after_s: 5.0,
            rtk_fixed_after_s: 15.0,
            rtk_hold_s: 5.0,
            dgnss_timeout_s: 60.0,
        }
    }
}

/// The receiver's fix (once it has one: before the EKF's first fix the vehicle reports
/// `GPS_FIX_TYPE_NO_FIX` whatever this is).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum GnssFix {
    /// A plain 3D fix: metres of slow wander.
    Fix3d,
    /// RTK float: decimetres.
    RtkFloat,
    /// RTK fixed: centimetres.
    RtkFixed,
}

impl GnssFix {
    /// `GPS_RAW_INT.fix_type` of this fix.
    pub fn fix_type(self) -> GpsFixType {
        match self {
            GnssFix::Fix3d => GpsFixType::GPS_FIX_TYPE_3D_FIX,
            GnssFix::RtkFloat => GpsFixType::GPS_FIX_TYPE_RTK_FLOAT,
            GnssFix::RtkFixed => GpsFixType::GPS_FIX_TYPE_RTK_FIXED,
        }
    }
}

/// The base station the receiver knows.
#[derive(Debug, Clone, Copy)]
struct Base {
    ecef_m: [f64; 3],
    /// When this base was first heard.
    since: Instant,
    /// Distance from the vehicle's spawn point, m.
    baseline_m: f64,
}

/// The fix state machine of one receiver.
#[derive(Debug, Clone)]
pub(crate) struct RtkState {
    timing: RtkTiming,
    /// The receiver's antenna at the vehicle's spawn point, ECEF m (for the baseline).
    antenna_ecef_m: [f64; 3],
    base: Option<Base>,
    /// Last good observation frame.
    last_observation: Option<Instant>,
    /// Start of the current unbroken stream of observations.
    stream_start: Option<Instant>,
    fix: GnssFix,
}

fn secs(s: f64) -> Duration {
    Duration::from_secs_f64(s.max(0.0))
}

impl RtkState {
    /// A receiver with a 3D fix and no corrections, its antenna at `antenna_ecef_m`.
    pub fn new(timing: RtkTiming, antenna_ecef_m: [f64; 3]) -> RtkState {
        RtkState {
            timing,
            antenna_ecef_m,
            base: None,
            last_observation: None,
            stream_start: None,
            fix: GnssFix::Fix3d,
        }
    }

    /// A good observation frame at `now`; a stream broken for longer than `rtk_hold_s`
    /// starts over.
    pub fn on_observations(&mut self, now: Instant) {
        let broken = self
            .last_observation
            .is_none_or(|t| now.saturating_duration_since(t) > secs(self.timing.rtk_hold_s));
        if broken {
            self.stream_start = Some(now);
        }
        self.last_observation = Some(now);
    }

    /// A base position (1005/1006) at `now`, ECEF m; a new base starts RTK over.
    pub fn on_base(&mut self, now: Instant, ecef_m: [f64; 3]) {
        let moved = self
            .base
            .is_none_or(|b| distance(b.ecef_m, ecef_m) > BASE_MOVED_M);
        if moved {
            self.base = Some(Base {
                ecef_m,
                since: now,
                baseline_m: distance(self.antenna_ecef_m, ecef_m),
            });
        }
    }

    /// Age of the corrections at `now` (time since the last good observation frame).
    pub fn age(&self, now: Instant) -> Option<Duration> {
        self.last_observation
            .map(|t| now.saturating_duration_since(t))
    }

    /// Distance to the base in use, m (`None` without one).
    pub fn baseline_m(&self) -> Option<f64> {
        self.base.map(|b| b.baseline_m)
    }

    /// The fix now.
    pub fn fix(&self) -> GnssFix {
        self.fix
    }

    /// Updates the fix at `now` and returns it.
    pub fn update(&mut self, now: Instant) -> GnssFix {
        let t = self.timing;
        let base = self.base.filter(|b| b.baseline_m <= RTK_MAX_BASELINE_M);
        let (Some(age), Some(base), Some(stream)) = (self.age(now), base, self.stream_start) else {
            self.fix = GnssFix::Fix3d;
            return self.fix;
        };
        let fresh = age <= secs(t.rtk_hold_s);
        let rtk_for = now.saturating_duration_since(stream.max(base.since));
        // Float: corrections long enough, or older ones still used after a float or fix.
        let float = (fresh && rtk_for >= secs(t.rtk_float_after_s))
            || (self.fix != GnssFix::Fix3d && age <= secs(t.dgnss_timeout_s));
        self.fix = if fresh && rtk_for >= secs(t.rtk_float_after_s + t.rtk_fixed_after_s) {
            GnssFix::RtkFixed
        } else if float {
            GnssFix::RtkFloat
        } else {
            GnssFix::Fix3d
        };
        self.fix
    }
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}
