//! Observing a track: the gimbals of chosen observation UAVs point at a track and follow
//! it (`POST /api/v1/tracks/{id}/observe`), so the track stays in their cameras' view.
//!
//! Every formation tick (10 Hz) each observing vehicle's gimbal gets a `roi_location`
//! command at the track's current estimate (swarm frame; the gimbal turns it into angles
//! from its own vehicle's pose, within its slew rate). A lost track is followed on its
//! prediction; a deleted one ends the observation (the gimbals hold their angles). The
//! commands carry request id 0: their answers are not waited for.

use super::CoordinatorState;
use crate::protocol::ToVehicle;
use crate::tracks::{TrackStatus, TrackView};
use serde_json::json;

/// Why an observation was refused.
#[derive(Debug, Clone, PartialEq)]
pub enum ObserveRefusal {
    /// No such track (`id`).
    UnknownTrack(String),
    /// The track is lost: nothing to point at (`id`).
    TrackLost(String),
    /// A vehicle that does not exist or has no gimbal (`vehicles`).
    BadVehicle(String),
}

impl ObserveRefusal {
    /// The request field at fault.
    pub fn field(&self) -> &'static str {
        match self {
            ObserveRefusal::UnknownTrack(_) | ObserveRefusal::TrackLost(_) => "id",
            ObserveRefusal::BadVehicle(_) => "vehicles",
        }
    }

    /// What is wrong.
    pub fn message(&self) -> &str {
        match self {
            ObserveRefusal::UnknownTrack(m)
            | ObserveRefusal::TrackLost(m)
            | ObserveRefusal::BadVehicle(m) => m,
        }
    }
}

impl CoordinatorState {
    /// The gimbal slot of vehicle `id`, if it has one (a payload of kind `gimbal`).
    fn gimbal_slot(&self, id: &str) -> Option<String> {
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

    fn track(&self, id: &str) -> Option<TrackView> {
        self.tracking
            .shared()
            .tracks()
            .into_iter()
            .find(|t| t.id == id)
    }

    /// Starts observing `track` with `vehicles` (default: every vehicle with a gimbal);
    /// returns the vehicles now observing it. A vehicle observing another track switches.
    pub(super) fn observe_track(
        &mut self,
        track: &str,
        vehicles: Option<Vec<String>>,
    ) -> Result<Vec<String>, ObserveRefusal> {
        match self.track(track) {
            None => {
                return Err(ObserveRefusal::UnknownTrack(format!("no track `{track}`")));
            }
            Some(t) if t.status == TrackStatus::Lost => {
                return Err(ObserveRefusal::TrackLost(format!(
                    "track `{track}` is lost ({:.1} s unseen)",
                    t.unseen_s
                )));
            }
            Some(_) => {}
        }
        let chosen: Vec<(String, String)> = match vehicles {
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
        let names = chosen.iter().map(|(v, _)| v.clone()).collect();
        for (v, slot) in chosen {
            self.observing.insert(v, (track.to_string(), slot));
        }
        self.observe_tick();
        Ok(names)
    }

    /// Stops observing `track`: its gimbals hold their angles. Returns the vehicles that
    /// observed it.
    pub(super) fn stop_observing(&mut self, track: &str) -> Vec<String> {
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

    /// Points every observing gimbal at its track's current estimate.
    pub(super) fn observe_tick(&mut self) {
        if self.observing.is_empty() {
            return;
        }
        let tracks = self.tracking.shared().tracks();
        let mut ended = Vec::new();
        for (v, (track, slot)) in &self.observing {
            let Some(t) = tracks.iter().find(|t| t.id == *track) else {
                ended.push(v.clone());
                continue;
            };
            if let Some(p) = self.vehicles.get(v) {
                let _ = p.send(ToVehicle::PayloadCommand {
                    request_id: 0,
                    slot: slot.clone(),
                    command: json!({
                        "command": "roi_location",
                        "north_m": t.position.north_m,
                        "east_m": t.position.east_m,
                        "down_m": t.position.down_m,
                    }),
                });
            }
        }
        for v in ended {
            if let Some((track, _)) = self.observing.remove(&v) {
                tracing::info!(vehicle = %v, %track, "observation ended: the track was deleted");
            }
        }
    }

    /// Which vehicle observes which track.
    pub(super) fn observations(&self) -> Vec<(String, String)> {
        self.observing
            .iter()
            .map(|(v, (t, _))| (v.clone(), t.clone()))
            .collect()
    }
}
