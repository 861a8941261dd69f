//! The step being flown: what it commands when it starts, on each tick and when paused or
//! resumed, when it is done, and how far along it is.
//!
//! - `takeoff`: each landed vehicle of the group is told to take off, `interval_s` after
//!   the last; done when every one is airborne at its altitude (within 1 m).
//! - `transit` in a formation: the formation is set behind a virtual leader and, once
//!   the formation has its reference point, the leader flies the waypoints; done when
//!   the reference reached the last one; the formation is then cleared.
//! - `transit` without one, `survey`, `station`: each vehicle flies its own points
//!   ([`Route`]): the waypoints offset by its place in the group, its block of lanes, its
//!   station (the points assigned for the least squared distance flown, as formation
//!   slots are; held `duration_s` once all are on theirs).
//! - `patrol`: each vehicle laps the route from its own place on it, spaced evenly, for
//!   `duration_s` once all are on it (or until skipped).
//! - `return` and `land`: each vehicle told in turn; done when all are down.
//!
//! A vehicle that drops out (lost, failsafe, disconnected) is not waited for; its
//! unflown survey lanes go to the vehicle with the fewest left (a lane it was in the
//! middle of is flown again whole).

use super::route::{ARRIVED_M, Route};
use super::{Action, Tick, VehicleView};
use crate::lanes;
use crate::plan::{Point, StepKind};
use skein_formation::{FormationFrame, FormationSpec, LeaderMotion, VIRTUAL};
use skein_model::command::{Command, Takeoff};
use skein_model::fsm::VehicleState;
use skein_model::geo::Ned;
use std::collections::{BTreeMap, BTreeSet};

/// A vehicle within this of its takeoff altitude, metres, has taken off.
pub const TAKEOFF_TOLERANCE_M: f64 = 1.0;

/// How far along a step is.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize, utoipa::ToSchema)]
pub struct StepProgress {
    /// Done so far, 0 to 1 (a patrol without a duration stays at 0).
    pub fraction: f64,
    /// Survey lanes flown, and of how many (other steps: `null`).
    pub lanes_done: Option<usize>,
    /// Survey lanes in all.
    pub lanes_total: Option<usize>,
    /// What the step is doing, in words.
    pub detail: String,
}

/// Per-vehicle routes, and what kind of step flies them.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(super) enum Routes {
    Once,
    Survey {
        lanes: usize,
    },
    Station {
        duration_s: f64,
        since: Option<f64>,
    },
    Patrol {
        duration_s: Option<f64>,
        since: Option<f64>,
    },
}

/// The step being flown (see the module docs).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(super) enum Active {
    InTurn {
        ids: Vec<String>,
        command: Command,
        interval_s: f64,
        issued: usize,
        next_at: f64,
        /// Takeoff only: the altitude to reach.
        altitude_m: Option<f64>,
    },
    Formation {
        points: Vec<Ned>,
        next: usize,
        speed_m_s: f64,
        /// The leader was told to fly the waypoints (once the formation has a reference:
        /// the engine refuses a motion before).
        flying: bool,
    },
    Routes {
        routes: BTreeMap<String, Route>,
        kind: Routes,
        /// Vehicles sent away (home) during the step: no longer flown or waited for; their
        /// routes stay for the count of what they flew.
        released: BTreeSet<String>,
        /// Vehicles observing an intruder: their routes wait where they left them (the
        /// step waits for them too).
        observing: BTreeSet<String>,
    },
}

/// A vehicle that can fly a route now.
pub(super) fn flying(v: &VehicleView) -> bool {
    matches!(
        v.state,
        VehicleState::Hovering | VehicleState::InFormation | VehicleState::GoTo
    )
}

/// A vehicle out of the step: nothing more can be asked of it.
fn gone(v: Option<&VehicleView>) -> bool {
    v.is_none_or(|v| {
        matches!(
            v.state,
            VehicleState::Lost | VehicleState::Disconnected | VehicleState::Failsafe
        )
    })
}

fn ned(p: Point, altitude_m: f64) -> Ned {
    Ned::new(p[0], p[1], -altitude_m)
}

