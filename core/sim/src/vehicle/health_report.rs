//! PX4's health and arming check report (`HealthAndArmingChecks`, `Common.cpp`
//! `Report::report`), as events: `commander_arming_check_summary` (chunk 0, the error
//! and warning components, the mode groups that can arm and run), one event per failing
//! check (its affected modes and health component index first), then
//! `commander_health_summary` (components present, in error, in warning).
//!
//! The simulator's checks, each as PX4 reports it:
//! - `COM_ARM_ODID` 1 or 2 without an Open Drone ID system (the simulator has none):
//!   `check_open_drone_id_missing`, error, component `open_drone_id`; with 2 it prevents
//!   arming in every mode, with 1 it is shown for every mode but prevents nothing;
//! - no global position (before `ekf_fix_delay_s`): `check_modes_global_pos`, error,
//!   every mode (the simulator arms in no mode without a position);
//! - no home: `check_modes_home_position`, info, RTL.
//!
//! The checks run every [`CHECK_PERIOD`]; PX4 reports when the result changes (at most
//! every [`REPORT_MIN_INTERVAL`]), and at once on an arming attempt and when a ground
//! station connects.

use super::*;
use crate::px4_events::{self as ev, all_mode_groups, health_component as hc};
use events::args;

/// Shortest interval between two reports of a changed result.
pub const REPORT_MIN_INTERVAL: Duration = Duration::from_millis(500);
/// How often the checks run (PX4's commander runs them at about 10 Hz too).
pub const CHECK_PERIOD: Duration = Duration::from_millis(100);

/// One failing check.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct FailedCheck {
    def: &'static ev::EventDef,
    /// Modes it is reported for.
    modes: u32,
    /// Modes it prevents arming in.
    prevents: u32,
    component: u8,
}

/// A report: the checks that fail, and what follows from them.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct HealthReport {
    checks: Vec<FailedCheck>,
}

impl HealthReport {
    fn can_arm(&self) -> u32 {
        self.checks
            .iter()
            .fold(all_mode_groups(), |m, c| m & !c.prevents)
    }

    fn components(&self, level_max: u8) -> u32 {
        self.checks
            .iter()
            .filter(|c| c.def.level <= level_max)
            .fold(0, |m, c| m | (1 << c.component))
    }
}

/// What the last report said, and when.
#[derive(Debug, Default)]
pub(crate) struct HealthReporter {
    last: Option<HealthReport>,
    sent_at: Option<Instant>,
    checked_at: Option<Instant>,
}

impl Vehicle {
    fn evaluate_checks(&self, now: Instant) -> HealthReport {
        let all = all_mode_groups();
        let mut checks = Vec::new();
        let odid = self.params.get(Param::COM_ARM_ODID) as i32;
        if odid > 0 {
            checks.push(FailedCheck {
                def: &ev::CHECK_OPEN_DRONE_ID_MISSING,
                modes: all,
                prevents: if odid == 2 { all } else { 0 },
                component: hc::OPEN_DRONE_ID,
            });
        }
        if !self.ekf_ok(now) {
            checks.push(FailedCheck {
                def: &ev::CHECK_MODES_GLOBAL_POS,
                modes: all,
                prevents: all,
                component: hc::GLOBAL_POSITION_ESTIMATE,
            });
        }
        if !self.has_fix {
            let rtl = 1 << 5;
            checks.push(FailedCheck {
                def: &ev::CHECK_MODES_HOME_POSITION,
                modes: rtl,
                prevents: rtl,
                component: hc::SYSTEM,
            });
        }
        HealthReport { checks }
    }

    /// The report's events now.
    fn send_health_report(&mut self, now: Instant, report: &HealthReport, out: &mut Outbox) {
        let error = report.components(ev::level::ERROR);
        let warning = report.components(4) & !error;
        let can_arm = report.can_arm();
        let summary = args(&[
            &[0],
            &error.to_le_bytes(),
            &warning.to_le_bytes(),
            &can_arm.to_le_bytes(),
            &can_arm.to_le_bytes(),
        ]);
        self.send_event(now, &ev::ARMING_CHECK_SUMMARY, summary, out);
        for c in &report.checks {
            let a = args(&[&c.modes.to_le_bytes(), &[c.component]]);
            self.send_event(now, c.def, a, out);
        }
        let present: u32 = [
            hc::GPS,
            hc::ABSOLUTE_PRESSURE,
            hc::ACCEL,
            hc::GYRO,
            hc::MAGNETOMETER,
            hc::BATTERY,
        ]
        .iter()
        .fold(0, |m, i| m | (1 << i));
        let health = args(&[
            &[0],
            &present.to_le_bytes(),
            &0u32.to_le_bytes(),
            &0u32.to_le_bytes(),
        ]);
        self.send_event(now, &ev::HEALTH_SUMMARY, health, out);
        self.health.last = Some(report.clone());
        self.health.sent_at = Some(now);
    }

    /// Every step: a report when the result changed and the last is old enough.
    pub(crate) fn health_tick(&mut self, now: Instant, out: &mut Outbox) {
        if self
            .health
            .checked_at
            .is_some_and(|t| now.saturating_duration_since(t) < CHECK_PERIOD)
        {
            return;
        }
        self.health.checked_at = Some(now);
        let report = self.evaluate_checks(now);
        if self.health.last.as_ref() == Some(&report) {
            return;
        }
        let recent = self
            .health
            .sent_at
            .is_some_and(|t| now.saturating_duration_since(t) < REPORT_MIN_INTERVAL);
        if !recent {
            self.send_health_report(now, &report, out);
        }
    }

    /// A report now, whatever the last said (an arming attempt, a ground station).
    pub(crate) fn force_health_report(&mut self, now: Instant, out: &mut Outbox) {
        let report = self.evaluate_checks(now);
        self.send_health_report(now, &report, out);
    }
}
