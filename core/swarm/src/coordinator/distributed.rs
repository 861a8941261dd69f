//! The coordinator's part in the distributed roles (`skein coordinator`, `skein agent`):
//! what the DDS carrier of the swarm protocol asks of it ([`DistributedMsg`]).
//!
//! - In a **coordinator**, a vehicle of another process (an agent's) joins as a remote
//!   [`VehicleProxy`]: a port that publishes [`ToVehicle`] on DDS, and the snapshots and
//!   reports the agent publishes. The formation, the API and the tracker use it like a
//!   local one; its supervision is its agent's.
//! - In an **agent**, the coordinator actor is the supervisor of the vehicles of this
//!   computer: the carrier hands it what the active coordinator sends them
//!   ([`DistributedMsg::ToLocalVehicle`]), taps what they answer
//!   ([`DistributedMsg::TapUplink`]), reads their reports, and gives it the other
//!   agents' vehicles as neighbours to keep separation from.
//! - A **standby** coordinator mirrors the active one's formation and flying mission and,
//!   once it holds the role, flies them on ([`DistributedMsg::ResumeFormation`],
//!   [`DistributedMsg::ResumeMission`]); one that steps down lets its own go
//!   ([`DistributedMsg::SteppedDown`]).

use super::CoordinatorState;
use super::proxy::VehicleProxy;
use crate::context::SwarmContext;
use crate::events::SwarmEvent;
use crate::formation::FormationMirror;
use crate::protocol::{FromVehicle, ToVehicle, VehiclePort, VehicleReport};
use ractor::RpcReplyPort;
use skein_model::fsm::VehicleState;
use skein_model::vehicle::VehicleSnapshot;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::{mpsc, watch};

/// A vehicle of another process, as its carrier delivers it.
pub struct RemoteVehicle {
    /// Vehicle id (`"uav-3"`).
    pub id: String,
    /// Where its [`ToVehicle`] messages go.
    pub port: Arc<dyn VehiclePort>,
    /// Its snapshots, swarm frame of this process.
    pub snapshots: watch::Receiver<VehicleSnapshot>,
    /// Its reports, swarm frame of this process.
    pub reports: watch::Receiver<VehicleReport>,
    /// Who runs it (the agent's id), for the log and the join event.
    pub agent: String,
}

/// Messages of the distributed roles (inside [`super::CoordinatorMsg::Distributed`]).
pub enum DistributedMsg {
    /// Coordinator: a vehicle of another process joins (ignored, and logged, when the id
    /// is taken).
    AddRemoteVehicle(RemoteVehicle),
    /// Agent: a message for a vehicle of this process (dropped when it has no such
    /// vehicle: the sample was for another agent's).
    ToLocalVehicle(String, ToVehicle),
    /// Agent: a copy of every [`FromVehicle`] of this process's vehicles goes here.
    TapUplink(mpsc::UnboundedSender<FromVehicle>),
    /// Agent: the latest report of every vehicle of this process, by id.
    ListReports(RpcReplyPort<Vec<(String, VehicleReport)>>),
    /// Agent: where a vehicle of another process is (its report, swarm frame of this
    /// process), for the separation check of this process's vehicles.
    Neighbour(String, VehicleReport),
    /// The swarm context (its frame, for the carrier's frame conversions).
    GetContext(RpcReplyPort<Arc<SwarmContext>>),
    /// Coordinator: the formation to mirror to the standbys (`None`: none is flown).
    GetFormationMirror(RpcReplyPort<Option<FormationMirror>>),
    /// Coordinator that just took the role: fly on the formation of the one it replaces
    /// (its id), as mirrored (positions in this process's frame), unless it flies one.
    ResumeFormation(FormationMirror, String),
    /// Coordinator: the flying mission to mirror to the standbys (`None`: none flies).
    GetMissionMirror(RpcReplyPort<Option<super::missions::MissionMirror>>),
    /// Coordinator that just took the role: fly on the mission of the one it replaces
    /// (its id), as mirrored (positions in this process's frame, stamp in its clock),
    /// unless one flies here.
    ResumeMission(Box<super::missions::MissionMirror>, String),
    /// Coordinator that lost the role (a handover, or the loser of two actives after a
    /// partition; the reason): it flies no formation of its own from now on. The active
    /// one flies it and this one mirrors it, to resume it should it claim the role again;
    /// a formation kept would go on ticking unheard, drift from the flown one (paced to a
    /// stop by members that follow another reference) and be flown instead of the mirror
    /// at the next claim.
    SteppedDown(String),
}