impl Active {
    /// Starts `kind` for vehicles `ids` at `tick`; what to command at once.
    pub(super) fn start(kind: &StepKind, ids: &[String], tick: &Tick) -> (Active, Vec<Action>) {
        let mut out = Vec::new();
        let in_turn = |command, interval_s, altitude_m| Active::InTurn {
            ids: ids.to_vec(),
            command,
            interval_s,
            issued: 0,
            next_at: tick.now_s,
            altitude_m,
        };
        let active = match kind {
            StepKind::Takeoff(t) => in_turn(
                Command::Takeoff(Takeoff {
                    altitude_m: Some(t.altitude_m),
                }),
                t.interval_s,
                Some(t.altitude_m),
            ),
            StepKind::Return(t) => in_turn(Command::Rtl, t.interval_s, None),
            StepKind::Land(t) => in_turn(Command::Land, t.interval_s, None),
            StepKind::Transit(t) => {
                let points: Vec<Ned> = t.waypoints.iter().map(|p| ned(*p, t.altitude_m)).collect();
                match &t.formation {
                    Some(f) => {
                        out.push(Action::SetFormation(FormationSpec {
                            shape: f.shape,
                            spacing_m: f.spacing_m,
                            leader: Some(VIRTUAL.into()),
                            heading_deg: heading_deg(centre(ids, tick), points[0]),
                            altitude_m: Some(t.altitude_m),
                            frame: FormationFrame::Leader,
                            offsets: vec![],
                            standoff_m: None,
                        }));
                        Active::Formation {
                            points,
                            next: 0,
                            speed_m_s: t.speed_m_s,
                            flying: false,
                        }
                    }
                    None => Active::Routes {
                        routes: offset_routes(ids, tick, &points),
                        kind: Routes::Once,
                        released: BTreeSet::new(),
                        observing: BTreeSet::new(),
                    },
                }
            }
            StepKind::Survey(s) => {
                let spacing = s
                    .lane_spacing_m
                    .or(s.camera.map(|c| c.lane_spacing_m(s.altitude_m)))
                    .unwrap_or(f64::INFINITY);
                let all = lanes::lanes(&s.polygon, spacing);
                let blocks = lanes::split(&all, ids.len());
                let from: Vec<Point> = ids
                    .iter()
                    .map(|id| {
                        tick.vehicles
                            .get(id)
                            .and_then(|v| v.position)
                            .map_or([0.0, 0.0], |p| [p.north_m, p.east_m])
                    })
                    .collect();
                let routes = ids
                    .iter()
                    .zip(lanes::sweep(&blocks, &from))
                    .map(|(id, way)| {
                        let pts = way.into_iter().map(|p| ned(p, s.altitude_m)).collect();
                        (id.clone(), Route::lanes(pts))
                    })
                    .collect();
                Active::Routes {
                    routes,
                    kind: Routes::Survey { lanes: all.len() },
                    released: BTreeSet::new(),
                    observing: BTreeSet::new(),
                }
            }
            StepKind::Station(s) => Active::Routes {
                routes: ids
                    .iter()
                    .zip(stations(&s.points, s.altitude_m, ids, tick))
                    .map(|(id, p)| (id.clone(), Route::station(p)))
                    .collect(),
                kind: Routes::Station {
                    duration_s: s.duration_s,
                    since: None,
                },
                released: BTreeSet::new(),
                observing: BTreeSet::new(),
            },
            StepKind::Patrol(p) => {
                let pts: Vec<Ned> = p.route.iter().map(|q| ned(*q, p.altitude_m)).collect();
                Active::Routes {
                    routes: ids
                        .iter()
                        .enumerate()
                        .map(|(i, id)| {
                            let first = i * pts.len() / ids.len().max(1);
                            (id.clone(), Route::starting_at(pts.clone(), first))
                        })
                        .collect(),
                    kind: Routes::Patrol {
                        duration_s: p.duration_s,
                        since: None,
                    },
                    released: BTreeSet::new(),
                    observing: BTreeSet::new(),
                }
            }
        };
        (active, out)
    }

    /// One tick: what to command; true once the step is done.
    pub(super) fn tick(&mut self, tick: &Tick, out: &mut Vec<Action>) -> bool {
        match self {
            Active::InTurn { .. } => self.tick_in_turn(tick, out),
            Active::Formation {
                points,
                next,
                speed_m_s,
                flying,
            } => {
                let Some(r) = tick.reference else {
                    return false;
                };
                if !*flying {
                    *flying = true;
                    out.push(Action::LeaderMotion(LeaderMotion::Waypoints {
                        points: points.clone(),
                        speed_m_s: *speed_m_s,
                        next: 0,
                        repeat: false,
                    }));
                    return false;
                }
                while *next < points.len()
                    && (r - points[*next]).horizontal_norm() < 2.0 * ARRIVED_M
                {
                    *next += 1;
                }
                *next >= points.len()
            }
            Active::Routes {
                routes,
                kind,
                released,
                observing,
            } => tick_routes(routes, kind, released, observing, tick, out),
        }
    }

