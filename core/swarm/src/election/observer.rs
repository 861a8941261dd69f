//! The agent's side of the coordinator election: which coordinator to obey.
//!
//! An agent (`skein agent`) does not take part in the election; it hears the leases on
//! `/skein/coordinator` and obeys only the **active** coordinator: among the live leases
//! (heard within [`ElectionConfig::lease_timeout`]) that claim the role, the one with
//! the highest epoch (equal epochs: the higher rank, as the election orders them). A
//! target or command carries its sender's id and epoch; it is obeyed only when both are
//! the active one's. So during a healed partition, a coordinator that has not yet
//! learned it lost the role is not obeyed, and a sample from an old epoch that arrives
//! late is dropped.
//!
//! When no live lease claims the role, the agent has **lost its coordinator**
//! ([`Observer::lost_for`]): it holds its vehicles, then does its configured action.

use super::{ElectionConfig, Lease, claim_wins};
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// Why a sample from a coordinator is not obeyed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Refusal {
    /// No coordinator is active.
    NoActive,
    /// An epoch older than the highest one heard.
    StaleEpoch {
        /// The sample's epoch.
        epoch: u64,
        /// The highest epoch heard.
        highest: u64,
    },
    /// The sender is not the active coordinator.
    NotActive {
        /// The active coordinator's id.
        active: String,
    },
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refusal::NoActive => f.write_str("no coordinator is active"),
            Refusal::StaleEpoch { epoch, highest } => {
                write!(f, "epoch {epoch} is older than epoch {highest}")
            }
            Refusal::NotActive { active } => write!(f, "`{active}` is the active coordinator"),
        }
    }
}

/// The leases an agent has heard (see the module docs).
#[derive(Debug, Clone)]
pub struct Observer {
    lease_timeout: Duration,
    leases: BTreeMap<String, (Lease, Instant)>,
    highest_epoch: u64,
    /// When a lease claiming the role was last heard (or the observer started).
    last_active: Instant,
}

impl Observer {
    /// An observer that has heard nothing, started at `now` (so a coordinator counts as
    /// lost only a timeout after the start).
    pub fn new(config: ElectionConfig, now: Instant) -> Self {
        Observer {
            lease_timeout: config.lease_timeout,
            leases: BTreeMap::new(),
            highest_epoch: 0,
            last_active: now,
        }
    }

    /// Takes a lease heard at `now`.
    pub fn heard(&mut self, lease: Lease, now: Instant) {
        if lease.active {
            self.highest_epoch = self.highest_epoch.max(lease.epoch);
            self.last_active = self.last_active.max(now);
        }
        self.leases
            .insert(lease.coordinator_id.clone(), (lease, now));
    }

    /// The active coordinator at `now`, if any.
    pub fn active(&self, now: Instant) -> Option<&Lease> {
        self.leases
            .values()
            .filter(|(l, at)| l.active && now.saturating_duration_since(*at) < self.lease_timeout)
            .map(|(l, _)| l)
            .reduce(|a, b| if claim_wins(b, a) { b } else { a })
    }

    /// The highest epoch any active lease has carried.
    pub fn highest_epoch(&self) -> u64 {
        self.highest_epoch
    }

    /// Whether to obey a sample from `coordinator_id` in `epoch` at `now`.
    ///
    /// # Errors
    /// Why not ([`Refusal`]).
    pub fn accepts(&self, coordinator_id: &str, epoch: u64, now: Instant) -> Result<(), Refusal> {
        if epoch < self.highest_epoch {
            return Err(Refusal::StaleEpoch {
                epoch,
                highest: self.highest_epoch,
            });
        }
        match self.active(now) {
            None => Err(Refusal::NoActive),
            Some(a) if a.coordinator_id == coordinator_id && a.epoch == epoch => Ok(()),
            Some(a) => Err(Refusal::NotActive {
                active: a.coordinator_id.clone(),
            }),
        }
    }

    /// How long no lease claiming the role has been heard at `now` (since the start
    /// when none ever was).
    pub fn lost_for(&self, now: Instant) -> Duration {
        now.saturating_duration_since(self.last_active)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lease(id: &str, priority: u32, epoch: u64, active: bool) -> Lease {
        Lease {
            coordinator_id: id.into(),
            priority,
            epoch,
            active,
            api_url: String::new(),
        }
    }

    #[test]
    fn obeys_only_the_active_coordinator_of_the_highest_epoch() {
        let t0 = Instant::now();
        let mut o = Observer::new(ElectionConfig::default(), t0);
        assert_eq!(o.accepts("a", 1, t0), Err(Refusal::NoActive));
        o.heard(lease("a", 2, 1, true), t0);
        o.heard(lease("b", 1, 0, false), t0);
        assert_eq!(o.active(t0).map(|l| l.coordinator_id.as_str()), Some("a"));
        assert_eq!(o.accepts("a", 1, t0), Ok(()));
        assert_eq!(
            o.accepts("b", 1, t0),
            Err(Refusal::NotActive { active: "a".into() })
        );
        // A healed partition: b claimed epoch 2 meanwhile; a has not stepped down yet.
        o.heard(lease("b", 1, 2, true), t0);
        assert_eq!(o.accepts("b", 2, t0), Ok(()));
        assert_eq!(
            o.accepts("a", 1, t0),
            Err(Refusal::StaleEpoch {
                epoch: 1,
                highest: 2
            })
        );
    }

    #[test]
    fn a_coordinator_is_lost_a_lease_timeout_after_its_last_lease() {
        let t0 = Instant::now();
        let mut o = Observer::new(ElectionConfig::default(), t0);
        o.heard(lease("a", 2, 1, true), t0);
        let t = t0 + Duration::from_millis(900);
        assert!(o.active(t).is_some());
        assert_eq!(o.lost_for(t), Duration::from_millis(900));
        let t = t0 + Duration::from_millis(1500);
        assert!(o.active(t).is_none());
        assert_eq!(o.lost_for(t), Duration::from_millis(1500));
        assert_eq!(o.accepts("a", 1, t), Err(Refusal::NoActive));
        // A standby's lease does not end the loss.
        o.heard(lease("b", 1, 1, false), t);
        assert_eq!(o.lost_for(t), Duration::from_millis(1500));
        let t2 = t + Duration::from_millis(100);
        o.heard(lease("b", 1, 2, true), t2);
        assert_eq!(o.lost_for(t2), Duration::ZERO);
    }
}
