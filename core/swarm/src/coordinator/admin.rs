//! What the coordinator is told about itself ([`AdminMsg`]): supervision of its children
//! (watchdog ticks, hung and restarted children, services added; see [`super::supervisor`]),
//! injected faults, and the health, metrics and load it reports ([`super::status`]).

use super::messages::{CoordinatorMsg, FaultError, Health, ServiceSpec};
use super::{CoordinatorState, Node};
use crate::supervision;
use ractor::{ActorId, ActorProcessingErr, ActorRef, RpcReplyPort};
use skein_model::supervision::FaultKind;
use std::sync::Arc;
use std::time::Instant;

/// Messages about supervision, faults and the coordinator's own status (inside
/// [`CoordinatorMsg::Admin`]).
pub enum AdminMsg {
    /// Health.
    Health(RpcReplyPort<Health>),
    /// The metrics in Prometheus text format.
    RenderMetrics(RpcReplyPort<String>),
    /// The process's load monitor (services ask once, then read it directly to shed
    /// optional work, see [`crate::load`]).
    GetLoad(RpcReplyPort<Arc<crate::load::LoadMonitor>>),
    /// What the coordinator publishes for reads that do not wait in its mailbox
    /// ([`super::published`]); asked once, by [`super::Swarm::start`].
    GetReads(RpcReplyPort<super::SwarmReads>),
    /// Watchdog probe (the process watchdog pings the coordinator).
    Ping(RpcReplyPort<()>),
    /// Start and supervise a service (the HTTP API).
    AddService(ServiceSpec, RpcReplyPort<Result<(), String>>),
    /// Inject a fault at an actor path (`"coordinator/uav-1/px4link"`).
    InjectFault(String, FaultKind, RpcReplyPort<Result<(), FaultError>>),
    /// Fault injection into the coordinator itself.
    Fault(FaultKind),
    /// Time to ping the children.
    WatchTick,
    /// A child did not answer the watchdog.
    ChildHung(Node, ActorId),
    /// A child's backoff has passed.
    RestartChild(Node, Instant, String),
}

impl CoordinatorState {
    /// Handles an [`AdminMsg`].
    pub(super) async fn handle_admin(
        &mut self,
        myself: &ActorRef<CoordinatorMsg>,
        msg: AdminMsg,
    ) -> Result<(), ActorProcessingErr> {
        match msg {
            AdminMsg::Health(reply) => {
                let _ = reply.send(self.health());
            }
            AdminMsg::RenderMetrics(reply) => {
                let _ = reply.send(self.render_metrics());
            }
            AdminMsg::GetReads(reply) => {
                let _ = reply.send(self.published.reads());
            }
            AdminMsg::GetLoad(reply) => {
                let _ = reply.send(self.supervision.load.clone());
            }
            AdminMsg::Ping(reply) => {
                let _ = reply.send(());
            }
            AdminMsg::AddService(spec, reply) => {
                let name = spec.name.clone();
                let node = Node::Service(name.clone(), spec.kind);
                self.services.insert(name.clone(), spec);
                let r = self
                    .start_child(myself, node)
                    .await
                    .map_err(|e| format!("service `{name}` did not start: {e}"));
                let _ = reply.send(r);
            }
            AdminMsg::InjectFault(path, kind, reply) => self.inject(myself, &path, kind, reply),
            AdminMsg::Fault(kind) => {
                skein_link::fault::inject(kind, myself, supervision::ROOT).await?;
            }
            AdminMsg::WatchTick => {
                self.watch_gate.done();
                let me = myself.clone();
                self.children.watch(move |node, id| {
                    let _ = me.cast(AdminMsg::ChildHung(node, id).into());
                });
            }
            AdminMsg::ChildHung(node, id) => self.children.kill_hung(&node, id),
            AdminMsg::RestartChild(node, noticed, reason) => {
                let failed = self.vehicles.get(node.name()).is_some_and(|v| v.failed);
                if self.children.get(&node).is_none() && !failed {
                    self.restart_child(myself, node, noticed, reason).await?;
                }
            }
        }
        Ok(())
    }
}