    fn tick_in_turn(&mut self, tick: &Tick, out: &mut Vec<Action>) -> bool {
        let Active::InTurn {
            ids,
            command,
            interval_s,
            issued,
            next_at,
            altitude_m,
        } = self
        else {
            return false;
        };
        while *issued < ids.len() && tick.now_s >= *next_at {
            let id = &ids[*issued];
            *issued += 1;
            if gone(tick.vehicles.get(id)) {
                continue;
            }
            out.push(Action::Command {
                vehicle: id.clone(),
                command: command.clone(),
            });
            *next_at = tick.now_s + *interval_s;
        }
        *issued == ids.len()
            && ids.iter().all(|id| {
                let v = tick.vehicles.get(id);
                gone(v) || v.is_some_and(|v| finished_in_turn(v, *altitude_m))
            })
    }

    /// Commands to hold every vehicle of the step (a pause).
    pub(super) fn hold(&self, ids: &[String], out: &mut Vec<Action>) {
        if let Active::Formation { .. } = self {
            out.push(Action::LeaderMotion(LeaderMotion::Hold));
            return;
        }
        let observing = match self {
            Active::Routes { observing, .. } => Some(observing),
            _ => None,
        };
        // Observers keep their watch (the swarm's observation flies them).
        for id in ids
            .iter()
            .filter(|id| observing.is_none_or(|o| !o.contains(*id)))
        {
            out.push(Action::Command {
                vehicle: id.clone(),
                command: Command::Hold,
            });
        }
    }

    /// The step's vehicles fly their own routes (survey, patrol, station, transit without
    /// a formation).
    pub(super) fn flies_routes(&self) -> bool {
        matches!(self, Active::Routes { .. })
    }

    /// Points vehicle `id` reached on its route in the step; `None` when it has none.
    pub(super) fn reached(&self, id: &str) -> Option<usize> {
        self.route(id).map(Route::reached)
    }

    /// Vehicle `id`'s route in the step, if it flies one.
    pub(super) fn route(&self, id: &str) -> Option<&Route> {
        match self {
            Active::Routes { routes, .. } => routes.get(id),
            _ => None,
        }
    }

    /// Vehicle `id` has a route in the step and was not sent away.
    pub(super) fn flies(&self, id: &str) -> bool {
        matches!(self, Active::Routes { routes, released, .. }
            if routes.contains_key(id) && !released.contains(id))
    }

    /// Vehicle `id` leaves its route for an observation: the route waits where it is.
    pub(super) fn suspend(&mut self, id: &str) {
        if let Active::Routes { observing, .. } = self {
            observing.insert(id.to_string());
        }
    }

    /// Vehicle `id` is back from an observation: it flies its route on at once.
    pub(super) fn restore(&mut self, id: &str) {
        if let Active::Routes {
            observing, routes, ..
        } = self
            && observing.remove(id)
            && let Some(r) = routes.get_mut(id)
        {
            r.resend();
        }
    }

    /// Commands to carry on after a pause.
    pub(super) fn resume(&mut self, out: &mut Vec<Action>) {
        match self {
            Active::Formation {
                points,
                next,
                speed_m_s,
                flying: true,
            } => out.push(Action::LeaderMotion(LeaderMotion::Waypoints {
                points: points[(*next).min(points.len() - 1)..].to_vec(),
                speed_m_s: *speed_m_s,
                next: 0,
                repeat: false,
            })),
            Active::Routes { routes, .. } => routes.values_mut().for_each(Route::resend),
            Active::Formation { .. } | Active::InTurn { .. } => {}
        }
    }

    /// The altitude of the step's routes (above the swarm origin), for a step whose
    /// vehicles fly routes (those on their stations too); `None` for the others.
    pub(super) fn route_altitude_m(&self) -> Option<f64> {
        match self {
            Active::Routes { routes, .. } => routes
                .values()
                .find_map(|r| r.remaining().first().or(r.last()).copied())
                .map(|p| -p.down_m),
            _ => None,
        }
    }

    /// Vehicle `reserve` flies `low`'s route on from where `low` was (`at`, its position,
    /// for a cyclic route); `low` is released.
    pub(super) fn replace(&mut self, low: &str, reserve: &str, at: Option<Ned>) {
        if let Active::Routes {
            routes,
            released,
            observing,
            ..
        } = self
            && let Some(r) = routes.get_mut(low)
        {
            let taken = r.handover(at);
            routes.insert(reserve.to_string(), taken);
            released.insert(low.to_string());
            observing.remove(low);
        }
    }

