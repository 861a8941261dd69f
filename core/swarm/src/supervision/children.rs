//! The children table: what every supervisor keeps of its children, written once.
//!
//! A supervisor (the Coordinator for vehicles and services, a Vehicle for its link and
//! payloads) spawns its children linked under itself and puts each in a [`Children`]
//! table under a key of its own ([`ChildKey`]: the child's path element and kind). The
//! table then does what is the same for every supervisor:
//!
//! - maps ractor's [`SupervisionEvent`]s back to the key, telling a hang (the watchdog
//!   killed it) from a panic or a stop ([`Children::ended`]);
//! - records the end in the [`Supervision`] registry and says what comes next by policy
//!   ([`Children::next`]): restart now, restart after a backoff, or escalate;
//! - pings every child each watchdog period and kills one that does not answer while the
//!   process runs on time ([`Children::watch`], [`Children::kill_hung`]);
//! - records a restart once the replacement answers its first ping
//!   ([`Children::started_after_failure`]), which is the restart latency the API shows.
//!
//! What a restart spawns and what an escalation does stay with each supervisor.

use super::policy::{Decision, Exit};
use super::registry::Supervision;
use ractor::{ActorCell, ActorId, ActorRef, Message, RpcReplyPort, SupervisionEvent};
use skein_model::supervision::ChildKind;
use std::collections::{BTreeMap, HashSet};
use std::future::Future;
use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How a supervisor names its children.
pub trait ChildKey: Clone + Ord + Send + Sync + 'static {
    /// The child's path under its supervisor's path (`coordinator/uav-1` →
    /// `coordinator/uav-1/px4link`).
    fn path(&self, parent: &str) -> String;
    /// Its kind (which restart policy applies).
    fn kind(&self) -> ChildKind;
}

type Ping = Arc<dyn Fn(Duration) -> Pin<Box<dyn Future<Output = Pinged> + Send>> + Send + Sync>;

/// A ping's outcome.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pinged {
    /// It answered within the deadline.
    Answered,
    /// It is alive but did not answer in time (hung).
    Timeout,
    /// It is gone (its end is reported through supervision).
    Gone,
}

/// A running child: its cell, and how to ping it whatever its message type.
#[derive(Clone)]
pub struct ChildHandle {
    cell: ActorCell,
    ping: Ping,
}

impl ChildHandle {
    /// `actor`, pinged with the message `ping` builds (its `Ping(RpcReplyPort<()>)`).
    pub fn new<M: Message>(actor: ActorRef<M>, ping: fn(RpcReplyPort<()>) -> M) -> Self {
        let cell = actor.get_cell();
        let ping: Ping = Arc::new(move |deadline| {
            let actor = actor.clone();
            Box::pin(async move {
                match actor.call(ping, Some(deadline)).await {
                    Ok(ractor::rpc::CallResult::Success(())) => Pinged::Answered,
                    Ok(ractor::rpc::CallResult::Timeout) => Pinged::Timeout,
                    _ => Pinged::Gone,
                }
            })
        });
        ChildHandle { cell, ping }
    }

    /// The child's cell.
    pub fn cell(&self) -> &ActorCell {
        &self.cell
    }

    /// The child as an actor of message type `M` (the type it was spawned with).
    pub fn actor<M: Message>(&self) -> ActorRef<M> {
        ActorRef::from(self.cell.clone())
    }
}

/// What the supervisor does next about an ended child (from [`Children::next`]).
#[derive(Debug, Clone, PartialEq)]
pub enum Next {
    /// Start it again now.
    RestartNow,
    /// Start it again after this backoff (the supervisor schedules itself a message).
    RestartAfter(Duration),
    /// The policy gave up (or says never): the supervisor escalates.
    Escalate,
    /// A clean stop the policy leaves stopped.
    Leave,
}

/// A supervisor's children (see the module docs).
pub struct Children<K: ChildKey> {
    parent: String,
    supervision: Arc<Supervision>,
    running: BTreeMap<K, ChildHandle>,
    /// Children the watchdog found hung and killed: their end is a hang, not a panic.
    hung: HashSet<ActorId>,
    /// Children with a ping outstanding.
    pinging: Arc<Mutex<HashSet<ActorId>>>,
}

impl<K: ChildKey> Children<K> {
    /// An empty table of the supervisor at `parent` (`"coordinator/uav-1"`).
    pub fn new(parent: impl Into<String>, supervision: Arc<Supervision>) -> Self {
        Children {
            parent: parent.into(),
            supervision,
            running: BTreeMap::new(),
            hung: HashSet::new(),
            pinging: Arc::default(),
        }
    }

    /// The supervisor's own path.
    pub fn parent(&self) -> &str {
        &self.parent
    }

    /// The registry.
    pub fn supervision(&self) -> &Arc<Supervision> {
        &self.supervision
    }

    /// `key`'s full path.
    pub fn path(&self, key: &K) -> String {
        key.path(&self.parent)
    }

