//! How late the process is running, and what it sheds when it cannot keep up.
//!
//! skein runs on companion computers with a fraction of a laptop's CPU. When the work
//! asked of it exceeds the CPU it gets, every actor is late, not one: a watchdog that
//! killed each actor whose ping came late would turn overload into an outage (each
//! restart adds work, which makes the next actor later). The [`LoadMonitor`] measures the
//! lateness the whole process shares, so that
//!
//! - the watchdog tells a hung actor (its ping is late while the process is on time) from
//!   a late one (the process is late too): see [`LoadMonitor::lagging_since`];
//! - a payload's driver call is given more time while the process lags;
//! - optional work yields ([`LoadMonitor::shedding`]): the dashboard's and DDS's rates, the
//!   snapshots the API shows; control (the vehicles' ticks, the setpoint streams, the
//!   formation) never does. What was shed is counted ([`ShedWork`]).
//!
//! Lateness is measured by two probes that sleep [`PROBE_PERIOD`] and note how late they
//! wake: a task on the runtime (how long a ready task waits for a worker) and a thread of
//! its own (how long the OS keeps a runnable thread off the CPU: other processes, a
//! cgroup CPU quota). The lag is the larger of the two.

use crate::ticker::Ticker;
use serde::Serialize;
use std::collections::{BTreeMap, VecDeque};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock, Weak};
use std::time::{Duration, Instant};

/// How often each probe wakes.
pub const PROBE_PERIOD: Duration = Duration::from_millis(50);
/// Lag above which the process counts as late for the watchdog and for payload driver
/// calls, ms (2.5 control periods at 50 Hz).
pub const LAGGING_MS: f64 = 50.0;
/// Lag (largest over [`SHED_ENTER_WINDOW`]) that starts shedding, ms.
pub const SHED_ENTER_MS: f64 = 40.0;
/// Shedding stops once the lag stayed under this for [`SHED_EXIT_WINDOW`], ms.
pub const SHED_EXIT_MS: f64 = 15.0;
/// Window of the lag that starts shedding.
pub const SHED_ENTER_WINDOW: Duration = Duration::from_secs(1);
/// Window of calm that ends shedding.
pub const SHED_EXIT_WINDOW: Duration = Duration::from_secs(3);
/// How long lag samples are kept (the longest window asked about).
const HISTORY: Duration = Duration::from_secs(30);

/// Optional work that yields when the process is short of CPU.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, strum::EnumIter)]
pub enum ShedWork {
    /// A vehicle snapshot for the API not refreshed (10 Hz → 2 Hz).
    Snapshots,
    /// A `vehicles` frame of the dashboard's stream not sent (10 Hz → 2 Hz).
    Dashboard,
    /// A DDS publishing round not made (ROS 2 topics at a fifth of their rate).
    Dds,
}

impl ShedWork {
    /// The name in `/metrics` (`work` label) and in [`LoadStatus::shed`].
    pub fn name(self) -> &'static str {
        match self {
            ShedWork::Snapshots => "snapshots",
            ShedWork::Dashboard => "dashboard",
            ShedWork::Dds => "dds",
        }
    }

    /// While shedding, one in this many rounds of the work is done.
    pub fn keep_one_in(self) -> u64 {
        5
    }
}

/// Whether the process keeps up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum LoadLevel {
    /// Every piece of work at its rate.
    Normal,
    /// Late: optional work runs at reduced rates (see [`ShedWork`]).
    Shedding,
}