    /// Vehicle `id` leaves the step (sent home): its unflown survey lanes go to the live
    /// vehicle with the fewest left.
    pub(super) fn release(&mut self, id: &str, tick: &Tick) {
        let Active::Routes {
            routes,
            kind,
            released,
            observing,
        } = self
        else {
            return;
        };
        released.insert(id.to_string());
        observing.remove(id);
        if !matches!(kind, Routes::Survey { .. }) {
            return;
        }
        let rest = match routes.get_mut(id) {
            Some(r) => r.take_rest_of_lanes(),
            None => return,
        };
        let taker = routes
            .iter()
            .filter(|(other, _)| !released.contains(*other) && !gone(tick.vehicles.get(*other)))
            .min_by_key(|(_, r)| r.remaining().len())
            .map(|(other, _)| other.clone());
        if let Some(t) = taker {
            routes.get_mut(&t).expect("a taker").extend(&rest);
        }
    }

    /// What ending the step commands (a formation transit's formation cleared).
    pub(super) fn end(&self, out: &mut Vec<Action>) {
        if let Active::Formation { .. } = self {
            out.push(Action::ClearFormation);
        }
    }

    /// How far along it is.
    pub(super) fn progress(&self, tick_now_s: f64) -> StepProgress {
        let plain = |fraction: f64, detail: String| StepProgress {
            fraction: fraction.clamp(0.0, 1.0),
            lanes_done: None,
            lanes_total: None,
            detail,
        };
        match self {
            Active::InTurn { ids, issued, .. } => plain(
                *issued as f64 / ids.len().max(1) as f64,
                format!("{issued} of {} vehicles told", ids.len()),
            ),
            Active::Formation { points, next, .. } => plain(
                *next as f64 / points.len().max(1) as f64,
                format!("{next} of {} waypoints", points.len()),
            ),
            Active::Routes { routes, kind, .. } => routes_progress(routes, kind, tick_now_s),
        }
    }
}

/// Down (within 1 m of the altitude, for a takeoff), as the step wants it.
fn finished_in_turn(v: &VehicleView, altitude_m: Option<f64>) -> bool {
    match altitude_m {
        Some(a) => {
            flying(v)
                && v.relative_alt_m
                    .is_some_and(|h| (h - a).abs() < TAKEOFF_TOLERANCE_M)
        }
        None => matches!(v.state, VehicleState::Landed),
    }
}

fn tick_routes(
    routes: &mut BTreeMap<String, Route>,
    kind: &mut Routes,
    released: &BTreeSet<String>,
    observing: &BTreeSet<String>,
    tick: &Tick,
    out: &mut Vec<Action>,
) -> bool {
    if let Routes::Survey { .. } = kind {
        redistribute(routes, tick);
    }
    let flown = |id: &String| !released.contains(id) && !observing.contains(id);
    for (id, r) in routes.iter_mut().filter(|(id, _)| flown(id)) {
        if let Some(v) = tick.vehicles.get(id).filter(|v| flying(v)) {
            r.tick(v, tick.now_s, out);
        }
    }
    let live: Vec<&Route> = routes
        .iter()
        .filter(|(id, _)| !released.contains(*id) && !gone(tick.vehicles.get(*id)))
        .map(|(_, r)| r)
        .collect();
    // A timed step's clock runs once the vehicles on its duty are in place: those
    // observing a track carry on with that (a bench sortie's 30 s patrol lasted 700 s,
    // its clock held until its two observers, following an intruder, went home).
    let on_duty: Vec<&Route> = routes
        .iter()
        .filter(|(id, _)| flown(id) && !gone(tick.vehicles.get(*id)))
        .map(|(_, r)| r)
        .collect();
    match kind {
        Routes::Once | Routes::Survey { .. } => live.iter().all(|r| r.finished()),
        Routes::Station { duration_s, since } => held_for(
            on_duty.iter().all(|r| r.finished()),
            since,
            *duration_s,
            tick.now_s,
        ),
        Routes::Patrol { duration_s, since } => match duration_s {
            Some(d) => held_for(
                on_duty.iter().all(|r| r.reached() > 0),
                since,
                *d,
                tick.now_s,
            ),
            None => false,
        },
    }
}

/// Each vehicle's station (`points` at `altitude_m`), in `ids`' order: the points given so
/// that the sum of the squared distances flown is smallest (as a formation's slots are
/// assigned: straight ways that keep apart, no vehicle crossing the others' to reach a
/// far point). With a vehicle whose position is unknown, or more vehicles than points
/// (several share one), by order.
fn stations(points: &[Point], altitude_m: f64, ids: &[String], tick: &Tick) -> Vec<Ned> {
    let goals: Vec<Ned> = points.iter().map(|p| ned(*p, altitude_m)).collect();
    let by_order = || (0..ids.len()).map(|i| goals[i % goals.len()]).collect();
    let from: Option<Vec<Ned>> = ids
        .iter()
        .map(|id| tick.vehicles.get(id).and_then(|v| v.position))
        .collect();
    match from {
        Some(from) if from.len() <= goals.len() => {
            skein_model::formation::assign_slots(&from, &goals)
                .into_iter()
                .map(|j| goals[j])
                .collect()
        }
        _ => by_order(),
    }
}

