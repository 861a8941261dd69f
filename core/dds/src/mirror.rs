//! The mirrors of the active coordinator's flight state, for the standbys: its formation
//! on `/skein/formation` ([`FormationMirror`], 5 Hz, `null` when it flies none) and its
//! flying mission on `/skein/mission` ([`MissionMirror`], 2 Hz, `null` when none flies).
//! Every standby keeps the latest one of each of the highest epoch, converted into its
//! own swarm frame and clock. When a standby takes the role, it flies them on from where
//! they were (the formation's reference moved on by the mirror's age; the mission at the
//! same step, its clock moved on by the age), so a failover costs the formation no more
//! than the lease timeout of stale targets: the agents move their last targets on by
//! their age meanwhile, and hold only after `coordinator_timeout_s`.
//!
//! The topics are transient-local: a standby that starts late gets the last state at
//! once. The role reaches its coordinator through a [`MirrorContext`] for each
//! [`Mirrored`] state.

use crate::carrier::{Carrier, TopicReader, TopicWriter};
use crate::counters::DdsCounters;
use crate::envelope::{Envelope, body_or_drop, reframed_or_drop};
use crate::error::DdsError;
use crate::msgs::SwarmMessage;
use crate::reframe::{FrameSource, Positions, Reframe, SwarmFrame, into_frame};
use crate::topics::{self, TopicSpec};
use serde::Serialize;
use serde::de::DeserializeOwned;
use skein_swarm::clocks::PeerClocks;
use skein_swarm::coordinator::missions::{MISSION_TICK, MissionMirror};
use skein_swarm::election::{CoordinatorRole, ElectionStatus};
use skein_swarm::formation::FormationMirror;
use std::future::Future;
use std::marker::PhantomData;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::watch;

/// How often the active coordinator publishes its formation.
pub const MIRROR_PERIOD: Duration = Duration::from_millis(200);

/// A state the active coordinator mirrors to the standbys (JSON in a
/// `skein_msgs/SwarmMessage`, positions in its swarm frame).
pub trait Mirrored: Serialize + DeserializeOwned + Positions + Send + Sync + 'static {
    /// What a sample of it is called where a bad one is counted (`formation`).
    const WHAT: &'static str;
    /// How often the active coordinator publishes it.
    const PERIOD: Duration;
    /// Its topic.
    fn topic() -> TopicSpec;
    /// It, its positions converted by `r` into the receiver's frame.
    fn reframe(self, r: &Reframe) -> Self;
    /// When it was mirrored, µs on its sender's wall clock.
    fn stamp_us(&mut self) -> &mut u64;
}

impl Mirrored for FormationMirror {
    const WHAT: &'static str = "formation";
    const PERIOD: Duration = MIRROR_PERIOD;
    fn topic() -> TopicSpec {
        topics::formation()
    }
    fn reframe(self, r: &Reframe) -> Self {
        r.mirror(self)
    }
    fn stamp_us(&mut self) -> &mut u64 {
        &mut self.stamp_us
    }
}

impl Mirrored for MissionMirror {
    const WHAT: &'static str = "mission";
    /// The mission's own tick: it changes no faster.
    const PERIOD: Duration = MISSION_TICK;
    fn topic() -> TopicSpec {
        topics::mission()
    }
    fn reframe(mut self, r: &Reframe) -> Self {
        self.run.reframe(&|p| r.point(p));
        self
    }
    fn stamp_us(&mut self) -> &mut u64 {
        &mut self.stamp_us
    }
}

/// What the mirror of `T` needs from this process's coordinator.
pub trait MirrorContext<T>: FrameSource {
    /// The state to mirror (`Some(None)`: none is flown; `None`: no answer).
    fn current(&self) -> impl Future<Output = Option<Option<T>>> + Send;

    /// This coordinator just took the role: fly on `mirror` (in this process's frame and
    /// clock), the state of coordinator `from`, unless it flies its own.
    fn resume(&self, mirror: T, from: String);
}

/// The topic of one [`Mirrored`] state, for a coordinator candidate.
pub struct Mirror<T> {
    counters: Arc<DdsCounters>,
    writer: TopicWriter<SwarmMessage>,
    reader: TopicReader<SwarmMessage>,
    /// The other coordinators' clocks: a mirror's stamp is converted into this one's.
    clocks: Arc<PeerClocks>,
    of: PhantomData<fn() -> T>,
}

