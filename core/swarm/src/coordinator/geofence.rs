//! Changing the geofence while the swarm flies (`PUT /api/v1/geofence`), all or nothing:
//!
//! 1. the fence is checked ([`Geofence::validate`]: the field at fault);
//! 2. it is refused if it would leave a vehicle in the air outside (naming it), if
//!    another change is under way, or if a vehicle is flown by another process (an agent,
//!    whose fence this coordinator cannot change);
//! 3. every connected autopilot of this process is given it ([`Px4LinkMsg::TryFence`]:
//!    uploaded with the mission protocol, read back, `GF_ACTION` and `GF_MAX_VER_DIST`
//!    set), all at once, from a task;
//! 4. if every one holds it, it is committed: the context's fence changes (the setpoint
//!    shapers, the formation engine and the request checks read it at their next use),
//!    a [`SwarmEvent::GeofenceChanged`] goes to the stream and the recording;
//! 5. if any refused it (`MAV_MISSION_NO_SPACE`, `MAV_MISSION_ERROR`, a read-back that
//!    differs, a time-out), every vehicle tried is given the fence in force again (one
//!    may hold part of the new one: its fence but not its rally points) and the change is
//!    refused naming each vehicle and its reason: nothing half-applied.
//!
//! Vehicles not connected get the fence in force when they connect (their link follows
//! the context's plans).

use super::{CoordinatorMsg, CoordinatorState};
use crate::context::LiveFence;
use crate::events::SwarmEvent;
use crate::vehicle::VehicleMsg;
use ractor::rpc::CallResult;
use ractor::{ActorRef, RpcReplyPort};
use serde::Serialize;
use skein_link::Px4LinkMsg;
use skein_link::fence::FencePlan;
use skein_model::fsm::VehicleState;
use skein_model::geofence::{FenceStatus, FenceSyncState, FenceViolation, Geofence};
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Duration;

/// Longest wait for one vehicle's upload, read-back and parameters (the protocols' own
/// time-outs end a silent vehicle's well before).
const TRY_TIMEOUT: Duration = Duration::from_secs(60);

/// A geofence change that was committed: the fence, its version, and each connected
/// vehicle's autopilot status (all `synced`).
#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
pub struct FenceChange {
    /// The new version.
    pub version: u64,
    /// The fence now in force.
    pub fence: Geofence,
    /// Each vehicle given the fence, by id, with its autopilot's status.
    pub vehicles: BTreeMap<String, FenceStatus>,
}

/// Why a geofence change was refused.
#[derive(Debug, Clone, PartialEq)]
pub enum FenceRefusal {
    /// The fence is not valid: the field at fault and why (400).
    Invalid {
        /// The field (`"polygon"`, `"exclusions[1].circle"` …).
        field: String,
        /// Why.
        error: String,
    },
    /// The swarm's state forbids it (409): a vehicle in the air would be outside (the
    /// field of the rule it breaks), a change is under way, a vehicle refused the upload.
    Conflict {
        /// The field concerned, if one is.
        field: Option<String>,
        /// Why, naming the vehicles.
        error: String,
    },
}

/// A change waiting for its vehicles' uploads.
pub struct PendingFence {
    fence: Geofence,
    plan: Option<Arc<FencePlan>>,
    reply: RpcReplyPort<Result<FenceChange, FenceRefusal>>,
}

/// What the uploads of a change came to: each vehicle's status, and whether the fence in
/// force was given back to those that took it.
pub struct FenceTrial {
    results: BTreeMap<String, FenceStatus>,
}

/// Airborne as the FSM says, or lost (a vehicle unheard may still be in the air: a fence
/// that would leave it outside is refused).
fn maybe_airborne(state: VehicleState) -> bool {
    state.is_airborne() || state == VehicleState::Lost
}

fn field_of(v: FenceViolation) -> &'static str {
    match v {
        FenceViolation::Radius => "radius_m",
        FenceViolation::Polygon => "polygon",
        FenceViolation::Exclusion => "exclusions",
        FenceViolation::Ceiling => "max_altitude_m",
        FenceViolation::Floor => "min_altitude_m",
    }
}

