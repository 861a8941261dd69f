//! The vehicles of this process, as the coordinator registers them: the coordinator owns
//! the [`FleetRegistry`] (a vehicle is added when it joins), and hands [`Fleet`] readers
//! to whoever reads every vehicle (payload hosts show drivers the swarm, the counter-UAS
//! tracker reads the detectors' states and the members' poses). Vehicles of other
//! processes are not here: the coordinator reaches those through their proxies.

use super::VehicleShared;
use skein_model::vehicle::VehicleSnapshot;
use std::collections::BTreeMap;
use std::sync::Arc;
use tokio::sync::watch;

/// Every registered vehicle's persistent part, by id.
type Members = Arc<BTreeMap<String, Arc<VehicleShared>>>;

/// The coordinator's registry of this process's vehicles (see the module docs).
#[derive(Debug)]
pub struct FleetRegistry {
    members: watch::Sender<Members>,
}

impl Default for FleetRegistry {
    fn default() -> Self {
        FleetRegistry {
            members: watch::channel(Members::default()).0,
        }
    }
}

impl FleetRegistry {
    /// An empty registry.
    pub fn new() -> Self {
        Self::default()
    }

    /// Registers a vehicle (replacing one of the same id); readers see it at once.
    pub fn add(&self, vehicle: Arc<VehicleShared>) {
        self.members.send_modify(|m| {
            Arc::make_mut(m).insert(vehicle.id.clone(), vehicle);
        });
    }

    /// A reader of the registry, present and future members.
    pub fn reader(&self) -> Fleet {
        Fleet {
            members: self.members.subscribe(),
        }
    }
}

/// A reader of this process's vehicles (see the module docs).
#[derive(Clone, Debug)]
pub struct Fleet {
    members: watch::Receiver<Members>,
}

impl Fleet {
    fn members(&self) -> Members {
        self.members.borrow().clone()
    }

    /// Every vehicle's latest snapshot, by id.
    pub fn snapshots(&self) -> Vec<VehicleSnapshot> {
        self.members().values().map(|v| v.snapshot()).collect()
    }

    /// What `f` takes of every vehicle's latest snapshot, by id, the `None`s left out:
    /// read in place, so that nothing but what `f` keeps is copied (a snapshot holds a
    /// dozen strings; the tracker wants three vectors of each).
    pub fn map_snapshots<T>(&self, mut f: impl FnMut(&VehicleSnapshot) -> Option<T>) -> Vec<T> {
        self.members()
            .values()
            .filter_map(|v| v.with_snapshot(&mut f))
            .collect()
    }

    /// Every vehicle's id and link, by id.
    pub fn links(&self) -> Vec<(String, Arc<skein_link::VehicleLink>)> {
        self.members()
            .values()
            .map(|v| (v.id.clone(), v.link.clone()))
            .collect()
    }

    /// The last published state of every payload of `kind` (e.g. `"detector"`), as
    /// `(vehicle id, slot, state)`, by vehicle then slot; payloads that published nothing
    /// yet are left out.
    pub fn payload_states(&self, kind: &str) -> Vec<(String, String, serde_json::Value)> {
        let mut out = Vec::new();
        for v in self.members().values() {
            for (slot, p) in v.payloads().iter() {
                if p.spec.kind == kind
                    && let Some(state) = p.state()
                {
                    out.push((v.id.clone(), slot.clone(), state));
                }
            }
        }
        out
    }
}
