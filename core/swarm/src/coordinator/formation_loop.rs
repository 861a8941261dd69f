//! The formation loop: every tick ([`crate::SwarmConfig::formation_rate_hz`]) the engine
//! reads the members' reports, moves the reference, plans transitions and sends each
//! member its stamped [`SlotTarget`]; hovering vehicles join an active formation.

use super::CoordinatorState;
use crate::events::SwarmEvent;
use crate::formation::{FormationStatus, Member};
use crate::metrics::Metrics;
use crate::protocol::{Command, SlotTarget, ToVehicle, wall_us};
use skein_model::fsm::VehicleState;
use skein_model::geo::Ned;
use std::collections::BTreeMap;
use std::time::Instant;

impl CoordinatorState {
    /// The formation as `GET /api/v1/formation` shows it.
    pub(super) fn formation_status(&self) -> FormationStatus {
        let airborne: Vec<Ned> = self
            .vehicles
            .values()
            .filter(|v| v.state().is_airborne())
            .filter_map(|v| v.position())
            .collect();
        self.formation.status(&airborne)
    }

    /// Every hovering vehicle joins the active formation (but observers on their
    /// observation stations).
    pub(super) fn join_hovering(&self) {
        if !self.formation.is_active() {
            return;
        }
        for (id, v) in &self.vehicles {
            if !v.failed && v.state() == VehicleState::Hovering && !self.on_station(id) {
                self.internal_command(id, Command::JoinFormation);
            }
        }
    }

    /// A vehicle's state changed: a vehicle that starts hovering joins an active
    /// formation, unless it observes from a station.
    pub(super) fn on_state_changed(&self, id: &str, to: VehicleState) {
        if to == VehicleState::Hovering && self.formation.is_active() && !self.on_station(id) {
            self.internal_command(id, Command::JoinFormation);
        }
    }

    /// One tick of the formation loop (see the module docs).
    pub(super) fn formation_tick(&mut self) {
        // Vehicles without an actor (escalated) still show their telemetry.
        let frame = self.context.frame();
        for v in self.vehicles.values().filter(|v| v.failed) {
            if let Some(local) = &v.local {
                local.shared.settle_from_telemetry();
                local.shared.publish(frame, None, &self.supervision);
                local.shared.publish_report(frame);
            }
        }
        let status = self.formation_status();
        self.metrics
            .formation_rms_error_m
            .set(status.rms_error_m.unwrap_or(f64::NAN));
        self.metrics
            .min_separation_m
            .set(status.min_separation_m.unwrap_or(f64::NAN));
        for m in &status.members {
            self.metrics
                .slot_error_m
                .get_or_create(&Metrics::label("vehicle", &m.id))
                .set(m.error_m);
        }
        let now = Instant::now();
        let dt = now
            .duration_since(self.last_formation_tick)
            .as_secs_f64()
            .min(0.5);
        self.last_formation_tick = now;
        if !self.formation.is_active() || frame.is_none() {
            return;
        }
        let members: BTreeMap<String, Member> = self
            .vehicles
            .iter()
            .filter(|(_, v)| !v.failed && v.state() == VehicleState::InFormation)
            .filter_map(|(id, v)| {
                let r = v.report();
                Some((
                    id.clone(),
                    Member {
                        position: v.position()?,
                        velocity: r.velocity,
                        heading_rad: r.heading_rad,
                        silence: r.silence_now(),
                        target: r.target,
                    },
                ))
            })
            .collect();
        let hazards = self.update_hazards();
        self.formation.set_hazards(hazards);
        let slots = self
            .formation
            .tick(&members, dt, &self.context.geofence().fence);
        for replan in self.formation.take_replans() {
            tracing::warn!("formation planned again: {}", replan.reason);
            self.emit(SwarmEvent::FormationReplanned {
                stuck: replan.stuck,
                reason: replan.reason,
            });
        }
        if let Some(reason) = self.formation.take_blocked_change() {
            if let Some(why) = &reason {
                tracing::warn!("formation blocked: {why}");
            }
            self.emit(SwarmEvent::FormationBlocked { reason });
        }
        if self.formation.take_pending_applied() {
            let status = serde_json::to_value(self.formation_status()).unwrap_or_default();
            self.emit(SwarmEvent::FormationChanged { formation: status });
        }
        for change in self.formation.take_leader_changes() {
            tracing::info!(
                "formation leader {} -> {} ({})",
                change.from.as_deref().unwrap_or("none"),
                change.to,
                change.reason
            );
            self.emit(SwarmEvent::LeaderChanged {
                from: change.from,
                to: change.to,
                reason: change.reason,
            });
        }
        let stamp_us = wall_us();
        for (id, s) in slots {
            if let Some(v) = self.vehicles.get(&id).filter(|v| !v.failed) {
                let _ = v.send(ToVehicle::Slot {
                    target: Some(SlotTarget {
                        slot: s.slot,
                        leader: s.leader,
                        position: s.position,
                        goal: s.goal,
                        velocity: s.velocity,
                        yaw_rad: s.yaw_rad,
                        stamp_us,
                    }),
                });
            }
        }
    }
}
