//! The formation mirror on `/skein/formation`: the active coordinator publishes its
//! formation ([`FormationMirror`]) at 5 Hz, `null` when it flies none; every standby
//! keeps the latest one of the highest epoch, converted into its own swarm frame. When a
//! standby takes the role, it flies that formation on from where it was (its reference
//! moved on by the mirror's age), so a failover costs the formation no more than the
//! lease timeout of stale targets: the agents move their last targets on by their age
//! meanwhile, and hold only after `coordinator_timeout_s`.
//!
//! The topic is transient-local: a standby that starts late gets the last formation at
//! once. The role reaches its coordinator through a [`MirrorContext`].

use crate::carrier::{Carrier, TopicReader, TopicWriter};
use crate::counters::DdsCounters;
use crate::envelope::{Envelope, body_or_drop, reframed_or_drop};
use crate::error::DdsError;
use crate::msgs::SwarmMessage;
use crate::reframe::{FrameSource, SwarmFrame, into_frame};
use crate::topics;
use skein_swarm::clocks::PeerClocks;
use skein_swarm::election::{CoordinatorRole, ElectionStatus};
use skein_swarm::formation::FormationMirror;
use std::future::Future;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::watch;

/// How often the active coordinator publishes its formation.
pub const MIRROR_PERIOD: Duration = Duration::from_millis(200);

/// What the mirror needs from this process's coordinator.
pub trait MirrorContext: FrameSource {
    /// The formation to mirror (`Some(None)`: none is flown; `None`: no answer).
    fn formation(&self) -> impl Future<Output = Option<Option<FormationMirror>>> + Send;

    /// This coordinator just took the role: fly on `mirror` (in this process's frame),
    /// the formation of coordinator `from`, unless it flies one.
    fn resume(&self, mirror: FormationMirror, from: String);
}

/// The `/skein/formation` topic of a coordinator candidate.
pub struct Mirror {
    counters: Arc<DdsCounters>,
    writer: TopicWriter<SwarmMessage>,
    reader: TopicReader<SwarmMessage>,
    /// The other coordinators' clocks: a mirror's stamp is converted into this one's.
    clocks: Arc<PeerClocks>,
}

impl Mirror {
    /// Converts the mirrors' stamps with `clocks` (without, they are taken as this
    /// process's).
    pub fn with_clocks(mut self, clocks: Arc<PeerClocks>) -> Self {
        self.clocks = clocks;
        self
    }

    /// Opens `/skein/formation` for reading and writing on `carrier`, counting in
    /// `counters`.
    ///
    /// # Errors
    /// The topic, reader or writer could not be created.
    pub fn open(carrier: &impl Carrier, counters: &Arc<DdsCounters>) -> Result<Self, DdsError> {
        let topic = topics::formation();
        Ok(Mirror {
            writer: TopicWriter::open(carrier, &topic, counters)?,
            reader: TopicReader::open(carrier, &topic, counters, "formation sample")?,
            counters: counters.clone(),
            clocks: Arc::default(),
        })
    }
}

/// The latest formation heard from another coordinator.
struct Heard {
    from: String,
    epoch: u64,
    mirror: Option<FormationMirror>,
}

/// Runs the mirror until the task is aborted (see the module docs); `election` is this
/// candidate's status.
pub async fn run<C: MirrorContext>(
    mirror: Arc<Mirror>,
    election: watch::Receiver<ElectionStatus>,
    ctx: Arc<C>,
) {
    let Some(frame) = ctx.swarm_frame().await else {
        tracing::error!("dds: the coordinator did not answer: no formation mirror");
        return;
    };
    let me = election.borrow().this.coordinator_id.clone();
    let mut was_active = election.borrow().role == CoordinatorRole::Active;
    let mut heard: Option<Heard> = None;
    let mut tick = tokio::time::interval(MIRROR_PERIOD);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        tick.tick().await;
        while let Some(m) = mirror.reader.try_next() {
            let env = Envelope::from_msg(m);
            if env.sender_id == me || heard.as_ref().is_some_and(|h| h.epoch > env.epoch) {
                continue;
            }
            let Some(formation) =
                received_mirror(&mirror.counters, &mirror.clocks, frame.as_ref(), &env)
            else {
                continue;
            };
            heard = Some(Heard {
                from: env.sender_id,
                epoch: env.epoch,
                mirror: formation,
            });
        }
        let (active, epoch) = {
            let s = election.borrow();
            (s.role == CoordinatorRole::Active, s.this.epoch)
        };
        if active
            && !was_active
            && let Some(h) = heard.take()
            && h.epoch < epoch
            && let Some(formation) = h.mirror
        {
            ctx.resume(formation, h.from);
        }
        was_active = active;
        if active
            && let Some(formation) = ctx.formation().await
            && still_active(&election, epoch)
            && let Ok(m) = Envelope::message("", &me, epoch, frame.frame(), &formation)
        {
            let _ = mirror.writer.publish(m);
        }
    }
}

/// Whether this candidate still holds the role in `epoch`, after asking its coordinator
/// for the formation. The election updates its status before it tells the coordinator
/// of a step-down ([`crate::lease`]); so when the answer came after the step-down (the
/// formation let go: `null`), the status already says standby here, and that `null` is
/// not published. Published, it would be the last mirror the new active coordinator
/// heard from this one, and it would fly no formation.
fn still_active(election: &watch::Receiver<ElectionStatus>, epoch: u64) -> bool {
    let s = election.borrow();
    s.role == CoordinatorRole::Active && s.this.epoch == epoch
}

/// The formation mirror `env` carries (`None`: no formation), in this process's `frame`
/// (anchored at the sender's origin if it was not yet) and its stamp in this process's
/// clock; `None` when the sample is dropped: its body is no mirror, or a position is no
/// point in this frame (counted as malformed). The standby's and the agent's reading.
pub(crate) fn received_mirror(
    counters: &DdsCounters,
    clocks: &PeerClocks,
    frame: &dyn SwarmFrame,
    env: &Envelope,
) -> Option<Option<FormationMirror>> {
    let formation = body_or_drop::<Option<FormationMirror>>(counters, env, "formation")?;
    let reframe = into_frame(frame, env.origin);
    let Some(m) = formation else {
        return Some(None);
    };
    let mut m = reframed_or_drop(counters, env, "formation", m, reframe.as_ref(), |r, x| {
        r.mirror(x)
    })?;
    m.stamp_us = clocks.to_local_us(&env.sender_id, m.stamp_us);
    Some(Some(m))
}
