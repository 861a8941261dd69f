//! The formation loop: every tick ([`crate::SwarmConfig::formation_rate_hz`]) the engine
//! reads the members' reports, moves the reference, plans transitions and sends each
//! member its stamped [`SlotTarget`]; hovering vehicles join an active formation.

use super::CoordinatorState;
use crate::events::SwarmEvent;
use crate::formation::{
    Absence, FormationStatus, LEADER_SILENCE, Member, PACE_SILENCE, Whereabouts,
};
use crate::metrics::Metrics;
use crate::protocol::{Command, SlotTarget, ToVehicle, wall_us};
use skein_model::fsm::VehicleState;
use skein_model::geo::Ned;
use std::collections::BTreeMap;
use std::time::Instant;

impl CoordinatorState {
    /// The formation as `GET /api/v1/formation` shows it, its absent members included.
    pub(super) fn formation_status(&self) -> FormationStatus {
        // Where the airborne vehicles are now: a silent one's last position is not where
        // it is (a member riding through has flown on along its slot).
        let airborne: Vec<Ned> = self
            .vehicles
            .values()
            .filter(|v| v.state().is_airborne())
            .filter(|v| v.report().silence_now() <= PACE_SILENCE)
            .filter_map(|v| v.position())
            .collect();
        let whereabouts: BTreeMap<String, Whereabouts> = self
            .formation
            .absent_ids()
            .filter_map(|id| {
                let v = self.vehicles.get(id)?;
                let state = v.state();
                Some((
                    id.to_string(),
                    Whereabouts {
                        position: v.position(),
                        absence: absence_of(state, v.report().silence_now() >= LEADER_SILENCE),
                        state: state.name().to_string(),
                    },
                ))
            })
            .collect();
        self.formation.status_with(&airborne, &whereabouts)
    }

    /// `id` was commanded out of the formation (by the operator, or to an observation
    /// station): it is not an absent member (see [`crate::formation::AbsentMember`]).
    pub(super) fn released_from_formation(&mut self, id: &str, command: &Command) {
        if matches!(
            command,
            Command::Takeoff(_)
                | Command::Land
                | Command::Rtl
                | Command::Hold
                | Command::GoTo(_)
                | Command::LeaveFormation
                | Command::Disarm
                | Command::ForceDisarm(_)
        ) {
            self.formation.release(id);
        }
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
        // Members: the vehicles flying a slot, the silent ones within their ride-through
        // included (their agents fly them on their slots).
        let members: BTreeMap<String, Member> = self
            .vehicles
            .iter()
            .filter(|(_, v)| !v.failed)
            .filter_map(|(id, v)| {
                let r = v.formation_report()?;
                Some((
                    id.clone(),
                    Member {
                        position: v.position()?,
                        velocity: r.velocity,
                        heading_rad: r.heading_rad,
                        silence: r.silence_now(),
                        target: r.target,
                        ride_through: v.ride_through(),
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

/// Why a member that dropped out of the formation is out, from its state and whether it
/// has been silent for [`LEADER_SILENCE`] (its link not yet declared lost).
fn absence_of(state: VehicleState, silent: bool) -> Absence {
    match state {
        VehicleState::Lost => Absence::Lost,
        VehicleState::Failsafe => Absence::Failsafe,
        _ if silent => Absence::Silent,
        VehicleState::Hovering => Absence::Held,
        _ => Absence::Other,
    }
}
