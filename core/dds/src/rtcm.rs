//! RTK corrections relayed over DDS, so that one source serves a distributed swarm: the
//! active coordinator publishes every good RTCM3 frame of its corrections source on
//! `/skein/rtcm` (`rtcm_msgs/Message`, one frame a sample, QoS in [`crate::topics`]), and
//! every agent takes them as its own source when it has none, sending them to its
//! vehicles exactly as local corrections ([`skein_rtk::relay`]).
//!
//! - [`publish`] (a coordinator candidate, `skein up --dds`): a candidate publishes only
//!   while the election makes it active, so a standby with the same `[rtk]` (its source
//!   kept connected) never doubles the stream, and a failover moves the publishing with
//!   the role (no two are active at once but in a healed partition, [`crate::lease`]);
//!   `skein up --dds` is always active.
//! - [`receive`] (an agent): every sample's bytes go to the corrections service, which
//!   frames and checks them (CRC-24Q) and sends the good frames to the vehicles; a
//!   sample without a good frame is counted (here as `malformed`, and in the service's
//!   status) and dropped; while the agent has a source of its own the samples are
//!   ignored (its status says so).
//!
//! Any `rtcm_msgs/Message` writer on the topic feeds the agents, ROS 2's `ntrip_client`
//! remapped onto it too; under DDS Security only coordinators may write it
//! ([`crate::security::policy`]). The role reaches the corrections service through an
//! [`RtcmContext`], implemented here by [`RtkService`].

use crate::carrier::{Carrier, TopicReader, TopicWriter};
use crate::counters::DdsCounters;
use crate::error::DdsError;
use crate::msgs::{Header, RtcmMessage};
use crate::topics;
use ros2_client::builtin_interfaces::Time;
use skein_rtk::framer::Frame;
use skein_rtk::{Relayed, RtkService};
use skein_swarm::election::{CoordinatorRole, ElectionStatus};
use std::sync::Arc;
use tokio::sync::broadcast::error::RecvError;
use tokio::sync::{broadcast, watch};

/// What the relay needs from this process's corrections service.
pub trait RtcmContext: Send + Sync + 'static {
    /// Every good frame of this process's own source from now on (not relayed ones).
    fn source_frames(&self) -> broadcast::Receiver<Frame>;

    /// This process publishes its source's frames on `topic` now (`active`), or will
    /// once active.
    fn publishing(&self, topic: &str, active: bool);

    /// `frames` of the source were published, `failures` were not.
    fn published(&self, frames: u64, failures: u64);

    /// This process takes the frames of `topic` as its source when it has none.
    fn receiving(&self, topic: &str);

    /// One sample's `message` bytes, for the vehicles.
    fn relayed(&self, message: &[u8]) -> Relayed;
}

/// The publishing side: `/skein/rtcm`'s writer.
pub struct RtcmPublisher {
    writer: TopicWriter<RtcmMessage>,
}

impl RtcmPublisher {
    /// Opens `/skein/rtcm` for writing on `carrier`, counting in `counters`.
    ///
    /// # Errors
    /// The topic or writer could not be created (DDS Security: a role that may not).
    pub fn open(carrier: &impl Carrier, counters: &Arc<DdsCounters>) -> Result<Self, DdsError> {
        Ok(RtcmPublisher {
            writer: TopicWriter::open(carrier, &topics::rtcm(), counters)?,
        })
    }
}

/// The receiving side: `/skein/rtcm`'s reader.
pub struct RtcmReceiver {
    reader: TopicReader<RtcmMessage>,
    counters: Arc<DdsCounters>,
}

impl RtcmReceiver {
    /// Opens `/skein/rtcm` for reading on `carrier`, counting in `counters`.
    ///
    /// # Errors
    /// The topic or reader could not be created.
    pub fn open(carrier: &impl Carrier, counters: &Arc<DdsCounters>) -> Result<Self, DdsError> {
        Ok(RtcmReceiver {
            reader: TopicReader::open(carrier, &topics::rtcm(), counters, "RTCM sample")?,
            counters: counters.clone(),
        })
    }
}

/// Whether this process publishes now: always without an election (`skein up --dds`),
/// else while its candidate is active.
fn active(election: &Option<watch::Receiver<ElectionStatus>>) -> bool {
    election
        .as_ref()
        .is_none_or(|e| e.borrow().role == CoordinatorRole::Active)
}

/// The next change of the election's status; never without an election (or once it is
/// gone).
async fn election_changed(election: &mut Option<watch::Receiver<ElectionStatus>>) {
    if let Some(e) = election
        && e.changed().await.is_ok()
    {
        return;
    }
    std::future::pending().await
}

/// Publishes every frame of the source while active (see the module docs) until the task
/// is aborted or the source's tap closes; `election` is this candidate's status (`None`:
/// always active).
pub async fn publish<C: RtcmContext + ?Sized>(
    publisher: Arc<RtcmPublisher>,
    mut election: Option<watch::Receiver<ElectionStatus>>,
    ctx: Arc<C>,
) {
    let topic = topics::rtcm().to_string();
    let mut frames = ctx.source_frames();
    let mut was_active = active(&election);
    ctx.publishing(&topic, was_active);
    loop {
        tokio::select! {
            frame = frames.recv() => {
                // The status now, not as last seen: no frame goes out after a step-down.
                let now_active = active(&election);
                match frame {
                    Ok(f) if now_active => {
                        let ok = publisher.writer.publish(sample(&f)).is_ok();
                        ctx.published(u64::from(ok), u64::from(!ok));
                    }
                    Ok(_) => {}
                    Err(RecvError::Lagged(n)) if now_active => ctx.published(0, n),
                    Err(RecvError::Lagged(_)) => {}
                    Err(RecvError::Closed) => return,
                }
            }
            () = election_changed(&mut election) => {}
        }
        let now_active = active(&election);
        if now_active != was_active {
            ctx.publishing(&topic, now_active);
            was_active = now_active;
        }
    }
}

/// A frame as a sample, stamped now.
fn sample(frame: &Frame) -> RtcmMessage {
    RtcmMessage {
        header: Header {
            stamp: Time::now(),
            frame_id: String::new(),
        },
        message: frame.bytes.clone(),
    }
}

/// Hands every sample of the topic to the corrections service (see the module docs)
/// until the task is aborted.
pub async fn receive<C: RtcmContext + ?Sized>(receiver: Arc<RtcmReceiver>, ctx: Arc<C>) {
    let topic = topics::rtcm().to_string();
    ctx.receiving(&topic);
    loop {
        let m = receiver.reader.next().await;
        if ctx.relayed(&m.message) == Relayed::Malformed {
            DdsCounters::add(&receiver.counters.malformed);
            tracing::debug!(
                "dds: an RTCM sample of {} bytes on {topic} held no good frame: dropped",
                m.message.len()
            );
        }
    }
}

/// The relay's context on skein's corrections service ([`skein_rtk::relay`]).
impl RtcmContext for RtkService {
    fn source_frames(&self) -> broadcast::Receiver<Frame> {
        self.tap()
    }

    fn publishing(&self, topic: &str, active: bool) {
        self.relay_publisher(topic, active);
    }

    fn published(&self, frames: u64, failures: u64) {
        self.relay_published(frames, failures);
    }

    fn receiving(&self, topic: &str) {
        self.relay_receiver(topic);
    }

    fn relayed(&self, message: &[u8]) -> Relayed {
        RtkService::relayed(self, message)
    }
}
