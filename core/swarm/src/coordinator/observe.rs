//! Observing a track or a hostile swarm: the gimbals of chosen observation UAVs point at
//! it and follow it (`POST /api/v1/tracks/{id}/observe`, `POST /api/v1/swarms/{id}/observe`),
//! so it stays in their cameras' view; with `stations`, the observers also fly to the
//! stations that fix it best ([`super::stations`]).
//!
//! Every formation tick (10 Hz) each observing vehicle's gimbal gets a `roi_location`
//! command at the target's current estimate (a track's position, a swarm's centroid;
//! swarm frame; the gimbal turns it into angles from its own vehicle's pose, within its
//! slew rate). A lost track is followed on its prediction; a deleted track or a lost swarm
//! ends the observation (the gimbals hold their angles). The commands carry request id 0:
//! their answers are not waited for.

use super::CoordinatorState;
use crate::protocol::ToVehicle;
use crate::tracks::TrackStatus;
use serde_json::json;

pub(super) use crate::tracking::target::{TargetNow, locate};
pub use crate::tracks::SWARM_PREFIX;

/// Why an observation was refused.
#[derive(Debug, Clone, PartialEq)]
pub enum ObserveRefusal {
    /// No such track or swarm (`id`).
    UnknownTarget(String),
    /// The track is lost: nothing to point at (`id`).
    TrackLost(String),
    /// A vehicle that does not exist or has no gimbal (`vehicles`).
    BadVehicle(String),
    /// A stand-off outside its range (`standoff_m`).
    BadStandoff(String),
    /// No stations meet the limits (`stations`): the reason.
    NoStations(String),
}

impl ObserveRefusal {
    /// The request field at fault.
    pub fn field(&self) -> &'static str {
        match self {
            ObserveRefusal::UnknownTarget(_) | ObserveRefusal::TrackLost(_) => "id",
            ObserveRefusal::BadVehicle(_) => "vehicles",
            ObserveRefusal::BadStandoff(_) => "standoff_m",
            ObserveRefusal::NoStations(_) => "stations",
        }
    }

    /// What is wrong.
    pub fn message(&self) -> &str {
        match self {
            ObserveRefusal::UnknownTarget(m)
            | ObserveRefusal::TrackLost(m)
            | ObserveRefusal::BadVehicle(m)
            | ObserveRefusal::BadStandoff(m)
            | ObserveRefusal::NoStations(m) => m,
        }
    }
}

/// What to observe, with what, and how (`POST /api/v1/{tracks,swarms}/{id}/observe`).
#[derive(Debug, Clone, PartialEq)]
pub struct ObserveSpec {
    /// A track (`track-N`) or a hostile swarm (`swarm-N`).
    pub target: String,
    /// The observers; `None`: every vehicle with a gimbal.
    pub vehicles: Option<Vec<String>>,
    /// Also fly them to the stations that fix the target best.
    pub stations: bool,
    /// The stations' least horizontal distance from the target, metres (`None`: the
    /// default, [`super::stations::DEFAULT_STANDOFF_M`]).
    pub standoff_m: Option<f64>,
}

impl CoordinatorState {
    /// The gimbal slot of vehicle `id`, if it has one (a payload of kind `gimbal`).
    pub(super) fn gimbal_slot(&self, id: &str) -> Option<String> {
        self.fleet
            .reader()
            .snapshots()
            .into_iter()
            .find(|s| s.id == id)?
            .payloads
            .iter()
            .find(|p| p["kind"] == "gimbal")
            .and_then(|p| p["slot"].as_str().map(str::to_string))
    }

    /// Where the target `id` is now (see [`locate`]).
    pub(super) fn target_now(&self, id: &str) -> Option<TargetNow> {
        let shared = self.tracking.shared();
        locate(id, &shared.tracks(), &shared.swarms())
    }

