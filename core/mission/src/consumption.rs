//! A vehicle's measured consumption: its battery percent (`BATTERY_STATUS`) and
//! horizontal speed sampled while it flies, cut into windows of [`WINDOW_S`], and the
//! [`EnergyModel`] rates fitted to them by least squares (percent used in a window =
//! hover rate × minutes + cruise rate × metres per second × minutes). A fleet's packs and
//! airframes differ, and age: the plan's energy check uses each vehicle's own rates once
//! it has flown [`MIN_FLOWN_S`] and used [`MIN_USED_PERCENT`], and the model's defaults
//! before.

use crate::energy::EnergyModel;
use std::collections::VecDeque;

/// The length of a measurement window, seconds.
pub const WINDOW_S: f64 = 20.0;
/// Flight before the measured rates replace the model's, seconds.
pub const MIN_FLOWN_S: f64 = 30.0;
/// Battery used before the measured rates replace the model's, percent (the pack reports
/// whole percent).
pub const MIN_USED_PERCENT: f64 = 3.0;
/// A gap between samples longer than this, seconds, ends a window unmeasured.
const MAX_GAP_S: f64 = 5.0;
/// Windows kept (the latest: about an hour and a half of flight).
const MAX_WINDOWS: usize = 256;

/// One window: minutes flown, metres-per-second-minutes flown (the integral of the
/// horizontal speed, over 60), percent used.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Window {
    minutes: f64,
    speed_minutes: f64,
    used_percent: f64,
}

/// The window being measured.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Open {
    start_s: f64,
    start_percent: f64,
    last_s: f64,
    speed_minutes: f64,
}

/// One vehicle's measurements (see the module docs).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ConsumptionFit {
    windows: VecDeque<Window>,
    open: Option<Open>,
}

impl ConsumptionFit {
    /// A sample at `now_s` (any monotonic seconds): battery `percent`, horizontal
    /// `speed_m_s`, and whether the vehicle is `airborne` (on the ground, or without a
    /// battery reading, nothing is measured and the window open is dropped).
    pub fn sample(&mut self, now_s: f64, percent: Option<f64>, speed_m_s: f64, airborne: bool) {
        let Some(percent) = percent.filter(|p| p.is_finite() && airborne) else {
            self.open = None;
            return;
        };
        let Some(open) = self.open.as_mut().filter(|o| now_s - o.last_s <= MAX_GAP_S) else {
            self.open = Some(Open {
                start_s: now_s,
                start_percent: percent,
                last_s: now_s,
                speed_minutes: 0.0,
            });
            return;
        };
        open.speed_minutes += speed_m_s.max(0.0) * (now_s - open.last_s) / 60.0;
        open.last_s = now_s;
        if now_s - open.start_s >= WINDOW_S {
            let w = Window {
                minutes: (now_s - open.start_s) / 60.0,
                speed_minutes: open.speed_minutes,
                used_percent: (open.start_percent - percent).max(0.0),
            };
            if self.windows.len() == MAX_WINDOWS {
                self.windows.pop_front();
            }
            self.windows.push_back(w);
            self.open = Some(Open {
                start_s: now_s,
                start_percent: percent,
                last_s: now_s,
                speed_minutes: 0.0,
            });
        }
    }

    /// Seconds of flight measured.
    pub fn flown_s(&self) -> f64 {
        self.windows.iter().map(|w| w.minutes * 60.0).sum()
    }

    /// The model with this vehicle's measured rates (percent per minute hovering, and per
    /// m/s of cruise), `default`'s cruise speed kept; `None` before [`MIN_FLOWN_S`] and
    /// [`MIN_USED_PERCENT`]. Two rates when the windows flew at different speeds enough
    /// to tell them apart; otherwise `default`'s two rates scaled to what was used.
    pub fn model(&self, default: &EnergyModel) -> Option<EnergyModel> {
        let used: f64 = self.windows.iter().map(|w| w.used_percent).sum();
        if self.flown_s() < MIN_FLOWN_S || used < MIN_USED_PERCENT {
            return None;
        }
        let (h, c) = self
            .least_squares()
            .unwrap_or_else(|| self.scaled(default, used));
        Some(EnergyModel {
            hover_percent_per_min: h,
            cruise_percent_per_min_per_m_s: c,
            ..*default
        })
    }