    /// Puts a freshly spawned child in the table and marks it running in the registry.
    pub fn started(&mut self, key: K, child: ChildHandle) {
        self.supervision.started(&self.path(&key), key.kind());
        self.running.insert(key, child);
    }

    /// The running child under `key`.
    pub fn get(&self, key: &K) -> Option<&ChildHandle> {
        self.running.get(key)
    }

    /// The running child under `key` as an actor of message type `M`.
    pub fn actor<M: Message>(&self, key: &K) -> Option<ActorRef<M>> {
        self.running.get(key).map(ChildHandle::actor)
    }

    /// Keys of the running children.
    pub fn keys(&self) -> impl Iterator<Item = &K> {
        self.running.keys()
    }

    /// Running children.
    pub fn iter(&self) -> impl Iterator<Item = (&K, &ChildHandle)> {
        self.running.iter()
    }

    /// Takes `key` out of the table without a policy decision (it is being stopped on
    /// purpose); returns it.
    pub fn take(&mut self, key: &K) -> Option<ChildHandle> {
        self.running.remove(key)
    }

    /// Which of our running children ended, and how; `None` for an event about an actor
    /// that is not (or no longer) ours, such as a child already replaced. The child
    /// leaves the table.
    pub fn ended(&mut self, evt: &SupervisionEvent) -> Option<(K, Exit)> {
        let (id, failed) = match evt {
            SupervisionEvent::ActorFailed(cell, reason) => (cell.get_id(), Some(reason)),
            SupervisionEvent::ActorTerminated(cell, _, _) => (cell.get_id(), None),
            _ => return None,
        };
        let key = self
            .running
            .iter()
            .find(|(_, c)| c.cell.get_id() == id)
            .map(|(k, _)| k.clone())?;
        self.running.remove(&key);
        let exit = if self.hung.remove(&id) {
            Exit::Hung(self.supervision.config.watchdog_deadline())
        } else {
            match (failed, evt) {
                (Some(reason), _) => Exit::Failed(reason.to_string()),
                (None, SupervisionEvent::ActorTerminated(_, _, reason)) => {
                    Exit::Stopped(reason.clone())
                }
                _ => Exit::Stopped(None),
            }
        };
        Some((key, exit))
    }

    /// Records the end of `key` in the registry and says what to do by its policy.
    pub fn next(&self, key: &K, exit: Exit) -> Next {
        match self.supervision.exit(&self.path(key), key.kind(), exit) {
            Decision::Restart(d) if d.is_zero() => Next::RestartNow,
            Decision::Restart(d) => Next::RestartAfter(d),
            Decision::Escalate => Next::Escalate,
            Decision::Leave => Next::Leave,
        }
    }

    /// Puts the replacement of a failed child in the table; the restart (with its
    /// latency from `noticed`) is recorded once the replacement answers its first ping.
    pub fn started_after_failure(
        &mut self,
        key: K,
        child: ChildHandle,
        noticed: Instant,
        reason: String,
    ) {
        let path = self.path(&key);
        let kind = key.kind();
        let sup = self.supervision.clone();
        let deadline = sup.config.watchdog_deadline();
        let ping = child.ping.clone();
        self.started(key, child);
        tokio::spawn(async move {
            if ping(deadline).await == Pinged::Answered {
                sup.restarted(&path, kind, &reason, noticed.elapsed());
            }
        });
    }

    /// Pings every running child whose last ping has been answered; `on_hang(key, id)`
    /// for each that does not answer within the watchdog deadline while the process
    /// itself ran on time. A late answer while the whole process ran late (see
    /// [`crate::load`]) is counted, not punished: the child is pinged again next round.
    /// Runs as tasks: the supervisor never waits.
    pub fn watch(&self, on_hang: impl Fn(K, ActorId) + Clone + Send + Sync + 'static) {
        let deadline = self.supervision.config.watchdog_deadline();
        for (key, child) in &self.running {
            let id = child.cell.get_id();
            // One ping at a time per child: a late child is not sent a queue of them.
            if !self
                .pinging
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .insert(id)
            {
                continue;
            }
            let (key, ping) = (key.clone(), child.ping.clone());
            let (on_hang, pinging) = (on_hang.clone(), self.pinging.clone());
            let load = self.supervision.load.clone();
            tokio::spawn(async move {
                let sent = Instant::now();
                let pinged = ping(deadline).await;
                pinging
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .remove(&id);
                if pinged == Pinged::Timeout {
                    if load.lagging_since(sent) {
                        load.watchdog_late();
                    } else {
                        on_hang(key, id);
                    }
                }
            });
        }
    }

    /// Kills `key` if it is still the hung actor `id` (not a replacement); its end then
    /// counts as a hang.
    pub fn kill_hung(&mut self, key: &K, id: ActorId) {
        let current = self.running.get(key).filter(|c| c.cell.get_id() == id);
        if let Some(child) = current
            && self.hung.insert(id)
        {
            tracing::warn!("{} hung: killing it", self.path(key));
            child.cell.kill();
        }
    }
}