/// How often hovering remote vehicles are joined to an active formation again.
const REJOIN_PERIOD: Duration = Duration::from_secs(1);

/// How far a neighbour's report is moved on by its age (as the coordinator's own).
const NEIGHBOUR_EXTRAPOLATION: Duration = crate::protocol::REPORT_EXTRAPOLATION;

impl CoordinatorState {
    pub(super) fn on_distributed(&mut self, msg: DistributedMsg) {
        match msg {
            DistributedMsg::AddRemoteVehicle(r) => self.add_remote(r),
            DistributedMsg::ToLocalVehicle(id, msg) => {
                if let Some(v) = self.vehicles.get(&id).filter(|v| v.local.is_some())
                    && let Err(e) = v.send(msg)
                {
                    tracing::debug!("{id}: {e}");
                }
            }
            DistributedMsg::TapUplink(tap) => self.uplink_tap = Some(tap),
            DistributedMsg::ListReports(reply) => {
                let reports = self
                    .vehicles
                    .iter()
                    .filter(|(_, v)| v.local.is_some())
                    .map(|(id, v)| (id.clone(), v.report()))
                    .collect();
                let _ = reply.send(reports);
            }
            DistributedMsg::Neighbour(id, r) => {
                if self.vehicles.contains_key(&id) {
                    return; // a vehicle of this process: it reports itself
                }
                let measured = r
                    .position_now(NEIGHBOUR_EXTRAPOLATION)
                    .map(|p| (p, r.velocity));
                let setpoint = r.target.map(|t| (t, r.velocity));
                self.neighbours.slot(&id).set(
                    measured,
                    setpoint,
                    r.state == VehicleState::InFormation,
                );
            }
            DistributedMsg::GetContext(reply) => {
                let _ = reply.send(self.context.clone());
            }
            DistributedMsg::GetFormationMirror(reply) => {
                let _ = reply.send(self.formation.mirror());
            }
            DistributedMsg::ResumeFormation(mirror, from) => {
                if self.formation.is_active() {
                    tracing::warn!(
                        "the formation of `{from}` is not resumed: this coordinator flies one"
                    );
                    return;
                }
                tracing::warn!(
                    "resuming the formation of `{from}` ({:?}, {} members)",
                    mirror.spec.shape,
                    mirror.assignment.len()
                );
                self.formation
                    .resume(mirror, &self.context.geofence().fence);
                self.join_hovering();
                self.formation_changed();
            }
            DistributedMsg::GetMissionMirror(reply) => {
                let _ = reply.send(self.mission_mirror());
            }
            DistributedMsg::ResumeMission(mirror, from) => self.resume_mission(*mirror, &from),
            DistributedMsg::SteppedDown(reason) => {
                self.missions_stepped_down(&reason);
                if self.formation.is_active() {
                    tracing::warn!(
                        "the formation is left to the active coordinator: this one stepped \
                         down ({reason})"
                    );
                    self.formation.deactivate();
                    self.formation_changed();
                }
            }
        }
    }

    fn add_remote(&mut self, r: RemoteVehicle) {
        if self.vehicles.contains_key(&r.id) {
            tracing::error!(
                "{} of agent `{}` is not added: a vehicle of that id exists",
                r.id,
                r.agent
            );
            return;
        }
        let sysid = r.snapshots.borrow().sysid;
        let connection = format!("dds:{}", r.agent);
        self.vehicles.insert(
            r.id.clone(),
            VehicleProxy::remote(r.port, r.snapshots, r.reports),
        );
        self.metrics.vehicles.set(self.vehicles.len() as i64);
        self.publish_vehicles();
        tracing::info!("{} joined (sysid {sysid}, agent `{}`)", r.id, r.agent);
        self.emit(SwarmEvent::VehicleJoined {
            id: r.id,
            sysid,
            connection,
        });
    }

