//! [`RtkService`]: the corrections source of this process, kept connected. A task opens
//! the configured source ([`crate::session`]), reconnects after a failure or a stall with
//! capped exponential backoff (1 s doubling to 30 s, back to 1 s once a connection
//! delivered frames), and starts over when the source is changed or removed.
//!
//! In a distributed swarm ([`crate::relay`]) the service also feeds a relay: its source's
//! frames are tapped for the active coordinator to publish ([`RtkService::tap`]), and an
//! agent without a source of its own takes the relayed frames as its source
//! ([`RtkService::relayed`]): they are framed, checked and sent as a source's are, the
//! source is `dds:<topic>`, streaming until no frame came for the stall timeout (10 s).
//! A source of its own (`[rtk]`, `PUT`) takes precedence; removing it makes the relay the
//! source again.

use crate::config::{
    ConfigError, DEFAULT_MAX_BYTES_S, DEFAULT_STALL_TIMEOUT_S, RtkConfig, RtkSettings,
};
use crate::framer::{Frame, RtcmFramer};
use crate::hub::{Hub, Vehicles};
use crate::relay::{self, Relay, RelayRole, Relayed};
use crate::session::{self, Ended};
use crate::status::{RtkStatus, SourceState};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::{Notify, broadcast, watch};

/// The first wait before reconnecting.
pub const BACKOFF_MIN: Duration = Duration::from_secs(1);
/// The longest wait before reconnecting.
pub const BACKOFF_MAX: Duration = Duration::from_secs(30);

/// Where the service's corrections come from now.
#[derive(Debug, Clone)]
enum Mode {
    /// Nowhere: nothing is sent.
    Idle,
    /// This process's own source.
    Source(Arc<RtkSettings>),
    /// Frames relayed on this topic by another process.
    Relayed(String),
}

/// The corrections service (see the module docs). Dropping it stops its task.
pub struct RtkService {
    hub: Arc<Hub>,
    relay: Relay,
    /// A relayed frame arrived (the relay's stall watch).
    relayed_frame: Arc<Notify>,
    control: watch::Sender<Mode>,
}

impl RtkService {
    /// Starts the service's task on the current tokio runtime, with no source; corrections
    /// will go to `vehicles`.
    pub fn start(vehicles: Vehicles) -> Self {
        let hub = Hub::new(vehicles);
        let (control, mode) = watch::channel(Mode::Idle);
        let relayed_frame = Arc::new(Notify::new());
        let (h, arrived) = (hub.clone(), relayed_frame.clone());
        // Both end when the service is dropped (its mode's sender with it).
        tokio::spawn(async move {
            tokio::select! {
                _ = run(mode, h.clone(), arrived) => {}
                _ = h.pump_held_back() => {}
            }
        });
        RtkService {
            hub,
            relay: Relay::default(),
            relayed_frame,
            control,
        }
    }

    /// Uses `config`'s source from now on (`None`: stops sending corrections, or, in an
    /// agent that receives relayed frames, makes them the source again). A new source,
    /// or the same one given again, connects afresh.
    ///
    /// # Errors
    /// The field of `config` that is wrong; the current source is then kept.
    pub fn configure(&self, config: Option<&RtkConfig>) -> Result<(), ConfigError> {
        let settings = config.map(RtkConfig::settings).transpose()?;
        let receiving = self.relay.receiving_topic();
        match (settings, receiving) {
            (Some(s), topic) => {
                self.hub.reset(
                    Some(s.source.redacted()),
                    s.max_bytes_s,
                    s.stall_timeout.as_secs_f64(),
                );
                if let Some(t) = topic {
                    self.relay.set_role(&t, RelayRole::Ignoring);
                }
                self.control.send_replace(Mode::Source(Arc::new(s)));
            }
            (None, Some(topic)) => self.take_relayed(&topic),
            (None, None) => {
                self.hub.reset(None, DEFAULT_MAX_BYTES_S, 0.0);
                self.control.send_replace(Mode::Idle);
            }
        }
        Ok(())
    }

    /// The status now.
    pub fn status(&self) -> RtkStatus {
        RtkStatus {
            relay: self.relay.status(),
            ..self.hub.status()
        }
    }

    /// Every good frame of this process's own source from now on, as it goes to the
    /// vehicles (not the frames relayed to it): what the relay of the active coordinator
    /// publishes. A reader that falls more than [`crate::hub::TAP_DEPTH`] frames behind
    /// loses the oldest (`RecvError::Lagged`).
    pub fn tap(&self) -> broadcast::Receiver<Frame> {
        self.hub.tap()
    }

    /// This process publishes its source's frames on `topic` while it is the active
    /// coordinator (`active`), or would once active: the status's `relay` says which.
    pub fn relay_publisher(&self, topic: &str, active: bool) {
        let role = if active {
            RelayRole::Publishing
        } else {
            RelayRole::Standby
        };
        self.relay.set_role(topic, role);
    }

