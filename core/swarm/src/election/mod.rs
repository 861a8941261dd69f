//! Coordinator election: which of the coordinator candidates of a DDS domain is active.
//!
//! Every candidate (`skein coordinator --priority P`) publishes a [`Lease`] on
//! `/skein/coordinator` every [`ElectionConfig::publish_period`] and hears everyone
//! else's. A lease not heard for [`ElectionConfig::lease_timeout`] has expired: its
//! candidate is gone. The rule, applied at every [`Election::tick`]:
//!
//! 1. **Claim.** A standby becomes active only when no live lease claims the role, it
//!    has listened for [`ElectionConfig::first_listen`] since it started (so it has heard
//!    an active one if there is one: a lease timeout, or longer where the link needs time
//!    before it delivers anything, as DDS Security's handshake does), and it is the live candidate with the highest priority (equal
//!    priorities: the smaller id). It takes the epoch after the highest it has seen.
//! 2. **No pre-emption.** A standby of higher priority that appears while another is
//!    active does not claim: it waits. After it has been heard for
//!    [`ElectionConfig::handover_after`], the active one **hands over**: it steps down to
//!    standby (its lease says so), and the higher one claims by rule 1 once it hears that.
//!    So a returning coordinator takes the role back only through a moment with none
//!    active, never with two.
//! 3. **Two actives** (a healed network partition, where each side elected its own): the
//!    one with the lower (epoch, priority, smaller-id-wins) steps down at once.
//!
//! Agents obey only the active coordinator with the highest epoch they have heard, so
//! targets of a coordinator that has not yet learned it lost the role are dropped.
//!
//! Failover time: the active coordinator stops; its last lease expires after
//! `lease_timeout` (1 s), and the highest standby claims at its next tick (100 ms):
//! about 1.1 s, within the 2 s the design allows.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// A candidate's lease, as published on `/skein/coordinator`
/// (`skein_msgs/CoordinatorLease`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct Lease {
    /// The candidate's id (`--id`, default `<hostname>-<pid>`).
    pub coordinator_id: String,
    /// Its priority (`--priority`): the higher wins.
    pub priority: u32,
    /// The epoch it holds the role in (active), or the highest it has seen (standby).
    pub epoch: u64,
    /// True while it holds the role.
    pub active: bool,
    /// Where its HTTP API listens (`http://10.0.0.2:8080`), for the operator to be sent
    /// there.
    pub api_url: String,
}

/// The election's timing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ElectionConfig {
    /// How often a candidate publishes its lease (default 200 ms).
    pub publish_period: Duration,
    /// A lease not heard for this long has expired (default 1 s).
    pub lease_timeout: Duration,
    /// How long a higher-priority standby must have been heard before the active one
    /// hands it the role (default 5 s).
    pub handover_after: Duration,
    /// How long a candidate listens after it starts before it may claim (default 1 s, the
    /// lease timeout): at least as long as a new participant takes to hear the others.
    pub first_listen: Duration,
}

impl Default for ElectionConfig {
    fn default() -> Self {
        ElectionConfig {
            publish_period: Duration::from_millis(200),
            lease_timeout: Duration::from_secs(1),
            handover_after: Duration::from_secs(5),
            first_listen: Duration::from_secs(1),
        }
    }
}

/// A candidate's role.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum CoordinatorRole {
    /// Holds the role: runs the formation, takes writes.
    Active,
    /// Mirrors the active one; its API answers reads and refuses writes (409).
    Standby,
}

/// What the election did at a tick.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Transition {
    /// Took the role in this epoch.
    Claimed {
        /// The new epoch.
        epoch: u64,
    },
    /// Gave the role up, and why.
    SteppedDown {
        /// Why (names the coordinator it yields to).
        reason: String,
    },
}

/// The election as `GET /api/v1/coordinator` shows it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct ElectionStatus {
    /// This candidate's own lease (its id, priority, epoch, role).
    pub this: Lease,
    /// Its role.
    pub role: CoordinatorRole,
    /// The active coordinator's lease (this one's when active), `null` when none is.
    pub active: Option<Lease>,
    /// The other candidates heard, with their leases' age in seconds.
    pub peers: Vec<PeerStatus>,
}

/// Another candidate as this one hears it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct PeerStatus {
    /// Its latest lease.
    pub lease: Lease,
    /// Seconds since that lease was heard.
    pub age_s: f64,
}

#[derive(Debug, Clone)]
struct Peer {
    lease: Lease,
    first_heard: Instant,
    last_heard: Instant,
}

/// One candidate's election state (see the module docs for the rule).
#[derive(Debug, Clone)]
pub struct Election {
    config: ElectionConfig,
    me: Lease,
    started: Instant,
    peers: BTreeMap<String, Peer>,
}

