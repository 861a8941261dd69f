//! The low-battery reaction ([`crate::plan::LowBattery`]): during a step whose vehicles
//! fly their own routes (survey, patrol, station, transit without a formation), a
//! vehicle below the threshold is replaced by the first idle reserve. The reserve takes
//! off to the step's altitude while the low vehicle carries on; once the reserve is up,
//! it takes the low vehicle's route from where that one was and the low vehicle returns
//! to launch. Without a reserve left, the low vehicle returns at once and its survey
//! lanes go to the others.

use super::step::Active;
use super::{Action, Tick, VehicleView};
use crate::plan::LowBattery;
use serde::{Deserialize, Serialize};
use skein_model::command::{Command, Takeoff};
use skein_model::fsm::VehicleState;
use std::collections::BTreeSet;
use utoipa::ToSchema;

/// A reserve within this of the step's altitude, metres, is up.
const UP_TOLERANCE_M: f64 = 1.5;

/// Something the run did by itself.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Reaction {
    /// Mission seconds when it happened.
    pub at_s: f64,
    /// `low_battery` (a reserve sent for a vehicle, or a vehicle sent home), or
    /// `intruder` (observers sent to a track, or back to the step).
    #[serde(deserialize_with = "super::takeover::reaction_kind")]
    #[schema(value_type = String)]
    pub kind: super::takeover::Name,
    /// The vehicles it concerns (the low one first).
    pub vehicles: Vec<String>,
    /// What happened, in words.
    pub detail: String,
    /// A reserve that took a vehicle's route, once it reached that route's next point:
    /// seconds the route went unflown, from the low vehicle's leaving (the gap in a
    /// persistent patrol's coverage); `null` for every other reaction.
    #[serde(default)]
    pub gap_s: Option<f64>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
struct Swap {
    low: String,
    reserve: String,
    /// The altitude the reserve was sent up to (its step's): it is up there, whatever
    /// step flies when it gets there.
    altitude_m: f64,
}

/// A reserve on its way to the route it took, since mission second `left_at_s` (when
/// the low vehicle left it).
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Joining {
    swap: Swap,
    left_at_s: f64,
}

/// The reaction's state through the mission.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(super) struct Swaps {
    rule: LowBattery,
    /// Reserves sent (each flies once).
    used: BTreeSet<String>,
    /// Vehicles already replaced or sent home.
    handled: BTreeSet<String>,
    pending: Vec<Swap>,
    /// Sent home with no reserve to take their place, since the last tick.
    retired: Vec<String>,
    /// Reserves that took a route and have not reached its next point yet.
    joining: Vec<Joining>,
}

impl Swaps {
    pub(super) fn new(rule: LowBattery) -> Self {
        Swaps {
            rule,
            used: BTreeSet::new(),
            handled: BTreeSet::new(),
            pending: Vec::new(),
            retired: Vec::new(),
            joining: Vec::new(),
        }
    }

    /// One tick of the step `active` flown by `vehicles`: what to command, what happened,
    /// and the places reserves took this tick, as `(low, reserve)` (the reserve flies the
    /// rest of the mission in the low vehicle's place).
    pub(super) fn tick(
        &mut self,
        active: &mut Active,
        vehicles: &[String],
        tick: &Tick,
        out: &mut Vec<Action>,
        happened: &mut Vec<Reaction>,
    ) -> Vec<(String, String)> {
        let mut took = Vec::new();
        let Some(altitude_m) = active.route_altitude_m() else {
            return took;
        };
        self.retired.clear();
        self.notice_joined(active, tick, happened);
        self.notice_low(active, vehicles, tick, altitude_m, out, happened);
        let mut still = Vec::new();
        for swap in std::mem::take(&mut self.pending) {
            let reserve = tick.vehicles.get(&swap.reserve);
            if reserve.is_some_and(|v| up(v, swap.altitude_m)) {
                active.replace(&swap.low, &swap.reserve);
                took.push((swap.low.clone(), swap.reserve.clone()));
                home(&swap.low, out);
                self.joining.push(Joining {
                    swap: swap.clone(),
                    left_at_s: tick.now_s,
                });
                happened.push(Reaction {
                    gap_s: None,
                    at_s: tick.now_s,
                    kind: "low_battery",
                    vehicles: vec![swap.low.clone(), swap.reserve.clone()],
                    detail: format!(
                        "{} took over from {}, which returns",
                        swap.reserve, swap.low
                    ),
                });
            } else if reserve.is_none_or(gone) {
                active.release(&swap.low, tick);
                home(&swap.low, out);
                self.retired.push(swap.low.clone());
            } else {
                still.push(swap);
            }
        }
        self.pending = still;
        took
    }