    /// Joins hovering remote vehicles to an active formation, once a second. The
    /// coordinator joins every vehicle that starts hovering (`on_state_changed`);
    /// for a remote vehicle that change can be missed (its agent held it during a
    /// partition, and the join sent when its reports came back reached the agent before
    /// the agent heard the coordinator's lease again, so it was not obeyed): this is the
    /// same rule, applied to the state rather than to its change.
    pub(super) fn rejoin_remote_hovering(&mut self) {
        if !self.formation.is_active() || self.last_rejoin.elapsed() < REJOIN_PERIOD {
            return;
        }
        self.last_rejoin = std::time::Instant::now();
        for (id, v) in &self.vehicles {
            if v.local.is_none()
                && !v.failed
                && v.state() == VehicleState::Hovering
                && !self.on_station(id)
            {
                self.internal_command(id, crate::protocol::Command::JoinFormation);
            }
        }
    }

    /// Copies a local vehicle's message to the tap (an agent's carrier).
    pub(super) fn tap(&self, msg: &FromVehicle) {
        let id = msg.vehicle_id();
        if let Some(tap) = &self.uplink_tap
            && self.vehicles.get(id).is_some_and(|v| v.local.is_some())
        {
            let _ = tap.send(msg.clone());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::DistributedMsg;
    use crate::coordinator::swarm::tests::swarm_on_udp;
    use crate::formation::{FormationMirror, LeaderMotion, Reference};
    use crate::protocol::wall_us;
    use skein_model::geo::Ned;
    use std::time::Duration;

    /// A line orbiting the swarm origin at 5 m/s, its reference at `north_m` now.
    fn orbiting(north_m: f64) -> FormationMirror {
        FormationMirror {
            spec: serde_json::from_value(serde_json::json!({
                "shape": "line", "spacing_m": 6.0, "leader": "virtual", "altitude_m": 12.0,
                "heading_deg": 0.0, "frame": "world", "offsets": []
            }))
            .unwrap(),
            reference: Reference {
                position: Ned::new(north_m, 0.0, -12.0),
                velocity: Ned::new(0.0, 5.0, 0.0),
                heading_rad: 0.0,
                heading_rate_rad_s: 0.0,
                motion: LeaderMotion::Orbit {
                    centre: Ned::new(0.0, 0.0, -12.0),
                    radius_m: north_m,
                    speed_m_s: 5.0,
                    clockwise: true,
                },
            },
            leader: None,
            pattern_heading_rad: None,
            assignment: Default::default(),
            stamp_us: wall_us(),
        }
    }

    /// The formation the coordinator would mirror now.
    async fn mirrored(swarm: &crate::Swarm) -> Option<FormationMirror> {
        swarm
            .coordinator
            .call(
                |r| DistributedMsg::GetFormationMirror(r).into(),
                Some(Duration::from_secs(5)),
            )
            .await
            .expect("the coordinator answers")
            .success_or(())
            .expect("an answer")
    }

    /// A coordinator that steps down lets its formation go, so that when it claims the
    /// role again it resumes the formation the active one flew meanwhile (its mirror),
    /// not its own, left ticking unheard while it stood by (which had drifted, paced to
    /// a stop, 18 m from where the members flew, in a test of five failovers).
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_coordinator_that_stepped_down_resumes_the_mirror_not_its_own_formation() {
        let swarm = swarm_on_udp().await;
        let cast = |m: DistributedMsg| swarm.coordinator.cast(m.into()).expect("cast");
        cast(DistributedMsg::ResumeFormation(
            orbiting(40.0),
            "gcs-b".into(),
        ));
        let own = mirrored(&swarm)
            .await
            .expect("the resumed formation is flown");
        assert!(
            (own.reference.position.north_m - 40.0).abs() < 1.0,
            "{own:?}"
        );

        cast(DistributedMsg::SteppedDown("handed over to gcs-a".into()));
        assert_eq!(mirrored(&swarm).await, None, "a standby flies no formation");

        cast(DistributedMsg::ResumeFormation(
            orbiting(60.0),
            "gcs-a".into(),
        ));
        let resumed = mirrored(&swarm).await.expect("the mirror is flown");
        assert!(
            (resumed.reference.position.north_m - 60.0).abs() < 1.0,
            "the old formation was flown on, not the mirror: {resumed:?}"
        );
        swarm.coordinator.stop(None);
    }
}
