//! A real video source as the camera sees it: a thread of its own receives and decodes
//! frames (an RTSP session, a ROS 2 image topic, a V4L2 device), keeps the newest one for
//! the camera to take, and reports its health ([`StreamStatus`]). [`VideoInput`] is the
//! camera's handle on it; the source's thread works through [`Shared`]. Every source
//! reconnects with the same backoff ([`MIN_BACKOFF`] doubling to [`MAX_BACKOFF`]).

use crate::recent::Recent;
use crate::scale::RgbFrame;
use crate::status::{Dropped, SourceState, StreamStatus};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use tokio::sync::Notify;

/// First wait before opening a failed source again; doubled after each failure.
pub const MIN_BACKOFF: Duration = Duration::from_millis(500);
/// Longest wait between attempts to open a source.
pub const MAX_BACKOFF: Duration = Duration::from_secs(5);
/// The longest a blocking source goes without checking whether the camera dropped it.
pub const BLOCKING_STEP: Duration = Duration::from_millis(100);
/// The window over which `stream_rate_hz` is measured.
const RATE_WINDOW: Duration = Duration::from_secs(3);

/// A decoded frame and when the camera captured it.
#[derive(Debug, Clone, PartialEq)]
pub struct DecodedFrame {
    /// The pixels, at the source's size.
    pub frame: RgbFrame,
    /// Capture time, wall-clock µs since the Unix epoch (the stream's timestamps, the
    /// message header's stamp or the driver's).
    pub capture_us: u64,
}

struct Health {
    status: StreamStatus,
    /// The frames decoded in the last [`RATE_WINDOW`].
    recent: Recent<()>,
}

/// What a source's thread shares with the camera: the newest frame, the health, and the
/// request to stop.
pub struct Shared {
    latest: Mutex<Option<DecodedFrame>>,
    health: Mutex<Health>,
    stop: AtomicBool,
    /// Woken when the camera drops the source: a thread waiting (for a frame, for its
    /// backoff) on it returns at once.
    pub wake: Notify,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panic elsewhere while holding the lock leaves the data as it was: still usable.
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

impl Shared {
    /// True once the camera dropped the source: the thread returns.
    pub fn stopping(&self) -> bool {
        self.stop.load(Ordering::SeqCst)
    }

    /// Frames decoded so far.
    pub fn frames_decoded(&self) -> u64 {
        lock(&self.health).status.frames_decoded
    }

    /// A new session (connection, subscription, device opening) begins: counted, and
    /// the state is `connecting` until the first frame ever.
    pub fn session_begins(&self) {
        let mut h = lock(&self.health);
        h.status.sessions += 1;
        if h.status.frames_decoded == 0 {
            h.status.state = SourceState::Connecting;
        }
    }

    /// A decoded frame: the newest, replacing one the camera has not taken (counted as
    /// superseded); the source is streaming.
    pub fn publish(&self, frame: RgbFrame, capture_us: u64) {
        let (w, h) = (frame.width_px, frame.height_px);
        let superseded = lock(&self.latest)
            .replace(DecodedFrame { frame, capture_us })
            .is_some();
        let now = Instant::now();
        let mut health = lock(&self.health);
        let s = &mut health.status;
        s.frames_decoded += 1;
        s.dropped.superseded += u64::from(superseded);
        s.stream_width_px = Some(w);
        s.stream_height_px = Some(h);
        s.state = SourceState::Streaming;
        s.detail = None;
        health.recent.push(now, ());
    }

    /// The session ended or could not start, for `why`: stalled once the source has
    /// streamed, else failed.
    pub fn lost(&self, why: String) {
        let mut h = lock(&self.health);
        h.status.state = if h.status.frames_decoded > 0 {
            SourceState::Stalled
        } else {
            SourceState::Failed
        };
        h.status.detail = Some(why);
    }

    /// Counts a dropped frame (or part of one) in `f`'s field.
    pub fn count(&self, f: impl FnOnce(&mut Dropped)) {
        f(&mut lock(&self.health).status.dropped);
    }

    /// After a session that began with `before` frames decoded and ended with `outcome`
    /// (`Err`: the reason; `Ok`: the source ended the stream): reports the source lost
    /// (the reason cleaned by `scrub`) and returns the wait before the next session, the
    /// backoff `backoff` holds, which it doubles for the time after (up to
    /// [`MAX_BACKOFF`]); a session that decoded frames starts it again from
    /// [`MIN_BACKOFF`].
    fn session_ended(
        &self,
        before: u64,
        outcome: Result<(), String>,
        scrub: impl Fn(String) -> String,
        backoff: &mut Duration,
    ) -> Duration {
        if self.frames_decoded() > before {
            *backoff = MIN_BACKOFF;
        }
        let wait = *backoff;
        let why = scrub(outcome.err().unwrap_or_else(|| "the stream ended".into()));
        self.lost(format!(
            "{why}; opening it again in {:.1} s",
            wait.as_secs_f64()
        ));
        *backoff = (wait * 2).min(MAX_BACKOFF);
        wait
    }