/// Gives `plan` to the autopilot behind the vehicle actor `vehicle`.
async fn try_on(vehicle: Option<ActorRef<VehicleMsg>>, plan: Arc<FencePlan>) -> FenceStatus {
    let failed = |why: &str| FenceStatus {
        state: FenceSyncState::Failed,
        reason: Some(why.into()),
        ..FenceStatus::pending(plan.version, "")
    };
    let Some(vehicle) = vehicle else {
        return failed("the vehicle's actor is not running");
    };
    let link = match vehicle
        .call(VehicleMsg::GetLink, Some(Duration::from_secs(2)))
        .await
    {
        Ok(CallResult::Success(Some(link))) => link,
        _ => return failed("the vehicle's link is not running"),
    };
    let p = plan.clone();
    match link
        .call(|r| Px4LinkMsg::TryFence(p, r), Some(TRY_TIMEOUT))
        .await
    {
        Ok(CallResult::Success(status)) => status,
        _ => failed("no answer from the vehicle's link"),
    }
}

/// Messages about the geofence (inside [`CoordinatorMsg::Geofence`]).
pub enum GeofenceMsg {
    /// The geofence in force and its version (`GET /api/v1/geofence`).
    GetGeofence(RpcReplyPort<Arc<LiveFence>>),
    /// Put a new geofence in force (`PUT /api/v1/geofence`): checked, tried on every
    /// connected autopilot, committed or refused as a whole (see [`super::geofence`]).
    SetGeofence(Geofence, RpcReplyPort<Result<FenceChange, FenceRefusal>>),
    /// The vehicles' uploads of a geofence change came back (from its task).
    FenceTried(FenceTrial),
}

impl CoordinatorState {
    /// Handles a [`GeofenceMsg`].
    pub(super) fn handle_geofence(&mut self, myself: &ActorRef<CoordinatorMsg>, msg: GeofenceMsg) {
        match msg {
            GeofenceMsg::GetGeofence(reply) => {
                let _ = reply.send(self.geofence());
            }
            GeofenceMsg::SetGeofence(fence, reply) => self.set_geofence(myself, fence, reply),
            GeofenceMsg::FenceTried(trial) => self.fence_tried(trial),
        }
    }

    /// The geofence in force.
    pub(super) fn geofence(&self) -> Arc<LiveFence> {
        self.context.geofence()
    }

    /// `PUT /api/v1/geofence` (see the module docs): refused at once, committed at once
    /// (nothing to upload), or tried on the vehicles from a task that answers with
    /// [`GeofenceMsg::FenceTried`].
    pub(super) fn set_geofence(
        &mut self,
        myself: &ActorRef<CoordinatorMsg>,
        fence: Geofence,
        reply: RpcReplyPort<Result<FenceChange, FenceRefusal>>,
    ) {
        let refuse = |field: Option<&str>, error: String| FenceRefusal::Conflict {
            field: field.map(str::to_string),
            error,
        };
        if let Err((field, error)) = fence.validate() {
            let _ = reply.send(Err(FenceRefusal::Invalid { field, error }));
            return;
        }
        if self.fence_change.is_some() {
            let why = "another geofence change is being uploaded to the vehicles; try again";
            let _ = reply.send(Err(refuse(None, why.into())));
            return;
        }
        let mut targets = Vec::new();
        for (id, v) in &self.vehicles {
            let report = v.report();
            if maybe_airborne(report.state)
                && let Some(p) = report.position
            {
                let (q, violation) = fence.clamp(p, false);
                if let Some(kind) = violation
                    && (q - p).norm() > 1e-3
                {
                    let _ = reply.send(Err(refuse(
                        Some(field_of(kind)),
                        format!(
                            "{id} is in the air at ({:.1}, {:.1}) m, {:.1} m up, outside the new \
                             geofence ({}): land it or move it inside first",
                            p.north_m,
                            p.east_m,
                            -p.down_m,
                            kind.name()
                        ),
                    )));
                    return;
                }
            }
            let Some(local) = &v.local else {
                let _ = reply.send(Err(refuse(
                    None,
                    format!(
                        "{id} is flown by another process (an agent): its geofence cannot be \
                         changed from this coordinator"
                    ),
                )));
                return;
            };
            let connected = !local.shared.link.is_lost()
                && local.shared.link.with_telemetry(|t| t.heartbeat.is_some());
            if connected {
                targets.push((id.clone(), local.port.actor()));
            }
        }
        let version = self.geofence().version + 1;
        let plan = self.context.plan_of(&fence, version);
        let Some(candidate) = plan.clone().filter(|_| !targets.is_empty()) else {
            // No autopilot to give it to yet: they get it when they connect.
            self.fence_change = Some(PendingFence { fence, plan, reply });
            self.commit_geofence(BTreeMap::new());
            return;
        };
        self.fence_change = Some(PendingFence { fence, plan, reply });
        let me = myself.clone();
        tokio::spawn(async move {
            let tries = targets.into_iter().map(|(id, actor)| {
                let plan = candidate.clone();
                async move { (id, try_on(actor, plan).await) }
            });
            let results = join_all(tries).await;
            let _ = me.cast(
                GeofenceMsg::FenceTried(FenceTrial {
                    results: results.into_iter().collect(),
                })
                .into(),
            );
        });
    }

