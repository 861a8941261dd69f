//! The coordinator as a supervisor: it spawns the Vehicle actors of this process and the
//! services (the HTTP API) linked under itself, applies their restart policies through
//! the shared [`Children`](crate::supervision::Children) table, escalates a vehicle whose
//! budget is spent ([`super::escalation`]), and routes injected faults by path.

use super::CoordinatorState;
use super::messages::{AdminMsg, CoordinatorMsg, FaultError, FleetMsg, ServiceMsg};
use crate::protocol::Uplink;
use crate::supervision::{self, ChildHandle, ChildKey, Exit, Next};
use crate::vehicle::{Vehicle, VehicleArgs, VehicleMsg};
use ractor::{Actor, ActorProcessingErr, ActorRef, RpcReplyPort};
use skein_model::supervision::{ChildKind, FaultKind};
use std::cmp::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// How long a vehicle has to answer a fault-injection request about its children.
const VEHICLE_CALL_TIMEOUT: Duration = Duration::from_secs(2);

/// A child of the coordinator: a vehicle of this process, or a service.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Node {
    /// The Vehicle actor of this id.
    Vehicle(String),
    /// A service (`"api"`) of this kind.
    Service(String, ChildKind),
}

impl Node {
    /// The vehicle id or service name.
    pub fn name(&self) -> &str {
        match self {
            Node::Vehicle(n) | Node::Service(n, _) => n,
        }
    }
}

impl Ord for Node {
    fn cmp(&self, other: &Self) -> Ordering {
        let service = |n: &Node| matches!(n, Node::Service(..));
        self.name()
            .cmp(other.name())
            .then(service(self).cmp(&service(other)))
    }
}

impl PartialOrd for Node {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl ChildKey for Node {
    /// `coordinator/<id>` or `coordinator/<service>`.
    fn path(&self, parent: &str) -> String {
        format!("{parent}/{}", self.name())
    }

    fn kind(&self) -> ChildKind {
        match self {
            Node::Vehicle(_) => ChildKind::Vehicle,
            Node::Service(_, kind) => *kind,
        }
    }
}

impl CoordinatorState {
    /// Spawns `node` linked under the coordinator.
    async fn spawn(
        &mut self,
        myself: &ActorRef<CoordinatorMsg>,
        node: &Node,
    ) -> Result<ChildHandle, ActorProcessingErr> {
        match node {
            Node::Vehicle(id) => {
                let local = self
                    .vehicles
                    .get(id)
                    .and_then(|v| v.local.as_ref())
                    .ok_or_else(|| format!("{id} is not a vehicle of this process"))?;
                let (actor, _) = Actor::spawn_linked(
                    None,
                    Vehicle,
                    VehicleArgs {
                        shared: local.shared.clone(),
                        context: self.context.clone(),
                        fleet: self.fleet.reader(),
                        neighbours: self.neighbours.reader(id),
                        position: self.neighbours.slot(id),
                        events: self.events.clone(),
                        uplink: uplink_to(myself.clone()),
                        supervision: self.supervision.clone(),
                    },
                    myself.get_cell(),
                )
                .await?;
                local.port.set(Some(actor.clone()));
                Ok(ChildHandle::new(actor, VehicleMsg::Ping))
            }
            Node::Service(name, _) => {
                let spec = self
                    .services
                    .get(name)
                    .ok_or_else(|| format!("no service `{name}`"))?;
                let actor = (spec.spawn)(myself.get_cell()).await?;
                Ok(ChildHandle::new(actor, ServiceMsg::Ping))
            }
        }
    }

    /// Starts `node` for the first time.
    pub(super) async fn start_child(
        &mut self,
        myself: &ActorRef<CoordinatorMsg>,
        node: Node,
    ) -> Result<(), ActorProcessingErr> {
        let handle = self.spawn(myself, &node).await?;
        self.children.started(node, handle);
        Ok(())
    }

    /// Starts `node` again after a failure noticed at `noticed`.
    pub(super) async fn restart_child(
        &mut self,
        myself: &ActorRef<CoordinatorMsg>,
        node: Node,
        noticed: Instant,
        reason: String,
    ) -> Result<(), ActorProcessingErr> {
        match self.spawn(myself, &node).await {
            Ok(handle) => {
                self.children
                    .started_after_failure(node, handle, noticed, reason);
                Ok(())
            }
            Err(e) => {
                Box::pin(self.child_ended(
                    myself,
                    node,
                    Exit::Failed(format!("restart failed: {e}")),
                ))
                .await
            }
        }
    }

