//! What the coordinator is told about the formation ([`FormationMsg`]): the operator's
//! requests (set, clear, leader motion, hazard cleared), checked against the
//! configuration, the geofence and the tracks, and the formation loop's tick.

use super::messages::FieldError;
use super::{CoordinatorState, track_leader, validation};
use crate::events::SwarmEvent;
use crate::formation::{FormationSpec, FormationStatus, LeaderMotion};
use crate::protocol::Command;
use ractor::RpcReplyPort;
use skein_model::fsm::VehicleState;
use skein_model::geo::Ned;

/// Messages about the formation (inside [`super::CoordinatorMsg::Formation`]).
pub enum FormationMsg {
    /// The formation.
    GetFormation(RpcReplyPort<FormationStatus>),
    /// Set the formation.
    SetFormation(
        FormationSpec,
        RpcReplyPort<Result<FormationStatus, FieldError>>,
    ),
    /// The operator says vehicle `id` is no longer a hazard; `Err(None)` when there is no
    /// such vehicle, `Err(Some(why))` when it is not a hazard.
    ClearHazard(String, RpcReplyPort<Result<(), Option<String>>>),
    /// Stop flying the formation (vehicles hold where they are).
    ClearFormation(RpcReplyPort<FormationStatus>),
    /// Move the formation's reference point (leader go-to, waypoints, orbit).
    LeaderMotion(
        LeaderMotion,
        RpcReplyPort<Result<FormationStatus, FieldError>>,
    ),
    /// Formation loop tick.
    FormationTick,
}

impl CoordinatorState {
    /// Handles a [`FormationMsg`].
    pub(super) fn handle_formation(&mut self, msg: FormationMsg) {
        match msg {
            FormationMsg::GetFormation(reply) => {
                let _ = reply.send(self.formation_status());
            }
            FormationMsg::SetFormation(spec, reply) => {
                let _ = reply.send(self.set_formation(spec));
            }
            FormationMsg::LeaderMotion(motion, reply) => {
                let _ = reply.send(self.leader_motion(motion));
            }
            FormationMsg::ClearHazard(id, reply) => {
                let _ = reply.send(self.clear_hazard(&id));
            }
            FormationMsg::ClearFormation(reply) => {
                let _ = reply.send(self.clear_formation());
            }
            FormationMsg::FormationTick => {
                self.formation_gate.done();
                self.rejoin_remote_hovering();
                self.follow_track_tick();
                self.formation_tick();
                self.observe_tick();
            }
        }
    }

    /// Checks `spec` and, if sound, flies it at once (hovering vehicles join).
    pub(super) fn set_formation(
        &mut self,
        spec: FormationSpec,
    ) -> Result<FormationStatus, FieldError> {
        let vehicles: Vec<validation::Candidate> = self
            .vehicles
            .iter()
            .map(|(id, v)| validation::Candidate {
                id: id.as_str(),
                state: v.state(),
                failed: v.failed,
                eph_m: v.snapshot().gps.and_then(|g| g.eph_m),
            })
            .collect();
        let shared = self.tracking.shared();
        let (tracks, swarms) = (shared.tracks(), shared.swarms());
        track_leader::validate_track_leader(&spec, &tracks, &swarms).and_then(|()| {
            validation::validate_formation(
                &self.context.config,
                &self.context.geofence().fence,
                &spec,
                &vehicles,
            )
        })?;
        self.formation.set(spec);
        self.join_hovering();
        self.follow_track_tick();
        self.formation_tick();
        let status = self.formation_status();
        self.emit(SwarmEvent::FormationChanged {
            formation: serde_json::to_value(&status).unwrap_or_default(),
        });
        Ok(status)
    }

    /// Checks `motion` and, if sound, moves the formation's reference point with it.
    pub(super) fn leader_motion(
        &mut self,
        mut motion: LeaderMotion,
    ) -> Result<FormationStatus, FieldError> {
        // A point without an altitude keeps the formation's.
        if let Some(down) = self
            .formation
            .status(&[])
            .reference
            .map(|r| r.position.down_m)
        {
            fill_altitude(&mut motion, down);
        }
        validation::validate_motion(
            &self.context.config,
            &self.context.geofence().fence,
            &motion,
        )
        .and_then(|()| {
            self.formation.set_motion(motion).map_err(|e| FieldError {
                field: "formation".into(),
                error: e,
            })
        })
        .map(|()| self.formation_status())
    }

    /// Stops flying the formation: its members leave it and hold where they are.
    pub(super) fn clear_formation(&mut self) -> FormationStatus {
        self.formation.deactivate();
        let members: Vec<String> = self
            .vehicles
            .iter()
            .filter(|(_, v)| v.state() == VehicleState::InFormation)
            .map(|(id, _)| id.clone())
            .collect();
        for id in members {
            self.internal_command(&id, Command::LeaveFormation);
        }
        let status = self.formation_status();
        self.emit(SwarmEvent::FormationChanged {
            formation: serde_json::to_value(&status).unwrap_or_default(),
        });
        status
    }
}

/// Gives the points of `motion` that have no altitude (NaN) the altitude `down_m`.
fn fill_altitude(motion: &mut LeaderMotion, down_m: f64) {
    let fill = |p: &mut Ned| {
        if p.down_m.is_nan() {
            p.down_m = down_m;
        }
    };
    match motion {
        LeaderMotion::Hold => {}
        LeaderMotion::GoTo { target, .. } => fill(target),
        LeaderMotion::Waypoints { points, .. } => points.iter_mut().for_each(fill),
        LeaderMotion::Orbit { centre, .. } => fill(centre),
    }
}
