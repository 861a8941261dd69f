//! The intruder reaction ([`crate::plan::IntruderReaction`]): during a step whose vehicles
//! fly their own routes, a confirmed track inside the zone is observed by the nearest
//! vehicles of the step that carry a gimbal ([`Action::Observe`]); their routes wait
//! where they left them while the rest of the step carries on. When the track is lost or
//! gone they are released ([`Action::StopObserving`]) and fly their routes on; an observer
//! that drops out or is sent home leaves the observation, which goes on with the others.
//! A step that ends ends its observations: the next step's vehicles react afresh.

use super::step::{Active, flying};
use super::swap::Reaction;
use super::{Action, Tick, TrackSeen};
use crate::plan::IntruderReaction;
use skein_model::geofence::polygon;
use std::collections::{BTreeMap, BTreeSet};

/// The reaction's state through the mission.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub(super) struct Intrusions {
    rule: IntruderReaction,
    /// Tracks observed now, and by whom.
    watching: BTreeMap<String, Vec<String>>,
    /// Confirmed tracks in the zone with no vehicle free to observe them (said once).
    unanswered: BTreeSet<String>,
}

impl Intrusions {
    pub(super) fn new(rule: IntruderReaction) -> Self {
        Intrusions {
            rule,
            watching: BTreeMap::new(),
            unanswered: BTreeSet::new(),
        }
    }

    /// One tick of the step `active` flown by `vehicles`: releases the observers of tracks
    /// lost or gone, sends observers to new tracks in the zone.
    pub(super) fn tick(
        &mut self,
        active: &mut Active,
        vehicles: &[String],
        tick: &Tick,
        out: &mut Vec<Action>,
        happened: &mut Vec<Reaction>,
    ) {
        if !active.flies_routes() {
            return;
        }
        self.release_ended(active, tick, out, happened);
        self.drop_departed(active, tick, out);
        let new: Vec<&TrackSeen> = tick
            .tracks
            .iter()
            .filter(|t| t.confirmed && !self.watching.contains_key(&t.id) && self.in_zone(t))
            .collect();
        for track in new {
            self.send_observers(active, vehicles, track, tick, out, happened);
        }
    }

    fn in_zone(&self, t: &TrackSeen) -> bool {
        self.rule
            .zone
            .as_ref()
            .is_none_or(|z| polygon::inside(z, [t.position.north_m, t.position.east_m]))
    }

    /// Observers of tracks no longer confirmed go back to their routes.
    fn release_ended(
        &mut self,
        active: &mut Active,
        tick: &Tick,
        out: &mut Vec<Action>,
        happened: &mut Vec<Reaction>,
    ) {
        let ended: Vec<String> = self
            .watching
            .keys()
            .filter(|t| !tick.tracks.iter().any(|x| x.id == **t && x.confirmed))
            .cloned()
            .collect();
        for target in ended {
            let observers = self.stop(&target, active, out);
            self.unanswered.remove(&target);
            happened.push(Reaction {
                gap_s: None,
                at_s: tick.now_s,
                kind: "intruder",
                vehicles: observers.clone(),
                detail: format!(
                    "{target} lost or gone: {} back to the step",
                    observers.join(", ")
                ),
            });
        }
    }

    /// Observers sent home or dropped out leave their observation; it goes on with the
    /// others (or ends with none).
    fn drop_departed(&mut self, active: &mut Active, tick: &Tick, out: &mut Vec<Action>) {
        let targets: Vec<String> = self.watching.keys().cloned().collect();
        for target in targets {
            let observers = &self.watching[&target];
            let staying: Vec<String> = observers
                .iter()
                .filter(|v| active.flies(v) && tick.vehicles.get(*v).is_some_and(flying))
                .cloned()
                .collect();
            if staying.len() == observers.len() {
                continue;
            }
            self.stop(&target, active, out);
            if staying.is_empty() {
                continue;
            }
            for v in &staying {
                active.suspend(v);
            }
            out.push(self.observe(&target, &staying));
            self.watching.insert(target, staying);
        }
    }

