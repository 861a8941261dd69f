//! Observation stations: the observers of a track or a hostile swarm fly to where their
//! cameras fix it best, and again as it moves (`"stations": true` in an observe request;
//! the geometry is [`crate::tracking::stations`]).
//!
//! On the request the coordinator plans stations for the target's points forecast
//! [`PLAN_AHEAD_S`] ahead (a swarm's members, or the track; the stand-off is kept from
//! where they are now too, so no station lies on their way) and sends each observer a
//! go-to (command id 0: it leaves a formation it flies in, and does not rejoin one while it
//! observes). Every [`REPLAN_EVERY_S`] it plans again: the observers keep their stations
//! while those still meet the limits and predict a variance within [`REPLAN_GAIN`] of the
//! best layout's (so they hover, which keeps their cameras' poses exact, rather than chase
//! every metre), and fly to the new ones otherwise. A go-to goes again when an observer
//! was sent elsewhere (it hovers more than [`RESEND_M`] from its station, or flies in the
//! formation). Stations keep the formation engine's checks: the slot distance
//! (`√2 × (min_separation_m + separation_margin_m)`) between stations and from every other
//! vehicle, and the geofence shrunk by [`FENCE_MARGIN_M`]; each go-to is then flown
//! through the vehicle's own shaper (fence clamp, speed limits, separation). A lost track
//! keeps the stations it had; a deleted track or a lost swarm, or the operator's release,
//! ends the observation and the observers hold where they are.

use super::CoordinatorState;
use super::observe::ObserveRefusal;
use crate::protocol::Command;
use crate::tracking::stations::{self, Observer, StationLimits, StationPlan};
use crate::tracking::target::locate;
use crate::tracks::{SwarmView, TrackView};
use serde::Serialize;
use skein_model::command::GoTo;
use skein_model::geo::Ned;
use std::time::{Duration, Instant};

/// Default least horizontal distance of a station from the target, metres.
pub const DEFAULT_STANDOFF_M: f64 = 25.0;
/// Stand-offs accepted, metres.
pub const STANDOFF_RANGE_M: (f64, f64) = (10.0, 60.0);
/// Farthest a station is from the target's points: the simulated camera finds a small
/// multicopter up to about 120 m, and a fix degrades with range, metres.
pub const MAX_RANGE_M: f64 = 80.0;
/// Horizontal field of view of the observation cameras, degrees (the simulated camera's).
pub const CAMERA_FOV_DEG: f64 = 75.0;
pub use crate::tracking::target::PLAN_AHEAD_S;
/// How often stations are planned again, seconds.
pub const REPLAN_EVERY_S: f64 = 1.0;
/// The observers move when their stations' predicted variance exceeds the best layout's
/// by this factor.
pub const REPLAN_GAIN: f64 = 1.5;
/// An observer hovering farther than this from its station is sent there again, metres.
pub const RESEND_M: f64 = 3.0;
/// Stations stay this far inside the geofence, metres.
pub const FENCE_MARGIN_M: f64 = 5.0;

/// One observation flown on stations.
#[derive(Debug, Clone)]
pub(super) struct StationTask {
    vehicles: Vec<String>,
    standoff_m: f64,
    plan: StationPlan,
    last_plan: Instant,
    replans: u32,
}

/// A station of one observer (`GET /api/v1/swarms`, `GET /api/v1/tracks`).
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct StationView {
    /// The observer.
    pub vehicle: String,
    /// Its station, swarm-frame NED, metres.
    pub position: Ned,
}

/// How a target is observed from stations.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct StationsView {
    /// The track or swarm.
    pub target: String,
    /// Each observer's station.
    pub stations: Vec<StationView>,
    /// Predicted horizontal error of a fix from them, one σ, metres.
    pub predicted_sigma_m: f64,
    /// Widest angle between two observers' lines of sight to the target, degrees (0–90).
    pub triangulation_angle_deg: f64,
    /// The stand-off kept, metres.
    pub standoff_m: f64,
    /// Times the stations were moved since the request.
    pub replans: u32,
}

impl CoordinatorState {
    fn station_limits(&self, standoff_m: f64) -> StationLimits {
        let config = &self.context.config;
        StationLimits {
            standoff_m,
            max_range_m: MAX_RANGE_M,
            min_separation_m: config.min_slot_distance_m(),
            fov_deg: CAMERA_FOV_DEG,
            bearing_sigma_rad: crate::tracking::TrackerConfig::default()
                .bearing_sigma_deg
                .to_radians(),
            fence: config.geofence.clone(),
            fence_margin_m: FENCE_MARGIN_M,
        }
    }

    /// The positions of every airborne vehicle not in `vehicles`.
    fn others(&self, vehicles: &[String]) -> Vec<Ned> {
        self.vehicles
            .iter()
            .filter(|(id, v)| !vehicles.contains(id) && v.state().is_airborne())
            .filter_map(|(_, v)| v.position())
            .collect()
    }

    fn observers(&self, vehicles: &[String]) -> Result<Vec<Observer>, String> {
        vehicles
            .iter()
            .map(|id| {
                let v = self
                    .vehicles
                    .get(id)
                    .ok_or_else(|| format!("no vehicle `{id}`"))?;
                if !v.state().is_airborne() {
                    return Err(format!("{id} is {}: take off first", v.state()));
                }
                let position = v
                    .position()
                    .ok_or_else(|| format!("{id} has no position"))?;
                Ok(Observer {
                    id: id.clone(),
                    position,
                })
            })
            .collect()
    }