/// Orders candidates for the role: priority, then the smaller id.
fn outranks(a: &Lease, b: &Lease) -> bool {
    (a.priority, std::cmp::Reverse(&a.coordinator_id))
        > (b.priority, std::cmp::Reverse(&b.coordinator_id))
}

/// Orders two active claims: epoch, then rank.
pub(crate) fn claim_wins(a: &Lease, b: &Lease) -> bool {
    a.epoch > b.epoch || (a.epoch == b.epoch && outranks(a, b))
}

impl Election {
    /// A standby candidate starting now.
    pub fn new(
        coordinator_id: String,
        priority: u32,
        api_url: String,
        config: ElectionConfig,
        now: Instant,
    ) -> Self {
        Election {
            config,
            me: Lease {
                coordinator_id,
                priority,
                epoch: 0,
                active: false,
                api_url,
            },
            started: now,
            peers: BTreeMap::new(),
        }
    }

    /// The timing it runs with.
    pub fn config(&self) -> ElectionConfig {
        self.config
    }

    /// Takes a lease heard on the topic (its own echo is ignored).
    pub fn heard(&mut self, lease: Lease, now: Instant) {
        if lease.coordinator_id == self.me.coordinator_id {
            return;
        }
        match self.peers.get_mut(&lease.coordinator_id) {
            Some(p) => {
                p.lease = lease;
                p.last_heard = now;
            }
            None => {
                self.peers.insert(
                    lease.coordinator_id.clone(),
                    Peer {
                        lease,
                        first_heard: now,
                        last_heard: now,
                    },
                );
            }
        }
    }

    /// Applies the rule (module docs) at `now`: expires old leases, then claims, hands
    /// over or steps down.
    pub fn tick(&mut self, now: Instant) -> Option<Transition> {
        let timeout = self.config.lease_timeout;
        self.peers
            .retain(|_, p| now.saturating_duration_since(p.last_heard) <= timeout);
        let max_epoch = self
            .peers
            .values()
            .map(|p| p.lease.epoch)
            .chain([self.me.epoch])
            .max()
            .unwrap_or(0);
        if self.me.active {
            if let Some(p) = self
                .peers
                .values()
                .find(|p| p.lease.active && claim_wins(&p.lease, &self.me))
            {
                let reason = format!(
                    "coordinator `{}` holds the role in epoch {} (this one: {})",
                    p.lease.coordinator_id, p.lease.epoch, self.me.epoch
                );
                self.me.active = false;
                self.me.epoch = max_epoch;
                return Some(Transition::SteppedDown { reason });
            }
            let handover = self.peers.values().find(|p| {
                !p.lease.active
                    && outranks(&p.lease, &self.me)
                    && now.saturating_duration_since(p.first_heard) >= self.config.handover_after
            });
            if let Some(p) = handover {
                let reason = format!(
                    "handing over to `{}` (priority {} over {})",
                    p.lease.coordinator_id, p.lease.priority, self.me.priority
                );
                self.me.active = false;
                return Some(Transition::SteppedDown { reason });
            }
            return None;
        }
        self.me.epoch = max_epoch;
        if self.peers.values().any(|p| p.lease.active)
            || now.saturating_duration_since(self.started) < self.config.first_listen
            || self.peers.values().any(|p| outranks(&p.lease, &self.me))
        {
            return None;
        }
        self.me.active = true;
        self.me.epoch = max_epoch + 1;
        Some(Transition::Claimed {
            epoch: self.me.epoch,
        })
    }

    /// The lease to publish now.
    pub fn lease(&self) -> &Lease {
        &self.me
    }

    /// This candidate's role.
    pub fn role(&self) -> CoordinatorRole {
        if self.me.active {
            CoordinatorRole::Active
        } else {
            CoordinatorRole::Standby
        }
    }

    /// The lease of the active coordinator as this one sees it (its own when active).
    pub fn active(&self) -> Option<&Lease> {
        if self.me.active {
            return Some(&self.me);
        }
        self.peers
            .values()
            .filter(|p| p.lease.active)
            .map(|p| &p.lease)
            .reduce(|a, b| if claim_wins(b, a) { b } else { a })
    }

    /// The election as the API shows it.
    pub fn status(&self, now: Instant) -> ElectionStatus {
        ElectionStatus {
            this: self.me.clone(),
            role: self.role(),
            active: self.active().cloned(),
            peers: self
                .peers
                .values()
                .map(|p| PeerStatus {
                    lease: p.lease.clone(),
                    age_s: now.saturating_duration_since(p.last_heard).as_secs_f64(),
                })
                .collect(),
        }
    }
}

pub mod observer;

#[cfg(test)]
mod tests;