    /// Reserves that reached the next point of the route they took: the gap, measured.
    /// One whose route is not in this step (the step ended first) is not waited for.
    fn notice_joined(&mut self, active: &Active, tick: &Tick, happened: &mut Vec<Reaction>) {
        self.joining.retain(|j| {
            let Some(reached) = active.reached(&j.swap.reserve) else {
                return false;
            };
            if reached == 0 {
                return true;
            }
            let gap_s = tick.now_s - j.left_at_s;
            happened.push(Reaction {
                gap_s: Some(gap_s),
                at_s: tick.now_s,
                kind: "low_battery",
                vehicles: vec![j.swap.reserve.clone(), j.swap.low.clone()],
                detail: format!(
                    "{} on the route of {} {gap_s:.1} s after it left",
                    j.swap.reserve, j.swap.low
                ),
            });
            false
        });
    }

    fn notice_low(
        &mut self,
        active: &mut Active,
        vehicles: &[String],
        tick: &Tick,
        altitude_m: f64,
        out: &mut Vec<Action>,
        happened: &mut Vec<Reaction>,
    ) {
        for id in vehicles {
            let Some(v) = tick.vehicles.get(id) else {
                continue;
            };
            let low = v
                .battery_percent
                .is_some_and(|b| b < self.rule.below_percent);
            if !low || self.handled.contains(id) || gone(v) {
                continue;
            }
            self.handled.insert(id.clone());
            let battery = v.battery_percent.unwrap_or(0.0);
            let reserve = self.rule.reserves.iter().find(|r| {
                !self.used.contains(*r)
                    && tick
                        .vehicles
                        .get(*r)
                        .is_some_and(|v| v.state == VehicleState::Landed)
            });
            let Some(reserve) = reserve.cloned() else {
                active.release(id, tick);
                home(id, out);
                self.retired.push(id.clone());
                happened.push(Reaction {
                    gap_s: None,
                    at_s: tick.now_s,
                    kind: "low_battery",
                    vehicles: vec![id.clone()],
                    detail: format!("{id} at {battery:.0} %: no reserve left, it returns"),
                });
                continue;
            };
            self.used.insert(reserve.clone());
            out.push(Action::Command {
                vehicle: reserve.clone(),
                command: Command::Takeoff(Takeoff {
                    altitude_m: Some(altitude_m),
                }),
            });
            happened.push(Reaction {
                gap_s: None,
                at_s: tick.now_s,
                kind: "low_battery",
                vehicles: vec![id.clone(), reserve.clone()],
                detail: format!(
                    "{id} at {battery:.0} % (below {:.0} %): {reserve} takes off to replace it",
                    self.rule.below_percent
                ),
            });
            self.pending.push(Swap {
                low: id.clone(),
                reserve,
                altitude_m,
            });
        }
    }
}

impl Swaps {
    /// The vehicles the last tick sent home with no reserve in their place: they fly no
    /// later step.
    pub(super) fn retired(&self) -> &[String] {
        &self.retired
    }
}

fn up(v: &VehicleView, altitude_m: f64) -> bool {
    matches!(v.state, VehicleState::Hovering | VehicleState::GoTo)
        && v.relative_alt_m
            .is_some_and(|h| (h - altitude_m).abs() < UP_TOLERANCE_M)
}

fn gone(v: &VehicleView) -> bool {
    matches!(
        v.state,
        VehicleState::Lost | VehicleState::Disconnected | VehicleState::Failsafe
    )
}

fn home(id: &str, out: &mut Vec<Action>) {
    out.push(Action::Command {
        vehicle: id.to_string(),
        command: Command::Rtl,
    });
}
