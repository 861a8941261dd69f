//! The health and arming check report from a sequence of decoded events, as libevents'
//! `HealthAndArmingChecks::handleEvent` assembles it: an `arming_check` event of type
//! `summary` opens a report (chunk index, error and warning components, the mode groups
//! that can arm, and can run: PX4 v1.14+ sends both, older PX4 one `can_arm_and_run`),
//! each event of group `arming_check` or `health` without a type is a check (its first
//! argument the mode groups it affects, its second the health component's index), and
//! the `health` summary (same chunk index) closes it. An event out of that order starts
//! over.
//!
//! Whether a check prevents arming is worked out for the vehicle's current mode: the
//! mode's group (the metadata's `navigation_mode_groups`, by `custom_mode`) is among the
//! check's modes and cannot arm.

use super::decode::DecodedEvent;
use skein_model::vehicle::Px4ArmingCheck;
use std::collections::HashMap;
use std::sync::Arc;

/// One check of a report.
#[derive(Debug, Clone, PartialEq)]
pub struct Check {
    /// The message (`"Open Drone ID system missing"`).
    pub message: String,
    /// The description.
    pub description: String,
    /// External log level.
    pub log_level: u8,
    /// Mode groups it affects (bit = group).
    pub modes: u64,
    /// Index of its health component (0 none).
    pub component_index: u8,
}

/// A complete report.
#[derive(Debug, Clone, PartialEq)]
pub struct ArmingReport {
    /// The checks, in the order sent.
    pub checks: Vec<Check>,
    /// Mode groups that can arm.
    pub can_arm: u64,
    /// Mode groups that can run (armed).
    pub can_run: u64,
    /// Group of each `custom_mode`, from the metadata.
    pub mode_groups: Arc<HashMap<u32, u8>>,
}

/// libevents' log level names, by level.
pub fn severity_name(level: u8) -> &'static str {
    match level {
        0 => "emergency",
        1 => "alert",
        2 => "critical",
        3 => "error",
        4 => "warning",
        5 => "notice",
        6 => "info",
        7 => "debug",
        _ => "protocol",
    }
}

impl ArmingReport {
    /// The checks as the vehicle's snapshot shows them while in `custom_mode` (`None`:
    /// mode not known, a check prevents arming where it affects a group that cannot).
    pub fn checks_for(&self, custom_mode: Option<u32>) -> Vec<Px4ArmingCheck> {
        let group = custom_mode.and_then(|m| self.mode_groups.get(&m).copied());
        self.checks
            .iter()
            .map(|c| {
                let prevents = match group {
                    Some(g) => c.modes & (1 << g) != 0 && self.can_arm & (1 << g) == 0,
                    None => c.modes & !self.can_arm != 0,
                };
                Px4ArmingCheck {
                    message: c.message.clone(),
                    description: c.description.clone(),
                    severity: severity_name(c.log_level).to_string(),
                    prevents_arming: prevents,
                }
            })
            .collect()
    }
}

/// Assembles reports from events (see the module docs).
#[derive(Debug, Default)]
pub struct HealthReportBuilder {
    open: Option<(u64, ArmingReport)>,
}

impl HealthReportBuilder {
    /// One decoded event, in sequence order; a report once one completes. Events of
    /// other groups are none of its business.
    pub fn on_event(
        &mut self,
        e: &DecodedEvent,
        mode_groups: &Arc<HashMap<u32, u8>>,
    ) -> Option<ArmingReport> {
        let arg = |i: usize| e.args.get(i).map_or(0, |a| a.as_u64());
        match (e.group.as_str(), e.kind.as_str()) {
            ("arming_check", "summary") => {
                let (can_arm, can_run) = if e.args.len() >= 5 {
                    (arg(3), arg(4))
                } else {
                    (arg(3), arg(3))
                };
                self.open = Some((
                    arg(0),
                    ArmingReport {
                        checks: Vec::new(),
                        can_arm,
                        can_run,
                        mode_groups: mode_groups.clone(),
                    },
                ));
                None
            }
            ("health", "summary") => {
                let (chunk, report) = self.open.take()?;
                (chunk == arg(0)).then_some(report)
            }
            ("arming_check" | "health", "") => {
                let Some((_, report)) = self.open.as_mut() else {
                    return None; // a check outside a report: wait for the next summary
                };
                report.checks.push(Check {
                    message: e.message.clone(),
                    description: e.description.clone(),
                    log_level: e.log_level,
                    modes: arg(0),
                    component_index: arg(1) as u8,
                });
                None
            }
            _ => None,
        }
    }
}
