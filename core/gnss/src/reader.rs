//! [`GnssReader`]: one GNSS source kept connected by a task of its own, and what it
//! last said ([`GnssState`]). The task opens the source (`session`), reads it until it
//! fails, closes or sends no report for [`STALL_TIMEOUT`], and opens it again after a
//! backoff of 1 s doubling to [`BACKOFF_MAX`] (back to 1 s once a connection delivered
//! a report). Readers of the state take a lock that the task holds only to copy a fix
//! in, never across a wait.

use crate::fix::{GnssFix, GnssReport};
use crate::session::{self, Ended};
use crate::source::GnssSource;
use std::fmt;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

/// The first wait before reopening the source.
pub const BACKOFF_MIN: Duration = Duration::from_secs(1);
/// The longest wait before reopening it: a receiver plugged back in, or gpsd
/// restarted, is read again within this.
pub const BACKOFF_MAX: Duration = Duration::from_secs(10);
/// No report (fix or no fix) for this long: the source is stalled and reopened.
/// Receivers report once a second or faster.
pub const STALL_TIMEOUT: Duration = Duration::from_secs(10);

/// What the reader knows now.
#[derive(Debug, Clone, PartialEq)]
pub struct GnssState {
    /// The source.
    pub source: GnssSource,
    /// A connection to the source is open.
    pub connected: bool,
    /// Why the last connection ended or could not open; `None` once a report arrives.
    pub error: Option<String>,
    /// The last valid fix and when it arrived (any age: the caller judges it).
    pub last_fix: Option<(GnssFix, Instant)>,
    /// When the receiver first said it has no fix after its last fix; `None` while its
    /// latest report is a fix.
    pub no_fix_since: Option<Instant>,
    /// Reports read (fix or no fix).
    pub reports: u64,
    /// Lines dropped as malformed (a bad checksum or field, JSON that does not parse, a
    /// line too long).
    pub malformed: u64,
    /// Connections opened.
    pub connects: u64,
}

impl GnssState {
    fn new(source: GnssSource) -> GnssState {
        GnssState {
            source,
            connected: false,
            error: None,
            last_fix: None,
            no_fix_since: None,
            reports: 0,
            malformed: 0,
            connects: 0,
        }
    }

    /// The age of the last fix at `now`; `None` before the first.
    pub fn fix_age(&self, now: Instant) -> Option<Duration> {
        self.last_fix
            .map(|(_, at)| now.saturating_duration_since(at))
    }
}

/// The state shared by the task and the readers.
#[derive(Debug)]
pub(crate) struct Shared(Mutex<GnssState>);

impl Shared {
    fn lock(&self) -> MutexGuard<'_, GnssState> {
        self.0.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// A connection is open.
    pub(crate) fn connected(&self) {
        let mut s = self.lock();
        s.connected = true;
        s.connects += 1;
    }

    /// The connection ended (why).
    pub(crate) fn ended(&self, why: String) {
        let mut s = self.lock();
        s.connected = false;
        s.error = Some(why);
    }

    /// A report arrived at `now`.
    pub(crate) fn report(&self, report: GnssReport, now: Instant) {
        let mut s = self.lock();
        s.reports += 1;
        s.error = None;
        match report {
            GnssReport::Fix(f) => {
                s.last_fix = Some((f, now));
                s.no_fix_since = None;
            }
            GnssReport::NoFix => {
                s.no_fix_since.get_or_insert(now);
            }
        }
    }

    /// A line was dropped; returns how many have been.
    pub(crate) fn malformed(&self) -> u64 {
        let mut s = self.lock();
        s.malformed += 1;
        s.malformed
    }

    fn reports(&self) -> u64 {
        self.lock().reports
    }
}

/// The process's GNSS source, read by a task (see the module docs). Clones share the
/// task; dropping the last stops it.
#[derive(Clone)]
pub struct GnssReader {
    inner: Arc<Inner>,
}

struct Inner {
    shared: Arc<Shared>,
    task: tokio::task::AbortHandle,
}

impl Drop for Inner {
    fn drop(&mut self) {
        self.task.abort();
    }
}

impl GnssReader {
    /// Starts reading `source` on the current tokio runtime.
    ///
    /// # Panics
    /// Outside a tokio runtime.
    pub fn start(source: GnssSource) -> GnssReader {
        let shared = Arc::new(Shared(Mutex::new(GnssState::new(source.clone()))));
        let task = tokio::spawn(keep_connected(source, shared.clone())).abort_handle();
        GnssReader {
            inner: Arc::new(Inner { shared, task }),
        }
    }

    /// A copy of what the reader knows now (never waits on the source).
    pub fn state(&self) -> GnssState {
        self.inner.shared.lock().clone()
    }
}

impl fmt::Debug for GnssReader {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_tuple("GnssReader")
            .field(&self.inner.shared.lock().source.to_string())
            .finish()
    }
}

impl PartialEq for GnssReader {
    /// The same reader (clones of one).
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.inner, &other.inner)
    }
}

/// Opens, reads and reopens `source` with backoff, for ever.
async fn keep_connected(source: GnssSource, shared: Arc<Shared>) {
    let mut backoff = BACKOFF_MIN;
    loop {
        let before = shared.reports();
        let why = match session::run(&source, &shared).await {
            Ended::Failed(why) => why,
            Ended::Stalled => format!("no report for {} s", STALL_TIMEOUT.as_secs()),
        };
        if shared.reports() > before {
            backoff = BACKOFF_MIN;
        }
        tracing::warn!(
            "operator GNSS {source}: {why}; reopening in {} s",
            backoff.as_secs()
        );
        shared.ended(why);
        tokio::time::sleep(backoff).await;
        backoff = (backoff * 2).min(BACKOFF_MAX);
    }
}
