//! Supervision: restart policies, the record of every failure, and the registry the API
//! shows as a tree.
//!
//! ractor reports a child's end to its supervisor and restarts nothing; the policy is
//! ours. Each supervisor (the Coordinator for vehicles and the API, each Vehicle for its
//! link and payloads) asks [`Supervision::exit`] what to do when a child ends:
//!
//! - policy `never`: escalate at the first failure;
//! - `on-failure`: restart after a panic, an error or a hang, not after a clean stop;
//! - `always`: restart after any end;
//! - at most `max_restarts` within `window_s`; one more failure escalates;
//! - backoff: the first restart in a window is immediate (a one-off failure costs
//!   microseconds), each further one waits `backoff_initial_ms × 2^(k−1)` capped at
//!   `backoff_max_ms`.
//!
//! Escalation depends on the kind (carried out by the supervisor): a payload is marked
//! failed and disabled while its vehicle flies on; a link that keeps failing fails its
//! Vehicle actor; a Vehicle actor that keeps failing gets its vehicle commanded to HOLD
//! (or LAND) through a separate link actor and is marked failed; the API failing for good
//! fails the coordinator, and the process exits non-zero for systemd or Docker to restart.
//!
//! Hangs: every supervisor pings its children every `watchdog_period_ms`; a child that
//! does not answer within `watchdog_deadline_ms` is killed and handled as a failure.

use crate::events::SwarmEvent;
use crate::metrics::Metrics;
use ractor::{ActorRef, Message, RpcReplyPort};
use serde::{Deserialize, Serialize};
use skein_model::supervision::{ChildKind, ChildStatus, RestartPolicy};
use std::collections::{BTreeMap, VecDeque};
use std::sync::{Arc, RwLock};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};
use tokio::sync::broadcast;

/// Restart policy of one kind of child.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PolicyConfig {
    /// When to restart.
    pub policy: RestartPolicy,
    /// Restarts allowed within `window_s`; one more failure escalates.
    pub max_restarts: u32,
    /// The sliding window of the budget, seconds.
    pub window_s: f64,
    /// Wait before the second restart in a window, ms (doubling after that).
    pub backoff_initial_ms: u64,
    /// Longest wait between restarts, ms.
    pub backoff_max_ms: u64,
}

impl Default for PolicyConfig {
    fn default() -> Self {
        PolicyConfig {
            policy: RestartPolicy::OnFailure,
            max_restarts: 5,
            window_s: 60.0,
            backoff_initial_ms: 100,
            backoff_max_ms: 5_000,
        }
    }
}

/// What the coordinator commands a vehicle whose actor keeps failing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VehicleEscalation {
    /// PX4 HOLD (loiter where it is).
    #[default]
    Hold,
    /// PX4 LAND.
    Land,
}

/// Supervision settings (`[supervision]` in the config file).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SupervisionConfig {
    /// Policy of Vehicle actors.
    pub vehicle: PolicyConfig,
    /// Policy of Px4Link actors.
    pub px4link: PolicyConfig,
    /// Policy of payload actors.
    pub payload: PolicyConfig,
    /// Policy of the API server actor.
    pub api: PolicyConfig,
    /// What a vehicle is commanded when its actor's budget is spent.
    pub vehicle_escalation: VehicleEscalation,
    /// How often supervisors ping their children, ms.
    pub watchdog_period_ms: u64,
    /// How long a child may take to answer a ping before it is declared hung, ms.
    pub watchdog_deadline_ms: u64,
}

impl Default for SupervisionConfig {
    fn default() -> Self {
        SupervisionConfig {
            vehicle: PolicyConfig::default(),
            px4link: PolicyConfig::default(),
            payload: PolicyConfig::default(),
            api: PolicyConfig::default(),
            vehicle_escalation: VehicleEscalation::Hold,
            watchdog_period_ms: 250,
            watchdog_deadline_ms: 2_000,
        }
    }
}

impl SupervisionConfig {
    /// The policy of a kind of child.
    pub fn policy(&self, kind: ChildKind) -> &PolicyConfig {
        match kind {
            ChildKind::Vehicle => &self.vehicle,
            ChildKind::Px4Link => &self.px4link,
            ChildKind::Payload => &self.payload,
            ChildKind::Api | ChildKind::Coordinator => &self.api,
        }
    }

    /// The watchdog deadline.
    pub fn watchdog_deadline(&self) -> Duration {
        Duration::from_millis(self.watchdog_deadline_ms)
    }

    /// The watchdog period.
    pub fn watchdog_period(&self) -> Duration {
        Duration::from_millis(self.watchdog_period_ms.max(10))
    }
}

/// How a child ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Exit {
    /// Panic or error, with its message.
    Failed(String),
    /// No answer to the watchdog within the deadline.
    Hung(Duration),
    /// Clean stop, with its reason if any.
    Stopped(Option<String>),
}