impl<T: Mirrored> Mirror<T> {
    /// Converts the mirrors' stamps with `clocks` (without, they are taken as this
    /// process's).
    pub fn with_clocks(mut self, clocks: Arc<PeerClocks>) -> Self {
        self.clocks = clocks;
        self
    }

    /// Opens `T`'s topic for reading and writing on `carrier`, counting in `counters`.
    ///
    /// # Errors
    /// The topic, reader or writer could not be created.
    pub fn open(carrier: &impl Carrier, counters: &Arc<DdsCounters>) -> Result<Self, DdsError> {
        let topic = T::topic();
        Ok(Mirror {
            writer: TopicWriter::open(carrier, &topic, counters)?,
            reader: TopicReader::open(carrier, &topic, counters, format!("{} sample", T::WHAT))?,
            counters: counters.clone(),
            clocks: Arc::default(),
            of: PhantomData,
        })
    }
}

/// The latest state heard from another coordinator.
struct Heard<T> {
    from: String,
    epoch: u64,
    mirror: Option<T>,
}

/// Runs the mirror until the task is aborted (see the module docs); `election` is this
/// candidate's status.
pub async fn run<T: Mirrored, C: MirrorContext<T>>(
    mirror: Arc<Mirror<T>>,
    election: watch::Receiver<ElectionStatus>,
    ctx: Arc<C>,
) {
    let Some(frame) = ctx.swarm_frame().await else {
        tracing::error!("dds: the coordinator did not answer: no {} mirror", T::WHAT);
        return;
    };
    let me = election.borrow().this.coordinator_id.clone();
    let mut was_active = election.borrow().role == CoordinatorRole::Active;
    let mut heard: Option<Heard<T>> = None;
    let mut tick = tokio::time::interval(T::PERIOD);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        tick.tick().await;
        while let Some(m) = mirror.reader.try_next() {
            let env = Envelope::from_msg(m);
            if env.sender_id == me || heard.as_ref().is_some_and(|h| h.epoch > env.epoch) {
                continue;
            }
            let Some(state) =
                received_mirror(&mirror.counters, &mirror.clocks, frame.as_ref(), &env)
            else {
                continue;
            };
            heard = Some(Heard {
                from: env.sender_id,
                epoch: env.epoch,
                mirror: state,
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
            && let Some(state) = h.mirror
        {
            ctx.resume(state, h.from);
        }
        was_active = active;
        if active
            && let Some(state) = ctx.current().await
            && still_active(&election, epoch)
            && let Ok(m) = Envelope::message("", &me, epoch, frame.frame(), &state)
        {
            let _ = mirror.writer.publish(m);
        }
    }
}

/// Whether this candidate still holds the role in `epoch`, after asking its coordinator
/// for the state. The election updates its status before it tells the coordinator of a
/// step-down ([`crate::lease`]); so when the answer came after the step-down (the
/// formation or mission let go: `null`), the status already says standby here, and that
/// `null` is not published. Published, it would be the last mirror the new active
/// coordinator heard from this one, and it would fly no formation (or mission).
fn still_active(election: &watch::Receiver<ElectionStatus>, epoch: u64) -> bool {
    let s = election.borrow();
    s.role == CoordinatorRole::Active && s.this.epoch == epoch
}

/// The mirror `env` carries (`None`: no state), in this process's `frame` (anchored at
/// the sender's origin if it was not yet) and its stamp in this process's clock; `None`
/// when the sample is dropped: its body is no mirror, or a position is no point in this
/// frame (counted as malformed). The standby's and (the formation's) the agent's
/// reading.
pub(crate) fn received_mirror<T: Mirrored>(
    counters: &DdsCounters,
    clocks: &PeerClocks,
    frame: &dyn SwarmFrame,
    env: &Envelope,
) -> Option<Option<T>> {
    let state = body_or_drop::<Option<T>>(counters, env, T::WHAT)?;
    let reframe = into_frame(frame, env.origin);
    let Some(m) = state else {
        return Some(None);
    };
    let mut m = reframed_or_drop(counters, env, T::WHAT, m, reframe.as_ref(), |r, x| {
        x.reframe(r)
    })?;
    let stamp = m.stamp_us();
    *stamp = clocks.to_local_us(&env.sender_id, *stamp);
    Some(Some(m))
}