    /// Starts observing `spec.target` with `spec.vehicles` (default: every vehicle with a
    /// gimbal), and with `spec.stations` flies them to their stations; returns the
    /// vehicles now observing it. A vehicle observing another target switches.
    pub(super) fn observe(&mut self, spec: ObserveSpec) -> Result<Vec<String>, ObserveRefusal> {
        let target = spec.target.as_str();
        let kind = if target.starts_with(SWARM_PREFIX) {
            "swarm"
        } else {
            "track"
        };
        if let Some(t) = self
            .tracking
            .shared()
            .tracks()
            .into_iter()
            .find(|t| t.id == target && t.status == TrackStatus::Lost)
        {
            return Err(ObserveRefusal::TrackLost(format!(
                "track `{target}` is lost ({:.1} s unseen)",
                t.unseen_s
            )));
        }
        if self.target_now(target).is_none() {
            return Err(ObserveRefusal::UnknownTarget(format!(
                "no {kind} `{target}` (see GET /api/v1/{kind}s)"
            )));
        }
        let chosen: Vec<(String, String)> = match spec.vehicles.clone() {
            Some(list) => list
                .into_iter()
                .map(|v| match self.gimbal_slot(&v) {
                    Some(slot) => Ok((v, slot)),
                    None if self.vehicles.contains_key(&v) => Err(ObserveRefusal::BadVehicle(
                        format!("vehicle `{v}` has no gimbal"),
                    )),
                    None => Err(ObserveRefusal::BadVehicle(format!("no vehicle `{v}`"))),
                })
                .collect::<Result<_, _>>()?,
            None => self
                .vehicles
                .keys()
                .filter_map(|v| self.gimbal_slot(v).map(|s| (v.clone(), s)))
                .collect(),
        };
        if chosen.is_empty() {
            return Err(ObserveRefusal::BadVehicle(
                "no vehicle with a gimbal to observe with".into(),
            ));
        }
        let names: Vec<String> = chosen.iter().map(|(v, _)| v.clone()).collect();
        if spec.stations {
            self.start_stations(target, &names, spec.standoff_m)?;
        }
        for (v, slot) in chosen {
            if let Some((old, _)) = self.observing.insert(v.clone(), (target.to_string(), slot))
                && old != target
            {
                self.leave_stations(&old, &v);
            }
        }
        self.observe_tick();
        Ok(names)
    }

    /// Stops observing `track` (a track or a swarm): its gimbals hold their angles, its
    /// observers flying to stations hold where they are. Returns the vehicles that
    /// observed it.
    pub(super) fn stop_observing(&mut self, track: &str) -> Vec<String> {
        self.end_stations(track);
        let released: Vec<(String, String)> = self
            .observing
            .iter()
            .filter(|(_, (t, _))| t == track)
            .map(|(v, (_, slot))| (v.clone(), slot.clone()))
            .collect();
        for (v, slot) in &released {
            self.observing.remove(v);
            if let Some(p) = self.vehicles.get(v) {
                let _ = p.send(ToVehicle::PayloadCommand {
                    request_id: 0,
                    slot: slot.clone(),
                    command: json!({"command": "roi_none"}),
                });
            }
        }
        released.into_iter().map(|(v, _)| v).collect()
    }

    /// Points every observing gimbal at its target's current estimate; flies the
    /// observers on stations.
    pub(super) fn observe_tick(&mut self) {
        if self.observing.is_empty() {
            return;
        }
        let shared = self.tracking.shared();
        let (tracks, swarms) = (shared.tracks(), shared.swarms());
        let mut ended = Vec::new();
        for (v, (target, slot)) in &self.observing {
            let Some(t) = locate(target, &tracks, &swarms) else {
                ended.push(v.clone());
                continue;
            };
            if let Some(p) = self.vehicles.get(v) {
                let _ = p.send(ToVehicle::PayloadCommand {
                    request_id: 0,
                    slot: slot.clone(),
                    command: json!({
                        "command": "roi_location",
                        "north_m": t.centre.north_m,
                        "east_m": t.centre.east_m,
                        "down_m": t.centre.down_m,
                    }),
                });
            }
        }
        for v in ended {
            if let Some((target, _)) = self.observing.remove(&v) {
                tracing::info!(vehicle = %v, %target, "observation ended: the target is gone");
                self.end_stations(&target);
            }
        }
        self.stations_tick(&tracks, &swarms);
    }

    /// Which vehicle observes which track.
    pub(super) fn observations(&self) -> Vec<(String, String)> {
        self.observing
            .iter()
            .map(|(v, (t, _))| (v.clone(), t.clone()))
            .collect()
    }
}