    /// Counts `frames` of the source published on the relay topic and `failures` that
    /// were not (a failed write, frames lost by a publisher that fell behind).
    pub fn relay_published(&self, frames: u64, failures: u64) {
        self.relay.count_published(frames, failures);
    }

    /// This process takes the frames relayed on `topic` ([`RtkService::relayed`]) as its
    /// source whenever it has none of its own: from now on if it has none, its status's
    /// source is `dds:<topic>` (connecting until the first frame). Saying it again
    /// changes nothing.
    pub fn relay_receiver(&self, topic: &str) {
        if self.relay.receiving_topic().as_deref() == Some(topic) {
            return;
        }
        if matches!(*self.control.borrow(), Mode::Source(_)) {
            self.relay.set_role(topic, RelayRole::Ignoring);
        } else {
            self.take_relayed(topic);
        }
    }

    /// One sample relayed on the topic: its bytes are framed and checked like a source's
    /// (the sample is whole: a partial frame at its end is garbage), and its good frames
    /// go to every vehicle of this process as a source's do (cap, pacing, counters; the
    /// status counts the bytes, frames, bad CRCs, message types and base station).
    /// Ignored (counted) while this process has a source of its own or takes no relayed
    /// frames; without a good frame, counted as malformed and dropped.
    pub fn relayed(&self, bytes: &[u8]) -> Relayed {
        if !matches!(*self.control.borrow(), Mode::Relayed(_)) {
            self.relay.count_ignored();
            return Relayed::Ignored;
        }
        let (frames, counts) = self.relay.frame(bytes);
        self.hub.received(bytes.len(), &counts);
        if frames.is_empty() {
            return Relayed::Malformed;
        }
        for f in &frames {
            self.hub.deliver_relayed(f);
        }
        self.relayed_frame.notify_one();
        Relayed::Delivered(frames.len())
    }

    /// Makes the frames relayed on `topic` the source, afresh.
    fn take_relayed(&self, topic: &str) {
        self.relay.set_role(topic, RelayRole::Receiving);
        self.relay.restart_framing();
        self.hub.reset(
            Some(relay::source_name(topic)),
            DEFAULT_MAX_BYTES_S,
            DEFAULT_STALL_TIMEOUT_S,
        );
        // Waiting for the first frame (here, not in the task: a frame may come first).
        self.hub.connecting();
        self.control.send_replace(Mode::Relayed(topic.to_string()));
    }
}

async fn run(mut mode: watch::Receiver<Mode>, hub: Arc<Hub>, relayed_frame: Arc<Notify>) {
    loop {
        let current = mode.borrow_and_update().clone();
        let source = async {
            match &current {
                Mode::Idle => std::future::pending().await,
                Mode::Source(s) => keep_connected(s, &hub).await,
                Mode::Relayed(topic) => watch_relayed(topic, &hub, &relayed_frame).await,
            }
        };
        tokio::select! {
            _ = source => {}
            changed = mode.changed() => {
                if changed.is_err() {
                    return;
                }
            }
        }
    }
}

/// Relayed frames as the source: stalled when none came for the stall timeout (from the
/// last one, or from the start), streaming again at the next ([`Hub::deliver_relayed`]).
async fn watch_relayed(topic: &str, hub: &Hub, relayed_frame: &Notify) {
    let stall = Duration::from_secs_f64(DEFAULT_STALL_TIMEOUT_S);
    loop {
        if tokio::time::timeout(stall, relayed_frame.notified())
            .await
            .is_ok()
        {
            continue;
        }
        let why = format!("no RTCM frame on {topic} for {:.0} s", stall.as_secs_f64());
        tracing::warn!("RTK corrections relayed on {topic}: {why}");
        hub.set_state(SourceState::Stalled, Some(why));
        relayed_frame.notified().await;
    }
}

/// Connects, reads, and reconnects with backoff, for ever.
async fn keep_connected(s: &RtkSettings, hub: &Hub) {
    let mut framer = RtcmFramer::default();
    let mut backoff = BACKOFF_MIN;
    let source = s.source.redacted();
    loop {
        hub.connecting();
        let frames_before = framer.counts().frames;
        let ended = session::run(s, hub, &mut framer).await;
        framer.reset();
        if framer.counts().frames > frames_before {
            backoff = BACKOFF_MIN;
        }
        let (state, why) = match ended {
            Ended::Failed(e) => (SourceState::Failed, e),
            Ended::Stalled(e) => (SourceState::Stalled, e),
        };
        tracing::warn!(
            "RTK corrections from {source}: {why}; reconnecting in {:.0} s",
            backoff.as_secs_f64()
        );
        hub.set_state(state, Some(why));
        tokio::time::sleep(backoff).await;
        backoff = (backoff * 2).min(BACKOFF_MAX);
    }
}
