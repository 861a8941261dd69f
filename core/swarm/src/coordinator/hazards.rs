//! Hazard tracking: which vehicles the formation must plan around. A vehicle whose FSM
//! is `Lost` (link silent) or `Failsafe` (PX4 flies it, not the setpoints) is a
//! [`Hazard`] at its last known position, its radius growing with the time since it was
//! last heard ([`HazardConfig`]). It stops being one when it is heard again and follows
//! setpoints, when it is seen on the ground, when it has been unseen for
//! `max_unseen_s`, or when an operator clears it (until it is next lost).

use super::CoordinatorState;
use crate::events::SwarmEvent;
use crate::formation::Hazard;
use skein_model::fsm::VehicleState;
use skein_model::px4::LandedState;
use std::collections::{BTreeMap, BTreeSet};

/// The hazards in force and the ones an operator cleared.
#[derive(Debug, Default)]
pub struct Hazards {
    active: BTreeMap<String, Hazard>,
    cleared: BTreeSet<String>,
}

fn is_hazard_state(s: VehicleState) -> bool {
    matches!(s, VehicleState::Lost | VehicleState::Failsafe)
}

impl CoordinatorState {
    /// Brings the hazards up to date from the vehicles' reports; emits `hazard_added`
    /// and `hazard_cleared`; returns the hazards in force.
    pub(super) fn update_hazards(&mut self) -> Vec<Hazard> {
        let config = self.context.config.hazards;
        let mut events = Vec::new();
        for (id, v) in &self.vehicles {
            let r = v.report();
            // A silent member within its ride-through flies its slot: not a hazard.
            if v.failed || !is_hazard_state(r.state) || v.riding_through() {
                self.hazards.cleared.remove(id);
                if self.hazards.active.remove(id).is_some() {
                    let on_ground = matches!(r.state, VehicleState::Landed | VehicleState::Armed)
                        || v.snapshot().landed_state == LandedState::OnGround;
                    let reason = if on_ground {
                        "seen on the ground".to_string()
                    } else if v.failed {
                        "its actor failed: PX4 holds or lands it".to_string()
                    } else {
                        format!("heard again ({})", r.state)
                    };
                    events.push(SwarmEvent::HazardCleared {
                        id: id.clone(),
                        reason,
                    });
                }
                continue;
            }
            if self.hazards.cleared.contains(id) {
                continue;
            }
            let unseen_s = r.silence_now().as_secs_f64();
            if unseen_s > config.max_unseen_s {
                self.hazards.cleared.insert(id.clone());
                if self.hazards.active.remove(id).is_some() {
                    events.push(SwarmEvent::HazardCleared {
                        id: id.clone(),
                        reason: format!("unseen for over {} s", config.max_unseen_s),
                    });
                }
                continue;
            }
            let Some(position) = r.position else {
                continue;
            };
            let hazard = Hazard {
                id: id.clone(),
                position,
                radius_m: config.radius_m(unseen_s),
                unseen_s: if unseen_s.is_finite() { unseen_s } else { 0.0 },
                reason: r.state.name().to_string(),
            };
            if !self.hazards.active.contains_key(id) {
                tracing::warn!(
                    "{id} is a hazard ({}) at ({:.1}, {:.1}, {:.1})",
                    hazard.reason,
                    position.north_m,
                    position.east_m,
                    position.down_m
                );
                events.push(SwarmEvent::HazardAdded {
                    id: id.clone(),
                    position,
                    reason: hazard.reason.clone(),
                });
            }
            self.hazards.active.insert(id.clone(), hazard);
        }
        for ev in events {
            self.emit(ev);
        }
        self.hazards.active.values().cloned().collect()
    }

    /// An operator clears the hazard of vehicle `id` (until it is next lost).
    pub(super) fn clear_hazard(&mut self, id: &str) -> Result<(), Option<String>> {
        if !self.vehicles.contains_key(id) {
            return Err(None);
        }
        if self.hazards.active.remove(id).is_none() {
            return Err(Some(format!(
                "clear_hazard refused: vehicle {id} is not a hazard"
            )));
        }
        self.hazards.cleared.insert(id.to_string());
        // The operator let it go: no longer an absent member of the formation either.
        self.formation.release(id);
        let hazards = self.hazards.active.values().cloned().collect();
        self.formation.set_hazards(hazards);
        self.emit(SwarmEvent::HazardCleared {
            id: id.to_string(),
            reason: "cleared by an operator".into(),
        });
        Ok(())
    }
}
