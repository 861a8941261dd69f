//! The supervision registry: every supervised path with its record, shown by the API as
//! a tree, and the watchdog's ping.

use super::policy::{ChildRecord, Decision, Exit, RestartBudget, SupervisionConfig};
use crate::events::SwarmEvent;
use crate::load::LoadMonitor;
use crate::metrics::Metrics;
use serde::Serialize;
use skein_model::supervision::{ChildKind, ChildStatus};
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, RwLock};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};
use tokio::sync::broadcast;

/// A node of the supervision tree (`GET /api/v1/supervision`).
#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
pub struct TreeNode {
    /// Last path element (`"px4link"`).
    pub name: String,
    /// Full path (`"coordinator/uav-1/px4link"`).
    pub path: String,
    /// The child's record.
    #[serde(flatten)]
    pub record: ChildRecord,
    /// Children.
    #[schema(no_recursion)]
    pub children: Vec<TreeNode>,
}

fn wall_ms() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64)
}

/// The shared supervision registry (paths → records), with the policies, metrics and
/// the event bus. Supervisors write; the API reads.
pub struct Supervision {
    /// The configuration.
    pub config: SupervisionConfig,
    /// How late the process runs (the watchdog does not count shared lateness as a hang).
    pub load: Arc<LoadMonitor>,
    records: RwLock<BTreeMap<String, ChildRecord>>,
    /// The restart rate limit of the whole tree.
    restarts: Mutex<RestartBudget>,
    metrics: Arc<Metrics>,
    events: broadcast::Sender<SwarmEvent>,
}

impl std::fmt::Debug for Supervision {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Supervision").finish_non_exhaustive()
    }
}

/// Root path of the tree.
pub const ROOT: &str = "coordinator";

impl Supervision {
    /// A registry with the root (`coordinator`) running.
    pub fn new(
        config: SupervisionConfig,
        load: Arc<LoadMonitor>,
        metrics: Arc<Metrics>,
        events: broadcast::Sender<SwarmEvent>,
    ) -> Arc<Self> {
        let mut records = BTreeMap::new();
        records.insert(ROOT.to_string(), ChildRecord::new(ChildKind::Coordinator));
        let restarts = Mutex::new(RestartBudget::new(
            config.max_restarts_per_s,
            config.restart_burst,
        ));
        Arc::new(Supervision {
            config,
            load,
            records: RwLock::new(records),
            restarts,
            metrics,
            events,
        })
    }

    /// Marks `path` running (a new child, or a restarted one; counters are kept).
    pub fn started(&self, path: &str, kind: ChildKind) {
        let mut r = self.records.write().expect("records lock");
        let rec = r
            .entry(path.to_string())
            .or_insert_with(|| ChildRecord::new(kind));
        rec.status = ChildStatus::Running;
    }

    /// Marks `path` waiting for a plugin ([`ChildStatus::WaitingForPlugin`]): not running,
    /// nothing failed, no restart budget spent.
    pub fn waiting(&self, path: &str, kind: ChildKind) {
        let mut r = self.records.write().expect("records lock");
        let rec = r
            .entry(path.to_string())
            .or_insert_with(|| ChildRecord::new(kind));
        rec.status = ChildStatus::WaitingForPlugin;
    }

    /// Forgets `path` and everything under it.
    pub fn remove(&self, path: &str) {
        let prefix = format!("{path}/");
        self.records
            .write()
            .expect("records lock")
            .retain(|k, _| k != path && !k.starts_with(&prefix));
    }

    /// Records an end of `path` and decides what to do (see module docs). Emits the
    /// failure on the event bus and counts it in the metrics.
    pub fn exit(&self, path: &str, kind: ChildKind, exit: Exit) -> Decision {
        let policy = *self.config.policy(kind);
        let (decision, record) = {
            let mut r = self.records.write().expect("records lock");
            let rec = r
                .entry(path.to_string())
                .or_insert_with(|| ChildRecord::new(kind));
            let now = Instant::now();
            let mut d = rec.on_exit(&exit, &policy, now, wall_ms());
            if let Decision::Restart(delay) = d {
                let at = self
                    .restarts
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .reserve(now + delay);
                let wait = at.saturating_duration_since(now);
                if wait > delay {
                    self.load.restart_deferred();
                    d = Decision::Restart(wait);
                    rec.backoff_ms = wait.as_millis() as u64;
                    if let Some(f) = rec.last_failure.as_mut() {
                        f.next_backoff_ms = Some(rec.backoff_ms);
                    }
                }
            }
            (d, rec.clone())
        };
        match &exit {
            Exit::Hung(_) => {
                self.metrics.hung(kind);
                self.metrics.failed(kind);
            }
            Exit::Failed(_) => self.metrics.failed(kind),
            Exit::Stopped(_) => {}
        }
        if decision == Decision::Escalate {
            self.metrics.escalated(kind);
        }
        tracing::warn!(
            "{path} ended ({}); {:?} after {} restarts",
            exit.reason(),
            decision,
            record.restarts
        );
        let _ = self.events.send(SwarmEvent::ActorFailed {
            path: path.to_string(),
            kind: kind.name().to_string(),
            reason: exit.reason(),
            restarts: record.restarts,
            next_backoff_ms: match decision {
                Decision::Restart(d) => Some(d.as_millis() as u64),
                _ => None,
            },
            escalated: decision == Decision::Escalate,
        });
        decision
    }