    fn send_observers(
        &mut self,
        active: &mut Active,
        vehicles: &[String],
        track: &TrackSeen,
        tick: &Tick,
        out: &mut Vec<Action>,
        happened: &mut Vec<Reaction>,
    ) {
        let busy: BTreeSet<&String> = self.watching.values().flatten().collect();
        let mut free: Vec<(f64, &String)> = vehicles
            .iter()
            .filter(|id| !busy.contains(id) && active.flies(id))
            .filter_map(|id| {
                let v = tick.vehicles.get(id).filter(|v| v.observer && flying(v))?;
                Some(((v.position? - track.position).horizontal_norm(), id))
            })
            .collect();
        free.sort_by(|a, b| a.0.total_cmp(&b.0));
        let chosen: Vec<String> = free
            .into_iter()
            .take(self.rule.observers)
            .map(|(_, id)| id.clone())
            .collect();
        if chosen.is_empty() {
            if self.unanswered.insert(track.id.clone()) {
                happened.push(Reaction {
                    gap_s: None,
                    at_s: tick.now_s,
                    kind: "intruder",
                    vehicles: vec![],
                    detail: format!(
                        "{} in the zone: no vehicle of the step free to observe it",
                        track.id
                    ),
                });
            }
            return;
        }
        for v in &chosen {
            active.suspend(v);
        }
        out.push(self.observe(&track.id, &chosen));
        happened.push(Reaction {
            gap_s: None,
            at_s: tick.now_s,
            kind: "intruder",
            vehicles: chosen.clone(),
            detail: format!("{} in the zone: {} observe it", track.id, chosen.join(", ")),
        });
        self.unanswered.remove(&track.id);
        self.watching.insert(track.id.clone(), chosen);
    }

    fn observe(&self, target: &str, vehicles: &[String]) -> Action {
        Action::Observe {
            target: target.to_string(),
            vehicles: vehicles.to_vec(),
            stations: self.rule.stations && vehicles.len() >= 2,
            standoff_m: self.rule.standoff_m,
        }
    }

    /// Ends the observation of `target`: its observers fly their routes on. Returns them.
    fn stop(&mut self, target: &str, active: &mut Active, out: &mut Vec<Action>) -> Vec<String> {
        let observers = self.watching.remove(target).unwrap_or_default();
        out.push(Action::StopObserving {
            target: target.to_string(),
        });
        for v in &observers {
            active.restore(v);
        }
        observers
    }

    /// The swarm refused to observe `target` (`why`): its observers fly their routes on.
    pub(super) fn refused(
        &mut self,
        target: &str,
        why: &str,
        active: Option<&mut Active>,
        now_s: f64,
        happened: &mut Vec<Reaction>,
    ) {
        let observers = self.watching.remove(target).unwrap_or_default();
        if let Some(a) = active {
            for v in &observers {
                a.restore(v);
            }
        }
        self.unanswered.insert(target.to_string());
        happened.push(Reaction {
            gap_s: None,
            at_s: now_s,
            kind: "intruder",
            vehicles: observers,
            detail: format!("{target} could not be observed ({why}): the step carries on"),
        });
    }

    /// Ends every observation (the step ended, or an abort).
    pub(super) fn end_all(&mut self, out: &mut Vec<Action>) {
        for target in std::mem::take(&mut self.watching).into_keys() {
            out.push(Action::StopObserving { target });
        }
        self.unanswered.clear();
    }

    /// Moves the zone's points through `flat` (into another swarm frame).
    pub(super) fn reframe(&mut self, flat: &dyn Fn(&mut [f64; 2])) {
        if let Some(zone) = self.rule.zone.as_mut() {
            zone.iter_mut().for_each(flat);
        }
    }

    /// Another coordinator takes the run over (mission time `now_s`): every observation
    /// ends, its observers back to their routes (it flew the other coordinator's tracks;
    /// this one's own confirmed tracks start the reaction afresh).
    pub(super) fn hand_over(
        &mut self,
        active: &mut Active,
        now_s: f64,
        happened: &mut Vec<Reaction>,
    ) {
        let mut ignored = Vec::new();
        let targets: Vec<String> = self.watching.keys().cloned().collect();
        for target in targets {
            let observers = self.stop(&target, active, &mut ignored);
            happened.push(Reaction {
                gap_s: None,
                at_s: now_s,
                kind: "intruder",
                vehicles: observers.clone(),
                detail: format!(
                    "the coordinator changed: {} back to the step from {target}",
                    observers.join(", ")
                ),
            });
        }
        self.unanswered.clear();
    }

    /// The vehicles observing now.
    pub(super) fn observers(&self) -> BTreeSet<String> {
        self.watching.values().flatten().cloned().collect()
    }
}