impl Exit {
    /// The reason as recorded.
    pub fn reason(&self) -> String {
        match self {
            Exit::Failed(r) => r.clone(),
            Exit::Hung(d) => format!(
                "hung: no answer to the watchdog within {} ms",
                d.as_millis()
            ),
            Exit::Stopped(Some(r)) => format!("stopped: {r}"),
            Exit::Stopped(None) => "stopped".into(),
        }
    }

    fn is_failure(&self) -> bool {
        !matches!(self, Exit::Stopped(_))
    }
}

/// What the supervisor does about an ended child.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Decision {
    /// Restart it after this delay.
    Restart(Duration),
    /// Its budget is spent (or the policy says never): escalate.
    Escalate,
    /// Leave it stopped.
    Leave,
}

/// One recorded failure.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FailureRecord {
    /// When, Unix time in ms.
    pub at_unix_ms: u64,
    /// Panic message, error, hang or stop reason.
    pub reason: String,
    /// Restarts of this child so far (before this failure's restart).
    pub restart_count: u32,
    /// Delay before the restart this failure causes, ms (`None` when not restarted).
    pub next_backoff_ms: Option<u64>,
}

/// A supervised child's record.
#[derive(Debug, Clone, Serialize)]
pub struct ChildRecord {
    /// Kind of actor.
    pub kind: ChildKind,
    /// Current status.
    pub status: ChildStatus,
    /// Restarts since it was first started.
    pub restarts: u32,
    /// The last failure, if any.
    pub last_failure: Option<FailureRecord>,
    /// Backoff of the pending or last restart, ms.
    pub backoff_ms: u64,
    /// Time from the failure being noticed to the replacement answering, µs (last restart).
    pub last_restart_latency_us: Option<u64>,
    /// Failures recorded (every kind of end that counted as one).
    pub failures: u64,
    #[serde(skip)]
    window: VecDeque<Instant>,
}

impl ChildRecord {
    /// A freshly started child.
    pub fn new(kind: ChildKind) -> Self {
        ChildRecord {
            kind,
            status: ChildStatus::Running,
            restarts: 0,
            last_failure: None,
            backoff_ms: 0,
            last_restart_latency_us: None,
            failures: 0,
            window: VecDeque::new(),
        }
    }

    /// Applies `policy` to an end of the child at `now` (`wall_ms` for the record).
    pub fn on_exit(
        &mut self,
        exit: &Exit,
        policy: &PolicyConfig,
        now: Instant,
        wall_ms: u64,
    ) -> Decision {
        let restart_wanted = match policy.policy {
            RestartPolicy::Never => false,
            RestartPolicy::OnFailure => exit.is_failure(),
            RestartPolicy::Always => true,
        };
        let counts = exit.is_failure() || restart_wanted;
        if exit.is_failure() {
            self.failures += 1;
        }
        let window = Duration::from_secs_f64(policy.window_s.max(0.0));
        while self
            .window
            .front()
            .is_some_and(|t| now.duration_since(*t) > window)
        {
            self.window.pop_front();
        }
        let decision = if !restart_wanted {
            if exit.is_failure() {
                Decision::Escalate
            } else {
                Decision::Leave
            }
        } else if self.window.len() as u32 >= policy.max_restarts {
            Decision::Escalate
        } else {
            let k = self.window.len() as u32; // restarts already in this window
            self.window.push_back(now);
            let backoff_ms = if k == 0 {
                0
            } else {
                policy
                    .backoff_initial_ms
                    .saturating_mul(1u64 << (k - 1).min(30))
                    .min(policy.backoff_max_ms)
            };
            Decision::Restart(Duration::from_millis(backoff_ms))
        };
        self.status = match decision {
            Decision::Restart(_) => ChildStatus::Restarting,
            Decision::Escalate => ChildStatus::Failed,
            Decision::Leave => ChildStatus::Stopped,
        };
        if let Decision::Restart(d) = decision {
            self.backoff_ms = d.as_millis() as u64;
        }
        if counts {
            self.last_failure = Some(FailureRecord {
                at_unix_ms: wall_ms,
                reason: exit.reason(),
                restart_count: self.restarts,
                next_backoff_ms: match decision {
                    Decision::Restart(d) => Some(d.as_millis() as u64),
                    _ => None,
                },
            });
        }
        decision
    }
}