    /// Runs sessions one after the other until the camera drops the source: `session`
    /// returns why it ended, the source is reported lost and opened again after the
    /// backoff ([`MIN_BACKOFF`] doubling to [`MAX_BACKOFF`], from the start again after a
    /// session that decoded frames). `scrub` cleans a reason before it is shown
    /// (credentials in a URL).
    pub async fn sessions<F: Future<Output = Result<(), String>>>(
        &self,
        mut session: impl FnMut() -> F,
        scrub: impl Fn(String) -> String,
    ) {
        let mut backoff = MIN_BACKOFF;
        while !self.stopping() {
            self.session_begins();
            let before = self.frames_decoded();
            let outcome = tokio::select! {
                r = session() => r,
                () = self.wake.notified() => return,
            };
            if self.stopping() {
                return;
            }
            let wait = self.session_ended(before, outcome, &scrub, &mut backoff);
            tokio::select! {
                () = tokio::time::sleep(wait) => {}
                () = self.wake.notified() => return,
            }
        }
    }

    /// [`Shared::sessions`] for a source whose session blocks its thread (a V4L2 device):
    /// the session checks [`Shared::stopping`] itself, at least every
    /// [`BLOCKING_STEP`]; so does the wait between sessions.
    pub fn sessions_blocking(&self, mut session: impl FnMut() -> Result<(), String>) {
        let mut backoff = MIN_BACKOFF;
        while !self.stopping() {
            self.session_begins();
            let before = self.frames_decoded();
            let outcome = session();
            if self.stopping() {
                return;
            }
            let wait = self.session_ended(before, outcome, |why| why, &mut backoff);
            let until = Instant::now() + wait;
            while let Some(left) = until.checked_duration_since(Instant::now()) {
                if self.stopping() {
                    return;
                }
                std::thread::sleep(left.min(BLOCKING_STEP));
            }
        }
    }
}

/// The camera's handle on a running source. Dropping it stops the source's thread and
/// waits for it (a plugin's library must not be unloaded under a thread still running
/// its code).
pub struct VideoInput {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

impl VideoInput {
    /// Starts a source's thread `thread_name` running `run`, the source reported as
    /// `url` (without credentials) reached by `transport` (`"tcp"`, `"udp"`, `"dds"`,
    /// `"mmap"`).
    ///
    /// # Errors
    /// The thread could not be started.
    pub fn spawn(
        thread_name: &str,
        url: String,
        transport: &'static str,
        run: impl FnOnce(&Shared) + Send + 'static,
    ) -> Result<Self, String> {
        let status = StreamStatus {
            state: SourceState::Connecting,
            url,
            transport,
            detail: None,
            frames_decoded: 0,
            dropped: Dropped::default(),
            sessions: 0,
            stream_width_px: None,
            stream_height_px: None,
            stream_rate_hz: None,
            last_frame_age_ms: None,
        };
        let shared = Arc::new(Shared {
            latest: Mutex::new(None),
            health: Mutex::new(Health {
                status,
                recent: Recent::new(RATE_WINDOW),
            }),
            stop: AtomicBool::new(false),
            wake: Notify::new(),
        });
        let s = shared.clone();
        let thread = std::thread::Builder::new()
            .name(thread_name.into())
            .spawn(move || run(&s))
            .map_err(|e| format!("cannot start the {thread_name} thread: {e}"))?;
        Ok(VideoInput {
            shared,
            thread: Some(thread),
        })
    }

    /// The newest decoded frame not taken yet, taken (a later call gives it no more;
    /// `None` until a newer one is decoded).
    pub fn take_latest(&self) -> Option<DecodedFrame> {
        lock(&self.shared.latest).take()
    }

    /// The source's health now.
    pub fn status(&self) -> StreamStatus {
        let h = lock(&self.shared.health);
        let mut s = h.status.clone();
        s.last_frame_age_ms = h.recent.last_at().map(|t| t.elapsed().as_millis() as u64);
        s.stream_rate_hz = h.recent.rate_hz();
        s
    }
}

#[cfg(test)]
impl VideoInput {
    /// Polls the status until it is in `state` or `within` has passed; the last status.
    pub(crate) fn status_when(&self, state: SourceState, within: Duration) -> StreamStatus {
        let deadline = Instant::now() + within;
        loop {
            let s = self.status();
            if s.state == state || Instant::now() > deadline {
                return s;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }
}

impl Drop for VideoInput {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        self.shared.wake.notify_one();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// A single-threaded tokio runtime for a source's thread, or the reason (reported as the
/// source's failure) it could not be made.
pub fn runtime(shared: &Shared, what: &str) -> Option<tokio::runtime::Runtime> {
    match tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
    {
        Ok(rt) => Some(rt),
        Err(e) => {
            shared.lost(format!("no runtime for the {what}: {e}"));
            None
        }
    }
}
