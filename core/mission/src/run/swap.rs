//! The low-battery reaction ([`crate::plan::LowBattery`]): during a step whose vehicles
//! fly their own routes (survey, patrol, station, transit without a formation), a
//! vehicle below the threshold is replaced by the first idle reserve. The reserve takes
//! off to the step's altitude while the low vehicle carries on; once the reserve is up,
//! it takes the low vehicle's route from where that one was (on a patrol, from where it
//! met it on the route, [`super::meet`]) and the low vehicle returns to launch; the gap
//! (from the low vehicle's leaving until the reserve reached the route's next point) is
//! measured. Without a reserve left, the low vehicle returns at once and its survey
//! lanes go to the others.

use super::meet::{self, Verdict};
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
    /// Where it meets the low vehicle on a patrol, once up ([`super::meet`]).
    meet: Option<super::meet::Meet>,
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
    /// Vehicles sent home (told to return to launch).
    homing: BTreeSet<String>,
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
            homing: BTreeSet::new(),
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
        for mut swap in std::mem::take(&mut self.pending) {
            let reserve = tick.vehicles.get(&swap.reserve);
            let ready = swap.meet.is_some() || reserve.is_some_and(|v| up(v, swap.altitude_m));
            if ready && meeting(&mut swap, active, tick, out) == Verdict::Wait {
                still.push(swap);
                continue;
            }
            if ready {
                let at = tick.vehicles.get(&swap.low).and_then(|v| v.position);
                active.replace(&swap.low, &swap.reserve, at);
                took.push((swap.low.clone(), swap.reserve.clone()));
                self.send_home(&swap.low, out);
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
                self.send_home(&swap.low, out);
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
                self.send_home(id, out);
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
                meet: None,
            });
        }
    }
}

impl Swaps {
    /// Every vehicle the reaction sent home (replaced, or with no reserve left).
    pub(super) fn sent_home(&self) -> &BTreeSet<String> {
        &self.homing
    }

    fn send_home(&mut self, id: &str, out: &mut Vec<Action>) {
        self.homing.insert(id.to_string());
        out.push(Action::Command {
            vehicle: id.to_string(),
            command: Command::Rtl,
        });
    }

    /// The vehicles the last tick sent home with no reserve in their place: they fly no
    /// later step.
    pub(super) fn retired(&self) -> &[String] {
        &self.retired
    }
}

/// A reserve that is up and the vehicle it replaces: on a patrol, the meeting on its
/// route is planned (the reserve sent there) or checked ([`super::meet`]); elsewhere
/// the handover is at once.
fn meeting(swap: &mut Swap, active: &Active, tick: &Tick, out: &mut Vec<Action>) -> Verdict {
    let Some(route) = active.route(&swap.low).filter(|r| r.is_cyclic()) else {
        return Verdict::HandOver;
    };
    let at = |id: &str| tick.vehicles.get(id).and_then(|v| v.position);
    let (low, reserve) = (at(&swap.low), at(&swap.reserve));
    if let Some(m) = &swap.meet {
        return meet::verdict(m, route, low, reserve);
    }
    let Some(m) = low.zip(reserve).and_then(|(l, r)| meet::plan(route, l, r)) else {
        return Verdict::HandOver;
    };
    out.push(Action::Command {
        vehicle: swap.reserve.clone(),
        command: Command::GoTo(m.point.into()),
    });
    swap.meet = Some(m);
    Verdict::Wait
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