/// The load as `GET /api/v1/health` and the dashboard show it.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct LoadStatus {
    /// `normal` or `shedding`.
    pub level: LoadLevel,
    /// How late the process runs now (largest probe lag of the last second), ms.
    pub lag_ms: f64,
    /// Largest lag of the last 30 s, ms.
    pub max_lag_ms: f64,
    /// Actor ticks skipped because the actor had not handled the previous one (since
    /// the start).
    pub tick_overruns: u64,
    /// Watchdog pings answered late while the whole process was late: not counted as
    /// hangs, nothing killed (since the start).
    pub watchdog_late: u64,
    /// Payload driver calls given more time because the process was late.
    pub calls_extended: u64,
    /// Restarts held back by the restart rate limit of the whole tree.
    pub restarts_deferred: u64,
    /// Times the process started shedding.
    pub shedding_episodes: u64,
    /// Units of optional work shed, by kind (`snapshots`, `dashboard`, `dds`).
    pub shed: BTreeMap<String, u64>,
    /// The scheduling the setpoint thread got (`realtime`: `SCHED_FIFO`; `nice`; or
    /// `refused`), once a setpoint stream has started (see `skein_link::priority`).
    pub setpoint_priority: Option<skein_link::priority::Priority>,
}

#[derive(Default)]
struct Samples {
    /// (when, lag ms), oldest first.
    lags: VecDeque<(Instant, f64)>,
    /// When each probe is due to wake next: a probe that has not woken yet is at least
    /// this late.
    due: [Option<Instant>; 2],
    shedding: bool,
}

/// The process's lag and shedding (see the module docs). One per swarm process.
pub struct LoadMonitor {
    samples: Mutex<Samples>,
    /// The process's clocks, for their tick overruns.
    ticker: OnceLock<Ticker>,
    shed: [AtomicU64; 3],
    watchdog_late: AtomicU64,
    calls_extended: AtomicU64,
    restarts_deferred: AtomicU64,
    episodes: AtomicU64,
}

impl std::fmt::Debug for LoadMonitor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LoadMonitor")
            .field("lag_ms", &self.lag_ms())
            .finish_non_exhaustive()
    }
}

impl Default for LoadMonitor {
    fn default() -> Self {
        LoadMonitor {
            samples: Mutex::new(Samples::default()),
            ticker: OnceLock::new(),
            shed: Default::default(),
            watchdog_late: AtomicU64::new(0),
            calls_extended: AtomicU64::new(0),
            restarts_deferred: AtomicU64::new(0),
            episodes: AtomicU64::new(0),
        }
    }
}

impl LoadMonitor {
    /// A monitor with its two probes running (the task on the current tokio runtime, if
    /// there is one). The probes stop when the monitor is dropped.
    pub fn start() -> Arc<Self> {
        let monitor = Arc::new(LoadMonitor::default());
        if let Ok(rt) = tokio::runtime::Handle::try_current() {
            rt.spawn(runtime_probe(Arc::downgrade(&monitor)));
        }
        let weak = Arc::downgrade(&monitor);
        // Without the thread the runtime probe still measures; nothing else depends on it.
        let _ = std::thread::Builder::new()
            .name("skein-load-probe".into())
            .spawn(move || thread_probe(weak));
        monitor
    }

    fn samples(&self) -> std::sync::MutexGuard<'_, Samples> {
        self.samples.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Records one probe's wake-up `lag` at `at` (probe 0: runtime, 1: thread) and when
    /// it is due next; updates the shedding level.
    fn record(&self, probe: usize, at: Instant, lag: Duration, next_due: Instant) {
        let mut s = self.samples();
        s.lags.push_back((at, lag.as_secs_f64() * 1e3));
        s.due[probe] = Some(next_due);
        while s
            .lags
            .front()
            .is_some_and(|(t, _)| at.duration_since(*t) > HISTORY)
        {
            s.lags.pop_front();
        }
        let recent = max_since(&s, at.checked_sub(SHED_ENTER_WINDOW), at);
        let calm = max_since(&s, at.checked_sub(SHED_EXIT_WINDOW), at);
        if !s.shedding && recent > SHED_ENTER_MS {
            s.shedding = true;
            self.episodes.fetch_add(1, Ordering::Relaxed);
            tracing::warn!("short of CPU (running {recent:.0} ms late): shedding optional work");
        } else if s.shedding && calm < SHED_EXIT_MS {
            s.shedding = false;
            tracing::info!("keeping up again: optional work back at its rates");
        }
    }

