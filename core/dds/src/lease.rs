//! The coordinator election on DDS: each `skein coordinator` publishes its
//! [`Lease`](skein_swarm::election::Lease) on `/skein/coordinator`
//! (`skein_msgs/CoordinatorLease`) and runs [`Election`] on the leases it hears.
//!
//! The election state lives here, outside the `DdsLink` actor, so a restart of
//! `coordinator/dds` keeps the role and epoch (a restart shorter than the lease timeout
//! is not even seen by the other candidates). Its status goes to a `watch` channel: the
//! API reads it for `GET /api/v1/coordinator` and to refuse writes on a standby.

use crate::link::{DdsCounters, DdsError, err};
use crate::msgs::{self, CoordinatorLease, Header, RosMessage};
use crate::topics;
use ros2_client::builtin_interfaces::Time;
use ros2_client::{Name, Node, Publisher, Subscription};
use skein_swarm::SwarmEvent;
use skein_swarm::election::{Election, ElectionConfig, ElectionStatus, Lease, Transition};
use std::sync::atomic::Ordering;
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};
use tokio::sync::{broadcast, watch};

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

/// The lease topic and the election state of this candidate.
pub struct ElectionLink {
    election: Mutex<Election>,
    status: watch::Sender<ElectionStatus>,
    writer: Publisher<CoordinatorLease>,
    reader: Subscription<CoordinatorLease>,
    events: broadcast::Sender<SwarmEvent>,
}

impl ElectionLink {
    /// Creates the `/skein/coordinator` reader and writer on `node`; the candidate
    /// starts as a standby.
    ///
    /// # Errors
    /// The topic, reader or writer could not be created.
    pub(crate) fn new(
        node: &mut Node,
        candidate: Candidate,
        events: broadcast::Sender<SwarmEvent>,
    ) -> Result<ElectionLink, DdsError> {
        // One topic, written and read by every candidate.
        let topic = node
            .create_topic(
                &Name::new(topics::NAMESPACE, "coordinator")
                    .map_err(|e| DdsError(format!("coordinator topic: {e:?}")))?,
                CoordinatorLease::type_name(),
                &topics::leases(),
            )
            .map_err(err("coordinator topic"))?;
        let writer = node
            .create_publisher::<CoordinatorLease>(&topic, None)
            .map_err(err("coordinator publisher"))?;
        let reader = node
            .create_subscription::<CoordinatorLease>(&topic, None)
            .map_err(err("coordinator subscription"))?;
        let now = Instant::now();
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
            events,
        })
    }

    /// The election's status, updated at every tick.
    pub fn subscribe(&self) -> watch::Receiver<ElectionStatus> {
        self.status.subscribe()
    }

    /// Hears, ticks and publishes until the task is aborted, counting leases written,
    /// failed writes and unreadable samples (dropped) in `counters`.
    pub(crate) async fn run(&self, counters: &DdsCounters) {
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
            let now = Instant::now();
            let mut heard = Vec::new();
            loop {
                match self.reader.take() {
                    Ok(Some((l, _))) => heard.push(l),
                    Ok(None) => break,
                    Err(e) => {
                        counters.malformed.fetch_add(1, Ordering::Relaxed);
                        tracing::warn!("dds: a coordinator lease sample was dropped: {e:?}");
                    }
                }
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
            if transition.is_some() {
                let _ = self.events.send(SwarmEvent::CoordinatorRoleChanged {
                    coordinator_id: lease.coordinator_id.clone(),
                    role: status.role,
                    epoch: lease.epoch,
                    reason,
                });
            }
            // A change of role goes out at once; otherwise at the publish period.
            if transition.is_some() || last_sent.is_none_or(|t| now - t >= period) {
                let c = match self.writer.publish(to_msg(&lease)) {
                    Ok(()) => &counters.published,
                    Err(_) => &counters.publish_errors,
                };
                c.fetch_add(1, Ordering::Relaxed);
                last_sent = Some(now);
            }
            self.status.send_replace(status);
        }
    }
}

fn to_msg(l: &Lease) -> CoordinatorLease {
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

fn from_msg(m: msgs::CoordinatorLease) -> Lease {
    Lease {
        coordinator_id: m.coordinator_id,
        priority: m.priority,
        epoch: m.epoch,
        active: m.active,
        api_url: m.api_url,
    }
}