    /// The uploads of the pending change came back: commit, or give the fence in force
    /// back to those that took it and refuse.
    pub(super) fn fence_tried(&mut self, trial: FenceTrial) {
        let refused: Vec<String> = trial
            .results
            .iter()
            .filter(|(_, s)| s.state != FenceSyncState::Synced)
            .map(|(id, s)| {
                format!(
                    "{id}: {} ({})",
                    s.state.name(),
                    s.reason.as_deref().unwrap_or("no reason given")
                )
            })
            .collect();
        if refused.is_empty() {
            self.commit_geofence(trial.results);
            return;
        }
        let Some(pending) = self.fence_change.take() else {
            return;
        };
        let live = self.geofence();
        let tried: Vec<_> = trial
            .results
            .keys()
            .filter_map(|id| {
                let actor = self.vehicles.get(id)?.local.as_ref()?.port.actor();
                Some(actor)
            })
            .collect();
        let error = format!(
            "the geofence was not changed: {} (version {} stays in force, given back to every \
             vehicle tried)",
            refused.join("; "),
            live.version,
        );
        tracing::warn!("{error}");
        // Every vehicle tried gets the fence in force back, before the answer.
        let back = self.context.plan_of(&live.fence, live.version);
        tokio::spawn(async move {
            if let Some(plan) = back {
                join_all(tried.into_iter().map(|a| try_on(a, plan.clone()))).await;
            }
            let _ = pending
                .reply
                .send(Err(FenceRefusal::Conflict { field: None, error }));
        });
    }

    /// Puts the pending change in force and answers it.
    fn commit_geofence(&mut self, vehicles: BTreeMap<String, FenceStatus>) {
        let Some(pending) = self.fence_change.take() else {
            return;
        };
        let version = self
            .context
            .set_geofence(pending.fence.clone(), pending.plan);
        tracing::info!("geofence version {version} in force");
        self.emit(SwarmEvent::GeofenceChanged {
            version,
            fence: pending.fence.clone(),
        });
        let _ = pending.reply.send(Ok(FenceChange {
            version,
            fence: pending.fence,
            vehicles,
        }));
    }
}

/// Runs the futures concurrently and collects their outputs in order.
async fn join_all<F: std::future::Future + Send + 'static>(
    futures: impl IntoIterator<Item = F>,
) -> Vec<F::Output>
where
    F::Output: Send + 'static,
{
    let handles: Vec<_> = futures.into_iter().map(tokio::spawn).collect();
    let mut out = Vec::with_capacity(handles.len());
    for h in handles {
        if let Ok(v) = h.await {
            out.push(v);
        }
    }
    out
}