    /// Largest lag since `since` (both probes; a probe overdue now counts as late by
    /// how much it is overdue), ms.
    pub fn lag_since_ms(&self, since: Instant) -> f64 {
        max_since(&self.samples(), Some(since), Instant::now())
    }

    /// How late the process runs now: the largest lag of the last second, ms.
    pub fn lag_ms(&self) -> f64 {
        let now = Instant::now();
        max_since(
            &self.samples(),
            now.checked_sub(Duration::from_secs(1)),
            now,
        )
    }

    /// True when the process ran late (over [`LAGGING_MS`]) at some time since `since`:
    /// a late answer from an actor then is the process's lateness, not the actor's hang.
    pub fn lagging_since(&self, since: Instant) -> bool {
        self.lag_since_ms(since) > LAGGING_MS
    }

    /// The current level.
    pub fn level(&self) -> LoadLevel {
        if self.samples().shedding {
            LoadLevel::Shedding
        } else {
            LoadLevel::Normal
        }
    }

    /// True while optional work should yield.
    pub fn shedding(&self) -> bool {
        self.level() == LoadLevel::Shedding
    }

    /// Whether round `round` of optional `work` runs: every round normally, one in
    /// [`ShedWork::keep_one_in`] while shedding (the others are counted as shed).
    pub fn keep(&self, work: ShedWork, round: u64) -> bool {
        if !self.shedding() || round.is_multiple_of(work.keep_one_in()) {
            return true;
        }
        self.shed[work as usize].fetch_add(1, Ordering::Relaxed);
        false
    }

    /// Counts a watchdog ping that came late while the process was late.
    pub fn watchdog_late(&self) {
        self.watchdog_late.fetch_add(1, Ordering::Relaxed);
    }

    /// Counts a payload driver call given more time because the process was late.
    pub fn call_extended(&self) {
        self.calls_extended.fetch_add(1, Ordering::Relaxed);
    }

    /// Counts a restart held back by the tree's restart rate limit.
    pub fn restart_deferred(&self) {
        self.restarts_deferred.fetch_add(1, Ordering::Relaxed);
    }

    /// Units of `work` shed so far.
    pub fn shed_count(&self, work: ShedWork) -> u64 {
        self.shed[work as usize].load(Ordering::Relaxed)
    }

    /// Reports the tick overruns of `ticker` (the process's clocks) with the load.
    pub fn attach_ticker(&self, ticker: &Ticker) {
        let _ = self.ticker.set(ticker.clone());
    }

    /// The status to show.
    pub fn status(&self) -> LoadStatus {
        use strum::IntoEnumIterator;
        let now = Instant::now();
        let round = |x: f64| (x * 10.0).round() / 10.0;
        LoadStatus {
            level: self.level(),
            lag_ms: round(self.lag_ms()),
            max_lag_ms: round(max_since(&self.samples(), now.checked_sub(HISTORY), now)),
            tick_overruns: self.ticker.get().map_or(0, Ticker::overruns),
            watchdog_late: self.watchdog_late.load(Ordering::Relaxed),
            calls_extended: self.calls_extended.load(Ordering::Relaxed),
            restarts_deferred: self.restarts_deferred.load(Ordering::Relaxed),
            shedding_episodes: self.episodes.load(Ordering::Relaxed),
            shed: ShedWork::iter()
                .map(|w| (w.name().to_string(), self.shed_count(w)))
                .collect(),
            setpoint_priority: skein_link::priority::setpoint_priority(),
        }
    }
}

fn max_since(s: &Samples, since: Option<Instant>, now: Instant) -> f64 {
    let recorded = s
        .lags
        .iter()
        .rev()
        .take_while(|(t, _)| since.is_none_or(|since| *t >= since))
        .map(|(_, lag)| *lag)
        .fold(0.0, f64::max);
    let overdue = s
        .due
        .iter()
        .flatten()
        .map(|due| now.saturating_duration_since(*due).as_secs_f64() * 1e3)
        .fold(0.0, f64::max);
    recorded.max(overdue)
}