/// `since` set when `ready` first holds; true once `duration_s` passed since.
fn held_for(ready: bool, since: &mut Option<f64>, duration_s: f64, now_s: f64) -> bool {
    if ready && since.is_none() {
        *since = Some(now_s);
    }
    since.is_some_and(|t| now_s - t >= duration_s)
}

/// A survey vehicle that dropped out hands its unflown lanes to the live vehicle with the
/// fewest points left (a lane it was in the middle of whole again).
fn redistribute(routes: &mut BTreeMap<String, Route>, tick: &Tick) {
    let dropped: Vec<String> = routes
        .iter()
        .filter(|(id, r)| gone(tick.vehicles.get(*id)) && !r.finished())
        .map(|(id, _)| id.clone())
        .collect();
    for id in dropped {
        let Some(taker) = routes
            .iter()
            .filter(|(other, _)| **other != id && !gone(tick.vehicles.get(*other)))
            .min_by_key(|(_, r)| r.remaining().len())
            .map(|(other, _)| other.clone())
        else {
            return;
        };
        let r = routes.get_mut(&id).expect("a dropped route");
        let rest = r.take_rest_of_lanes();
        routes.get_mut(&taker).expect("a taker").extend(&rest);
    }
}

fn routes_progress(routes: &BTreeMap<String, Route>, kind: &Routes, now_s: f64) -> StepProgress {
    let reached: usize = routes.values().map(Route::reached).sum();
    let total: usize = routes
        .values()
        .map(|r| r.reached() + r.remaining().len())
        .sum();
    match kind {
        Routes::Survey { lanes } => {
            let done: usize = routes.values().map(|r| r.reached() / 2).sum();
            let done = done.min(*lanes);
            StepProgress {
                fraction: done as f64 / (*lanes).max(1) as f64,
                lanes_done: Some(done),
                lanes_total: Some(*lanes),
                detail: format!("{done} of {lanes} lanes flown"),
            }
        }
        Routes::Station { duration_s, since }
        | Routes::Patrol {
            duration_s: Some(duration_s),
            since,
        } => StepProgress {
            fraction: since.map_or(0.0, |t| ((now_s - t) / duration_s.max(1e-9)).min(1.0)),
            lanes_done: None,
            lanes_total: None,
            detail: match since {
                Some(t) => format!("{:.0} of {duration_s:.0} s", now_s - t),
                None => "flying to their places".into(),
            },
        },
        Routes::Patrol {
            duration_s: None, ..
        } => StepProgress {
            fraction: 0.0,
            lanes_done: None,
            lanes_total: None,
            detail: format!("{reached} points patrolled, until skipped"),
        },
        Routes::Once => StepProgress {
            fraction: reached as f64 / total.max(1) as f64,
            lanes_done: None,
            lanes_total: None,
            detail: format!("{reached} of {total} points"),
        },
    }
}

/// Each vehicle's copy of `points`, offset by where it is from the group's centre.
fn offset_routes(ids: &[String], tick: &Tick, points: &[Ned]) -> BTreeMap<String, Route> {
    let c = centre(ids, tick);
    ids.iter()
        .map(|id| {
            let p = tick.vehicles.get(id).and_then(|v| v.position).unwrap_or(c);
            let off = Ned::new(p.north_m - c.north_m, p.east_m - c.east_m, 0.0);
            let pts = points.iter().map(|q| *q + off).collect();
            (id.clone(), Route::new(pts, false))
        })
        .collect()
}

/// The group's centre now (the origin when none reports a position).
fn centre(ids: &[String], tick: &Tick) -> Ned {
    let ps: Vec<Ned> = ids
        .iter()
        .filter_map(|id| tick.vehicles.get(id).and_then(|v| v.position))
        .collect();
    let n = ps.len().max(1) as f64;
    let sum = ps.iter().fold(Ned::ZERO, |a, p| a + *p);
    Ned::new(sum.north_m / n, sum.east_m / n, sum.down_m / n)
}

/// Degrees clockwise from north, from `from` toward `to`.
fn heading_deg(from: Ned, to: Ned) -> f64 {
    (to.east_m - from.east_m)
        .atan2(to.north_m - from.north_m)
        .to_degrees()
}
