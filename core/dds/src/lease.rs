//! The coordinator election on DDS: each `skein coordinator` publishes its
//! [`Lease`](skein_swarm::election::Lease) on `/skein/coordinator`
//! (`skein_msgs/CoordinatorLease`) and runs [`Election`] on the leases it hears.
//!
//! The election state lives here, outside the `DdsLink` actor, so a restart of
//! `coordinator/dds` keeps the role and epoch (a restart shorter than the lease timeout
//! is not even seen by the other candidates). Its status goes to a `watch` channel: the
//! API reads it for `GET /api/v1/coordinator` and to refuse writes on a standby, and the
//! coordinator's roles read it ([`crate::remote`], [`crate::mirror`]). A change of role
//! goes to the [`ElectionContext`] (in skein, the `coordinator_role_changed` event).

use crate::carrier::{Carrier, TopicReader, TopicWriter};
use crate::clock;
use crate::counters::DdsCounters;
use crate::error::DdsError;
use crate::msgs::{CoordinatorLease, Header};
use crate::topics;
use ros2_client::builtin_interfaces::Time;
use skein_swarm::election::{
    CoordinatorRole, Election, ElectionConfig, ElectionStatus, Lease, Transition,
};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};
use tokio::sync::watch;

/// How often the election is evaluated (the failover delay is the lease timeout plus at
/// most this).
pub const TICK: Duration = Duration::from_millis(100);

/// Who this candidate is (`skein coordinator --id --priority`).
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// Its id on the topic.
    pub coordinator_id: String,
    /// Its priority (the higher wins).
    pub priority: u32,
    /// Where its HTTP API listens, advertised in the lease.
    pub api_url: String,
    /// The election's timing.
    pub timing: ElectionConfig,
}

/// A change of this candidate's role, for [`ElectionContext::role_changed`].
#[derive(Debug, Clone, PartialEq)]
pub struct RoleChange {
    /// This candidate's id.
    pub coordinator_id: String,
    /// Its new role.
    pub role: CoordinatorRole,
    /// Its epoch (the one it claimed, or the one it leaves).
    pub epoch: u64,
    /// Why it stepped down (`None` when it claimed the role).
    pub reason: Option<String>,
}

/// What the election needs from this process.
pub trait ElectionContext: Send + Sync + 'static {
    /// This candidate took the role or stepped down; [`ElectionLink::subscribe`]'s status
    /// already shows the change when this is called.
    fn role_changed(&self, change: RoleChange);
}

/// The lease topic and the election state of this candidate.
pub struct ElectionLink {
    election: Mutex<Election>,
    status: watch::Sender<ElectionStatus>,
    writer: TopicWriter<CoordinatorLease>,
    reader: TopicReader<CoordinatorLease>,
}

impl ElectionLink {
    /// Opens `/skein/coordinator` for reading and writing on `carrier` (counting in
    /// `counters`); the candidate starts as a standby.
    ///
    /// # Errors
    /// The topic, reader or writer could not be created.
    pub fn open(
        carrier: &impl Carrier,
        candidate: Candidate,
        counters: &Arc<DdsCounters>,
    ) -> Result<ElectionLink, DdsError> {
        // One topic, written and read by every candidate.
        let topic = topics::coordinator();
        let writer = TopicWriter::open(carrier, &topic, counters)?;
        let reader = TopicReader::open(carrier, &topic, counters, "coordinator lease sample")?;
        let now = clock::now();
        let election = Election::new(
            candidate.coordinator_id,
            candidate.priority,
            candidate.api_url,
            candidate.timing,
            now,
        );
        let (status, _) = watch::channel(election.status(now));
        Ok(ElectionLink {
            election: Mutex::new(election),
            status,
            writer,
            reader,
        })
    }

    /// The election's status, updated at every tick.
    pub fn subscribe(&self) -> watch::Receiver<ElectionStatus> {
        self.status.subscribe()
    }

    /// Hears, ticks and publishes until the task is aborted; tells `ctx` of every change
    /// of role.
    pub async fn run<C: ElectionContext>(self: Arc<Self>, ctx: Arc<C>) {
        let period = self
            .election
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .config()
            .publish_period;
        let mut tick = tokio::time::interval(TICK);
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        let mut last_sent: Option<Instant> = None;
        loop {
            tick.tick().await;
            let now = clock::now();
            let mut heard = Vec::new();
            while let Some(l) = self.reader.try_next() {
                heard.push(l);
            }
            let (transition, lease, status) = {
                let mut e = self.election.lock().unwrap_or_else(PoisonError::into_inner);
                for l in heard {
                    e.heard(from_msg(l), now);
                }
                let t = e.tick(now);
                (t, e.lease().clone(), e.status(now))
            };
            let reason = match &transition {
                Some(Transition::Claimed { epoch }) => {
                    tracing::warn!(
                        "coordinator `{}`: active in epoch {epoch}",
                        lease.coordinator_id
                    );
                    None
                }
                Some(Transition::SteppedDown { reason }) => {
                    tracing::warn!("coordinator `{}`: standby: {reason}", lease.coordinator_id);
                    Some(reason.clone())
                }
                None => None,
            };
            // The status first, then the coordinator: whoever asks the coordinator after
            // it heard of the change sees the change in the status too (the mirror
            // relies on it).
            let role = status.role;
            self.status.send_replace(status);
            if transition.is_some() {
                ctx.role_changed(RoleChange {
                    coordinator_id: lease.coordinator_id.clone(),
                    role,
                    epoch: lease.epoch,
                    reason,
                });
            }
            // A change of role goes out at once; otherwise at the publish period.
            if transition.is_some() || last_sent.is_none_or(|t| now - t >= period) {
                let _ = self.writer.publish(to_msg(&lease));
                last_sent = Some(now);
            }
        }
    }
}

/// A lease as the topic carries it.
pub(crate) fn to_msg(l: &Lease) -> CoordinatorLease {
    CoordinatorLease {
        header: Header {
            stamp: Time::now(),
            frame_id: String::new(),
        },
        coordinator_id: l.coordinator_id.clone(),
        priority: l.priority,
        epoch: l.epoch,
        active: l.active,
        api_url: l.api_url.clone(),
    }
}

/// A lease heard on the topic.
pub(crate) fn from_msg(m: CoordinatorLease) -> Lease {
    Lease {
        coordinator_id: m.coordinator_id,
        priority: m.priority,
        epoch: m.epoch,
        active: m.active,
        api_url: m.api_url,
    }
}