    /// Records that `path` was restarted and answered its first message `latency` after
    /// the failure was noticed.
    pub fn restarted(&self, path: &str, kind: ChildKind, reason: &str, latency: Duration) {
        let restarts = {
            let mut r = self.records.write().expect("records lock");
            let rec = r
                .entry(path.to_string())
                .or_insert_with(|| ChildRecord::new(kind));
            rec.status = ChildStatus::Running;
            rec.restarts += 1;
            rec.last_restart_latency_us = Some(latency.as_micros() as u64);
            rec.restarts
        };
        self.metrics.restarted(kind);
        let _ = self.events.send(SwarmEvent::ActorRestarted {
            path: path.to_string(),
            reason: reason.to_string(),
            restarts,
            latency_us: latency.as_micros() as u64,
        });
    }

    /// Marks `path` failed for good (after an escalation was carried out) and says what
    /// was done.
    pub fn escalated(&self, path: &str, action: &str) {
        if let Some(rec) = self.records.write().expect("records lock").get_mut(path) {
            rec.status = ChildStatus::Failed;
        }
        let _ = self.events.send(SwarmEvent::ActorEscalated {
            path: path.to_string(),
            action: action.to_string(),
        });
    }

    /// The record of `path`.
    pub fn record(&self, path: &str) -> Option<ChildRecord> {
        self.records
            .read()
            .expect("records lock")
            .get(path)
            .cloned()
    }

    /// Every path currently known.
    pub fn paths(&self) -> Vec<String> {
        self.records
            .read()
            .expect("records lock")
            .keys()
            .cloned()
            .collect()
    }

    /// The tree rooted at `coordinator`.
    pub fn tree(&self) -> TreeNode {
        let records = self.records.read().expect("records lock");
        fn build(path: &str, records: &BTreeMap<String, ChildRecord>) -> TreeNode {
            let prefix = format!("{path}/");
            let mut children: Vec<TreeNode> = records
                .keys()
                .filter(|k| {
                    k.strip_prefix(&prefix).is_some_and(|rest| {
                        // Direct children only; payload slots nest one level deeper
                        // ("payload/camera") but belong to the vehicle.
                        !rest.contains('/')
                            || rest.starts_with("payload/") && rest.matches('/').count() == 1
                    })
                })
                .map(|k| build(k, records))
                .collect();
            children.sort_by(|a, b| a.path.cmp(&b.path));
            TreeNode {
                name: path.rsplit('/').next().unwrap_or(path).to_string(),
                path: path.to_string(),
                record: records
                    .get(path)
                    .cloned()
                    .unwrap_or_else(|| ChildRecord::new(ChildKind::Coordinator)),
                children,
            }
        }
        let mut root = build(ROOT, &records);
        // Payload paths are `<vehicle>/payload/<slot>`: name them by their slot.
        fn rename(n: &mut TreeNode) {
            if n.path.contains("/payload/") {
                n.name = format!("payload/{}", n.name);
            }
            n.children.iter_mut().for_each(rename);
        }
        rename(&mut root);
        root
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::supervision::SupervisionConfig;
    use skein_model::supervision::ChildStatus;

    #[test]
    fn registry_builds_the_tree() {
        let (tx, _) = broadcast::channel(16);
        let s = Supervision::new(
            SupervisionConfig::default(),
            Arc::new(LoadMonitor::default()),
            Arc::new(Metrics::new()),
            tx,
        );
        s.started("coordinator/api", ChildKind::Api);
        s.started("coordinator/uav-1", ChildKind::Vehicle);
        s.started("coordinator/uav-1/px4link", ChildKind::Px4Link);
        s.started("coordinator/uav-1/payload/camera", ChildKind::Payload);
        assert_eq!(
            s.exit(
                "coordinator/uav-1/px4link",
                ChildKind::Px4Link,
                Exit::Failed("p".into())
            ),
            Decision::Restart(Duration::ZERO)
        );
        s.restarted(
            "coordinator/uav-1/px4link",
            ChildKind::Px4Link,
            "p",
            Duration::from_micros(40),
        );
        let t = s.tree();
        assert_eq!(t.name, "coordinator");
        let names: Vec<&str> = t.children.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["api", "uav-1"]);
        let uav = &t.children[1];
        let names: Vec<&str> = uav.children.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["payload/camera", "px4link"]);
        let link = &uav.children[1].record;
        assert_eq!((link.restarts, link.status), (1, ChildStatus::Running));
        assert_eq!(link.last_restart_latency_us, Some(40));
        s.remove("coordinator/uav-1");
        assert_eq!(s.tree().children.len(), 1);
    }
}