/// A node of the supervision tree (`GET /api/v1/supervision`).
#[derive(Debug, Clone, Serialize)]
pub struct TreeNode {
    /// Last path element (`"px4link"`).
    pub name: String,
    /// Full path (`"coordinator/uav-1/px4link"`).
    pub path: String,
    /// The child's record.
    #[serde(flatten)]
    pub record: ChildRecord,
    /// Children.
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
    records: RwLock<BTreeMap<String, ChildRecord>>,
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
        metrics: Arc<Metrics>,
        events: broadcast::Sender<SwarmEvent>,
    ) -> Arc<Self> {
        let mut records = BTreeMap::new();
        records.insert(ROOT.to_string(), ChildRecord::new(ChildKind::Coordinator));
        Arc::new(Supervision {
            config,
            records: RwLock::new(records),
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
            let d = rec.on_exit(&exit, &policy, Instant::now(), wall_ms());
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

/// Pings `actor` with the message `ping` builds; calls `on_hang` when no answer arrives
/// within `deadline` (the actor is alive but stuck). Runs as a task: the caller never
/// waits.
pub fn watch<M: Message>(
    actor: ActorRef<M>,
    ping: fn(RpcReplyPort<()>) -> M,
    deadline: Duration,
    on_hang: impl FnOnce() + Send + 'static,
) {
    tokio::spawn(async move {
        // Answered, or the actor is gone (its end is reported by supervision): nothing.
        if let Ok(ractor::rpc::CallResult::Timeout) = actor.call(ping, Some(deadline)).await {
            on_hang();
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    fn policy(p: RestartPolicy, max: u32) -> PolicyConfig {
        PolicyConfig {
            policy: p,
            max_restarts: max,
            window_s: 10.0,
            backoff_initial_ms: 100,
            backoff_max_ms: 1_000,
        }
    }

    #[test]
    fn budget_and_capped_exponential_backoff() {
        let p = policy(RestartPolicy::OnFailure, 6);
        let mut r = ChildRecord::new(ChildKind::Payload);
        let t0 = Instant::now();
        let fail = Exit::Failed("boom".into());
        let delays: Vec<Decision> = (0..6).map(|_| r.on_exit(&fail, &p, t0, 0)).collect();
        assert_eq!(
            delays,
            [0, 100, 200, 400, 800, 1000]
                .map(|ms| Decision::Restart(Duration::from_millis(ms)))
                .to_vec()
        );
        assert_eq!(r.on_exit(&fail, &p, t0, 0), Decision::Escalate);
        assert_eq!(r.status, ChildStatus::Failed);
        let last = r.last_failure.clone().unwrap();
        assert_eq!((last.reason.as_str(), last.next_backoff_ms), ("boom", None));
        assert_eq!(r.failures, 7);
    }

    #[test]
    fn the_window_slides() {
        let p = policy(RestartPolicy::OnFailure, 2);
        let mut r = ChildRecord::new(ChildKind::Vehicle);
        let t0 = Instant::now();
        let fail = Exit::Failed("x".into());
        assert!(matches!(r.on_exit(&fail, &p, t0, 0), Decision::Restart(_)));
        assert!(matches!(r.on_exit(&fail, &p, t0, 0), Decision::Restart(_)));
        // 11 s later both have left the 10 s window: the budget is back, backoff restarts at 0.
        let later = t0 + Duration::from_secs(11);
        assert_eq!(
            r.on_exit(&fail, &p, later, 0),
            Decision::Restart(Duration::ZERO)
        );
    }

    #[test]
    fn policies_treat_stops_and_failures_differently() {
        let t0 = Instant::now();
        let stop = Exit::Stopped(Some("asked".into()));
        let hang = Exit::Hung(Duration::from_secs(2));
        let mut r = ChildRecord::new(ChildKind::Px4Link);
        assert_eq!(
            r.on_exit(&stop, &policy(RestartPolicy::OnFailure, 5), t0, 0),
            Decision::Leave
        );
        assert_eq!(r.status, ChildStatus::Stopped);
        assert!(r.last_failure.is_none(), "a clean stop is not a failure");
        assert_eq!(
            r.on_exit(&hang, &policy(RestartPolicy::OnFailure, 5), t0, 0),
            Decision::Restart(Duration::ZERO)
        );
        assert!(r.last_failure.as_ref().unwrap().reason.starts_with("hung"));
        let mut r = ChildRecord::new(ChildKind::Px4Link);
        assert_eq!(
            r.on_exit(&stop, &policy(RestartPolicy::Always, 5), t0, 0),
            Decision::Restart(Duration::ZERO)
        );
        let mut r = ChildRecord::new(ChildKind::Px4Link);
        assert_eq!(
            r.on_exit(
                &Exit::Failed("x".into()),
                &policy(RestartPolicy::Never, 5),
                t0,
                0
            ),
            Decision::Escalate
        );
        assert_eq!(
            ChildRecord::new(ChildKind::Api).on_exit(
                &stop,
                &policy(RestartPolicy::Never, 5),
                t0,
                0
            ),
            Decision::Leave
        );
    }

    #[test]
    fn registry_builds_the_tree() {
        let (tx, _) = broadcast::channel(16);
        let s = Supervision::new(SupervisionConfig::default(), Arc::new(Metrics::new()), tx);
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
