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
//! The whole tree restarts at most `restart_burst` children at once and
//! `max_restarts_per_s` on average ([`RestartBudget`]): a restart over that is delayed.
//!
//! Hangs: every supervisor pings its children every `watchdog_period_ms`; a child that
//! does not answer within `watchdog_deadline_ms` is killed and handled as a failure,
//! unless the whole process ran late meanwhile ([`crate::load::LoadMonitor`]): then the
//! late answer is the process's lateness, not the child's hang, and nothing is killed.
//!
//! - [`policy`]: the policies and each child's record;
//! - [`registry`]: the shared registry and the tree the API shows;
//! - [`children`]: the children table every supervisor uses (spawned children, hung
//!   set, watchdog, restart probe);
//! - [`install_panic_hook`]: the cheap panic hook of every executable with actors.

pub mod children;
pub mod policy;
pub mod registry;

pub use children::{ChildHandle, ChildKey, Children, Next};
pub use policy::{
    ChildRecord, Decision, Exit, FailureRecord, PolicyConfig, RestartBudget, SupervisionConfig,
    VehicleEscalation,
};
pub use registry::{ROOT, Supervision, TreeNode};

/// A panic's message (`panic!`'s text), from its payload.
pub fn panic_text(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "non-string panic payload".into())
}

/// Replaces the process's panic hook by one that logs one line per panic (message and
/// place), no backtrace: supervised actors panic on purpose in fault tests, and the
/// default hook (with `RUST_BACKTRACE=1`) costs ~100 µs of restart latency. Every
/// executable that runs supervised actors (`skein`, `skein-bench`) installs it first.
pub fn install_panic_hook() {
    std::panic::set_hook(Box::new(|info| {
        let msg = panic_text(info.payload());
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        tracing::error!("panic: {msg}{at}");
    }));
}