    /// Plans stations for `target` observed by `vehicles` and sends them there.
    pub(super) fn start_stations(
        &mut self,
        target: &str,
        vehicles: &[String],
        standoff_m: Option<f64>,
    ) -> Result<(), ObserveRefusal> {
        let standoff = standoff_m.unwrap_or(DEFAULT_STANDOFF_M);
        let (lo, hi) = STANDOFF_RANGE_M;
        if !(standoff.is_finite() && (lo..=hi).contains(&standoff)) {
            return Err(ObserveRefusal::BadStandoff(format!(
                "standoff_m {standoff} is outside {lo}..{hi} m"
            )));
        }
        let now = self
            .target_now(target)
            .ok_or_else(|| ObserveRefusal::UnknownTarget(format!("no target `{target}`")))?;
        let observers = self
            .observers(vehicles)
            .map_err(ObserveRefusal::NoStations)?;
        let plan = stations::plan(
            &observers,
            &now.ahead,
            &now.now,
            &self.others(vehicles),
            &self.station_limits(standoff),
        )
        .map_err(ObserveRefusal::NoStations)?;
        // An observer of another target's stations leaves them; every observer leaves the
        // formation because it was asked to.
        for v in vehicles {
            self.formation.release(v);
            let other = self
                .stations
                .iter()
                .find(|(t, task)| *t != target && task.vehicles.contains(v))
                .map(|(t, _)| t.clone());
            if let Some(t) = other {
                self.leave_stations(&t, v);
            }
        }
        tracing::info!(
            %target,
            sigma_m = plan.predicted_sigma_m,
            angle_deg = plan.triangulation_angle_deg,
            "observation stations planned"
        );
        self.send_stations(&plan, true);
        self.stations.insert(
            target.to_string(),
            StationTask {
                vehicles: vehicles.to_vec(),
                standoff_m: standoff,
                plan,
                last_plan: Instant::now(),
                replans: 0,
            },
        );
        Ok(())
    }

    /// Sends each observer of `plan` to its station: all of them when `all`, else those
    /// sent elsewhere since (hovering away from it, or flying in the formation).
    fn send_stations(&self, plan: &StationPlan, all: bool) {
        for (id, p) in &plan.stations {
            let Some(v) = self.vehicles.get(id) else {
                continue;
            };
            let state = v.state();
            let away = v.position().is_none_or(|q| (q - *p).norm() > RESEND_M);
            let resend = all
                || state == skein_model::fsm::VehicleState::InFormation
                || (state == skein_model::fsm::VehicleState::Hovering && away);
            if resend {
                self.internal_command(id, Command::GoTo(GoTo::from(*p)));
            }
        }
    }

    /// `vehicle` no longer observes `target` from a station; fewer than two left end it.
    pub(super) fn leave_stations(&mut self, target: &str, vehicle: &str) {
        let Some(task) = self.stations.get_mut(target) else {
            return;
        };
        task.vehicles.retain(|v| v != vehicle);
        task.plan.stations.retain(|(v, _)| v != vehicle);
        if task.vehicles.len() < 2 {
            self.end_stations(target);
        }
    }

    /// Ends the stations of `target`: its observers hold where they are.
    pub(super) fn end_stations(&mut self, target: &str) {
        if let Some(task) = self.stations.remove(target) {
            for v in &task.vehicles {
                self.internal_command(v, Command::Hold);
            }
        }
    }

    /// True when `vehicle` flies to or holds an observation station (it does not join the
    /// formation meanwhile).
    pub(super) fn on_station(&self, vehicle: &str) -> bool {
        self.stations
            .values()
            .any(|t| t.vehicles.iter().any(|v| v == vehicle))
    }

    /// Plans the stations again where due (see the module docs).
    pub(super) fn stations_tick(&mut self, tracks: &[TrackView], swarms: &[SwarmView]) {
        let due: Vec<String> = self
            .stations
            .iter()
            .filter(|(_, t)| t.last_plan.elapsed() >= Duration::from_secs_f64(REPLAN_EVERY_S))
            .map(|(id, _)| id.clone())
            .collect();
        for target in due {
            let Some(now) = locate(&target, tracks, swarms) else {
                self.end_stations(&target);
                continue;
            };
            let Some(task) = self.stations.get(&target).cloned() else {
                continue;
            };
            let limits = self.station_limits(task.standoff_m);
            let others = self.others(&task.vehicles);
            let mut next = task.clone();
            next.last_plan = Instant::now();
            let mut moved = false;
            if now.live
                && let Ok(observers) = self.observers(&task.vehicles)
            {
                let current =
                    stations::evaluate(&task.plan.stations, &now.ahead, limits.bearing_sigma_rad);
                let valid = stations::still_valid(
                    &task.plan.stations,
                    &now.ahead,
                    &now.now,
                    &others,
                    &limits,
                );
                match stations::plan(&observers, &now.ahead, &now.now, &others, &limits) {
                    Ok(best)
                        if !valid
                            || current.predicted_sigma_m.powi(2)
                                > REPLAN_GAIN * best.predicted_sigma_m.powi(2) =>
                    {
                        next.plan = best;
                        next.replans += 1;
                        moved = true;
                    }
                    Ok(_) => next.plan = current,
                    Err(e) => tracing::debug!(%target, "stations kept: {e}"),
                }
            }
            self.send_stations(&next.plan, moved);
            self.stations.insert(target, next);
        }
    }

    /// The observations flown on stations.
    pub(super) fn station_views(&self) -> Vec<StationsView> {
        self.stations
            .iter()
            .map(|(target, t)| StationsView {
                target: target.clone(),
                stations: t
                    .plan
                    .stations
                    .iter()
                    .map(|(v, p)| StationView {
                        vehicle: v.clone(),
                        position: *p,
                    })
                    .collect(),
                predicted_sigma_m: t.plan.predicted_sigma_m,
                triangulation_angle_deg: t.plan.triangulation_angle_deg,
                standoff_m: t.standoff_m,
                replans: t.replans,
            })
            .collect()
    }
}
