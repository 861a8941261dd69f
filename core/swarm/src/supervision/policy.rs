//! Restart policies: what a supervisor does when a child ends (see [`super`]), and the
//! record of each child's failures and restarts.

use serde::{Deserialize, Serialize};
use skein_model::supervision::{ChildKind, ChildStatus, RestartPolicy};
use std::collections::VecDeque;
use std::time::{Duration, Instant};

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
    /// Policy of the DDS link actor.
    pub dds: PolicyConfig,
    /// What a vehicle is commanded when its actor's budget is spent.
    pub vehicle_escalation: VehicleEscalation,
    /// How often supervisors ping their children, ms.
    pub watchdog_period_ms: u64,
    /// How long a child may take to answer a ping before it is declared hung, ms (while
    /// the whole process runs late, a late answer is not a hang: see [`crate::load`]).
    pub watchdog_deadline_ms: u64,
    /// Restarts per second the whole tree may make, on average ([`RestartBudget`]).
    pub max_restarts_per_s: f64,
    /// Restarts the whole tree may make at once before the rate applies.
    pub restart_burst: u32,
}

impl Default for SupervisionConfig {
    fn default() -> Self {
        SupervisionConfig {
            vehicle: PolicyConfig::default(),
            px4link: PolicyConfig::default(),
            payload: PolicyConfig::default(),
            api: PolicyConfig::default(),
            dds: PolicyConfig::default(),
            vehicle_escalation: VehicleEscalation::Hold,
            watchdog_period_ms: 250,
            watchdog_deadline_ms: 2_000,
            max_restarts_per_s: 10.0,
            restart_burst: 20,
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
            ChildKind::Dds => &self.dds,
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

/// The restart rate limit of the whole supervision tree: at most `burst` restarts at
/// once, then `rate_per_s` on average (a token bucket, kept as the time the bucket would
/// be full again). Each child's own budget ([`PolicyConfig`]) bounds how often *it* restarts;
/// this bounds the tree, so that many children failing together (the process short of
/// memory or CPU) restart at a pace the process can take instead of in a storm that makes
/// the next failures more likely. A restart over the limit is delayed, never dropped.
#[derive(Debug, Clone)]
pub struct RestartBudget {
    interval: Duration,
    burst: u32,
    /// When the bucket is full again (a past instant when it is full).
    full_at: Option<Instant>,
}

impl RestartBudget {
    /// A budget of `rate_per_s` restarts a second (at least one a minute) with bursts of
    /// `burst` (at least 1).
    pub fn new(rate_per_s: f64, burst: u32) -> Self {
        let rate = if rate_per_s.is_finite() {
            rate_per_s.max(1.0 / 60.0)
        } else {
            1e6
        };
        RestartBudget {
            interval: Duration::from_secs_f64(1.0 / rate),
            burst: burst.max(1),
            full_at: None,
        }
    }

    /// Reserves a restart wanted at `wanted`; returns when it may happen (`wanted` or
    /// later).
    pub fn reserve(&mut self, wanted: Instant) -> Instant {
        let full_at = self.full_at.map_or(wanted, |f| f.max(wanted));
        // The bucket holds `burst` restarts: it may be `burst - 1` intervals from full.
        let slack = self.interval * (self.burst - 1);
        let at = full_at.checked_sub(slack).map_or(wanted, |t| t.max(wanted));
        self.full_at = Some(full_at + self.interval);
        at
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
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
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
#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
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
    fn the_tree_restarts_a_burst_at_once_then_at_its_rate() {
        let mut b = RestartBudget::new(10.0, 3);
        let t0 = Instant::now();
        let at: Vec<Duration> = (0..6).map(|_| b.reserve(t0) - t0).collect();
        let ms: Vec<u128> = at.iter().map(|d| d.as_millis()).collect();
        assert_eq!(ms, vec![0, 0, 0, 100, 200, 300]);
        // After a quiet second the burst is available again.
        let later = t0 + Duration::from_secs(2);
        assert_eq!(b.reserve(later), later);
        assert_eq!(b.reserve(later), later);
        // A restart already delayed by its own backoff is not delayed further.
        let mut b = RestartBudget::new(1.0, 1);
        assert_eq!(b.reserve(t0), t0);
        let wanted = t0 + Duration::from_secs(5);
        assert_eq!(b.reserve(wanted), wanted);
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
}