    /// `(hover, cruise)` rates fitted to the windows, when the speeds flown tell them
    /// apart and both come out non-negative.
    fn least_squares(&self) -> Option<(f64, f64)> {
        let (mut tt, mut ts, mut ss, mut ty, mut sy) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for w in &self.windows {
            let (t, s, y) = (w.minutes, w.speed_minutes, w.used_percent);
            tt += t * t;
            ts += t * s;
            ss += s * s;
            ty += t * y;
            sy += s * y;
        }
        let det = tt * ss - ts * ts;
        // Speeds too alike (all hover, or all one cruise): a near-singular system.
        if det <= 1e-3 * tt * ss {
            return None;
        }
        let h = (ty * ss - sy * ts) / det;
        let c = (tt * sy - ts * ty) / det;
        (h >= 0.0 && c >= 0.0).then_some((h, c))
    }

    /// `default`'s rates scaled so that they predict the `used` percent.
    fn scaled(&self, default: &EnergyModel, used: f64) -> (f64, f64) {
        let predicted: f64 = self
            .windows
            .iter()
            .map(|w| {
                default.hover_percent_per_min * w.minutes
                    + default.cruise_percent_per_min_per_m_s * w.speed_minutes
            })
            .sum();
        let k = used / predicted.max(1e-9);
        (
            k * default.hover_percent_per_min,
            k * default.cruise_percent_per_min_per_m_s,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Flies `fit` for `secs` at `speed_m_s` on a pack using `h + c·v` percent a minute,
    /// reporting whole percent each second from `*t`, `*percent`.
    fn fly(fit: &mut ConsumptionFit, t: &mut f64, percent: &mut f64, secs: u32, speed_m_s: f64) {
        let (h, c) = (6.0, 0.5);
        for _ in 0..secs {
            *t += 1.0;
            *percent -= (h + c * speed_m_s) / 60.0;
            fit.sample(*t, Some(percent.ceil()), speed_m_s, true);
        }
    }

    #[test]
    fn hover_and_cruise_rates_are_measured_from_whole_percent() {
        let (mut fit, mut t, mut percent) = (ConsumptionFit::default(), 0.0, 100.0);
        let default = EnergyModel::default();
        fly(&mut fit, &mut t, &mut percent, 20, 0.0);
        assert_eq!(fit.model(&default), None, "too little flown yet");
        for _ in 0..4 {
            fly(&mut fit, &mut t, &mut percent, 60, 0.0);
            fly(&mut fit, &mut t, &mut percent, 60, 8.0);
        }
        let m = fit.model(&default).unwrap();
        assert!((m.hover_percent_per_min - 6.0).abs() < 0.6, "{m:?}");
        assert!(
            (m.cruise_percent_per_min_per_m_s - 0.5).abs() < 0.1,
            "{m:?}"
        );
        assert_eq!(m.cruise_speed_m_s, default.cruise_speed_m_s);
    }

    #[test]
    fn one_speed_scales_the_default_rates_and_the_ground_measures_nothing() {
        let (mut fit, mut t, mut percent) = (ConsumptionFit::default(), 0.0, 100.0);
        let default = EnergyModel::default();
        fly(&mut fit, &mut t, &mut percent, 180, 0.0);
        let m = fit.model(&default).unwrap();
        // 6 %/min measured hovering against the default 4: every rate × 1.5.
        assert!((m.hover_percent_per_min - 6.0).abs() < 0.5, "{m:?}");
        let k = m.hover_percent_per_min / default.hover_percent_per_min;
        let c = default.cruise_percent_per_min_per_m_s * k;
        assert!((m.cruise_percent_per_min_per_m_s - c).abs() < 1e-9);
        // Landed: samples count for nothing.
        let flown = fit.flown_s();
        for s in 0..100 {
            fit.sample(t + f64::from(s), Some(10.0), 0.0, false);
        }
        assert_eq!(fit.flown_s(), flown);
    }
}