async fn runtime_probe(monitor: Weak<LoadMonitor>) {
    loop {
        let due = tokio::time::Instant::now() + PROBE_PERIOD;
        if let Some(m) = monitor.upgrade() {
            m.samples().due[0] = Some(due.into_std());
        }
        tokio::time::sleep_until(due).await;
        let now = tokio::time::Instant::now();
        let Some(m) = monitor.upgrade() else { return };
        m.record(
            0,
            now.into_std(),
            now - due,
            (now + PROBE_PERIOD).into_std(),
        );
    }
}

fn thread_probe(monitor: Weak<LoadMonitor>) {
    loop {
        let due = Instant::now() + PROBE_PERIOD;
        std::thread::sleep(PROBE_PERIOD);
        let now = Instant::now();
        let Some(m) = monitor.upgrade() else { return };
        m.record(
            1,
            now,
            now.saturating_duration_since(due),
            now + PROBE_PERIOD,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn monitor_with(lags_ms: &[(u64, f64)]) -> (LoadMonitor, Instant) {
        let m = LoadMonitor::default();
        let t0 = Instant::now();
        for &(at_ms, lag) in lags_ms {
            let at = t0 + Duration::from_millis(at_ms);
            m.record(0, at, Duration::from_secs_f64(lag / 1e3), at + PROBE_PERIOD);
        }
        (m, t0)
    }

    #[test]
    fn a_late_process_sheds_until_it_has_been_calm_for_a_while() {
        let (m, _) = monitor_with(&[(0, 1.0), (50, 2.0)]);
        assert_eq!(m.level(), LoadLevel::Normal);
        assert!(m.keep(ShedWork::Dashboard, 3));
        let (m, _) = monitor_with(&[(0, 1.0), (50, 120.0), (100, 5.0)]);
        assert_eq!(m.level(), LoadLevel::Shedding);
        // One round in five goes on; the others are counted.
        let kept = (0..10).filter(|r| m.keep(ShedWork::Dds, *r)).count();
        assert_eq!(kept, 2);
        assert_eq!(m.shed_count(ShedWork::Dds), 8);
        // Calm for less than the exit window: still shedding; then back to normal.
        let t0 = Instant::now();
        for i in 0..80u64 {
            let at = t0 + Duration::from_millis(200 + 50 * i);
            m.record(0, at, Duration::from_millis(2), at + PROBE_PERIOD);
            if i == 30 {
                assert_eq!(m.level(), LoadLevel::Shedding, "1.5 s of calm");
            }
        }
        assert_eq!(m.level(), LoadLevel::Normal);
        assert_eq!(m.status().shedding_episodes, 1);
    }

    #[test]
    fn lagging_is_judged_over_the_window_asked_about() {
        let (m, t0) = monitor_with(&[(0, 80.0), (1000, 3.0), (1050, 2.0)]);
        assert!(m.lagging_since(t0));
        assert!(!m.lagging_since(t0 + Duration::from_millis(500)));
    }

    #[test]
    fn a_probe_that_has_not_woken_counts_as_late() {
        let m = LoadMonitor::default();
        let now = Instant::now();
        m.samples().due[1] = now.checked_sub(Duration::from_millis(300));
        assert!(m.lag_ms() >= 300.0);
        assert!(m.lagging_since(now));
    }

    #[tokio::test]
    async fn both_probes_report() {
        let m = LoadMonitor::start();
        // Poll until both probes have reported a few times.
        let deadline = Instant::now() + Duration::from_secs(10);
        while m.samples().lags.len() < 6 {
            assert!(Instant::now() < deadline, "the probes did not report");
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        assert!(m.lag_ms().is_finite());
    }
}