    /// Applies the policy to an ended child.
    pub(super) async fn child_ended(
        &mut self,
        myself: &ActorRef<CoordinatorMsg>,
        node: Node,
        exit: Exit,
    ) -> Result<(), ActorProcessingErr> {
        let noticed = Instant::now();
        if let Node::Vehicle(id) = &node
            && let Some(local) = self.vehicles.get(id).and_then(|v| v.local.as_ref())
        {
            local.port.set(None);
        }
        let path = self.children.path(&node);
        let reason = exit.reason();
        match (self.children.next(&node, exit), &node) {
            (Next::RestartNow, _) => self.restart_child(myself, node, noticed, reason).await?,
            (Next::RestartAfter(d), _) => {
                myself.send_after(d, move || {
                    AdminMsg::RestartChild(node, noticed, reason).into()
                });
            }
            // A vehicle left without its actor must not fly on unattended.
            (Next::Escalate | Next::Leave, Node::Vehicle(id)) => {
                let id = id.clone();
                self.escalate_vehicle(myself, &id).await;
            }
            (Next::Escalate, Node::Service(..)) => {
                return Err(format!(
                    "{path} keeps failing ({reason}): the coordinator gives up so that the \
                     process exits and its supervisor restarts it"
                )
                .into());
            }
            (Next::Leave, Node::Service(..)) => {}
        }
        Ok(())
    }

    /// Routes a fault to the actor at `path`.
    pub(super) fn inject(
        &self,
        myself: &ActorRef<CoordinatorMsg>,
        path: &str,
        kind: FaultKind,
        reply: RpcReplyPort<Result<(), FaultError>>,
    ) {
        if !self.context.config.fault_injection {
            let _ = reply.send(Err(FaultError::Disabled));
            return;
        }
        let unknown = || {
            FaultError::UnknownTarget(format!(
                "no actor `{path}` (known: {})",
                self.supervision.paths().join(", ")
            ))
        };
        let Some(rest) = path.strip_prefix(supervision::ROOT) else {
            let _ = reply.send(Err(unknown()));
            return;
        };
        if rest.is_empty() {
            let _ = reply.send(Ok(()));
            let _ = myself.cast(AdminMsg::Fault(kind).into());
            return;
        }
        let rest = rest.trim_start_matches('/');
        let (name, sub) = rest.split_once('/').unwrap_or((rest, ""));
        if kind == FaultKind::BypassGeofence
            && (!sub.is_empty() || !self.vehicles.contains_key(name))
        {
            let _ = reply.send(Err(FaultError::UnknownTarget(format!(
                "bypass_geofence is a vehicle's fault: target {}/<vehicle id>, not `{path}`",
                supervision::ROOT
            ))));
            return;
        }
        if let Some(spec) = self.services.get(name) {
            let node = Node::Service(name.to_string(), spec.kind);
            let r = match (self.children.actor::<ServiceMsg>(&node), sub) {
                (Some(a), "") => a
                    .cast(ServiceMsg::Fault(kind))
                    .map_err(|e| FaultError::Unreachable(e.to_string())),
                (None, "") => Err(FaultError::Unreachable(format!("{path} is not running"))),
                _ => Err(unknown()),
            };
            let _ = reply.send(r);
            return;
        }
        if !self.vehicles.contains_key(name) {
            let _ = reply.send(Err(unknown()));
            return;
        }
        let Some(a) = self
            .children
            .actor::<VehicleMsg>(&Node::Vehicle(name.to_string()))
        else {
            let _ = reply.send(Err(FaultError::Unreachable(format!(
                "{}/{name} is not running (restarting or failed)",
                supervision::ROOT
            ))));
            return;
        };
        // The vehicle answers (it knows its children).
        let sub = sub.to_string();
        tokio::spawn(async move {
            let r = match a
                .call(
                    |r| VehicleMsg::InjectFault(sub, kind, r),
                    Some(VEHICLE_CALL_TIMEOUT),
                )
                .await
            {
                Ok(ractor::rpc::CallResult::Success(Ok(()))) => Ok(()),
                Ok(ractor::rpc::CallResult::Success(Err(why))) => {
                    Err(FaultError::UnknownTarget(why))
                }
                _ => Err(FaultError::Unreachable("the vehicle did not answer".into())),
            };
            let _ = reply.send(r);
        });
    }
}

/// An uplink that posts a vehicle's protocol messages to the coordinator's mailbox.
pub fn uplink_to(coordinator: ActorRef<CoordinatorMsg>) -> Uplink {
    Arc::new(move |msg| {
        let _ = coordinator.cast(FleetMsg::FromVehicle(msg).into());
    })
}
