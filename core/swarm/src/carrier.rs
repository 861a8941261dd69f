//! The in-process carrier of the swarm protocol (`skein up`): protocol messages travel
//! as actor messages ([`LocalPort`] to a Vehicle actor; the other way, the uplink the
//! coordinator gives each vehicle posts to its mailbox), reports as `watch` channels. The
//! DDS carrier carries the same [`crate::protocol`] types between processes.

use crate::protocol::{ToVehicle, VehiclePort};
use crate::vehicle::VehicleMsg;
use ractor::ActorRef;
use std::sync::{Arc, Mutex, PoisonError};

/// The coordinator's port to a Vehicle actor in the same process. The actor changes when
/// it is restarted; in between, sends fail with a reason.
#[derive(Default)]
pub struct LocalPort {
    actor: Mutex<Option<ActorRef<VehicleMsg>>>,
}

impl LocalPort {
    /// A port with no actor yet.
    pub fn new() -> Arc<Self> {
        Arc::new(LocalPort::default())
    }

    /// Points the port at the vehicle's current actor (`None` while it restarts).
    pub fn set(&self, actor: Option<ActorRef<VehicleMsg>>) {
        *self.actor.lock().unwrap_or_else(PoisonError::into_inner) = actor;
    }

    /// The vehicle's current actor.
    pub fn actor(&self) -> Option<ActorRef<VehicleMsg>> {
        self.actor
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }
}

impl VehiclePort for LocalPort {
    fn send(&self, msg: ToVehicle) -> Result<(), String> {
        match self.actor() {
            Some(a) => a
                .cast(VehicleMsg::Protocol(msg))
                .map_err(|e| format!("the vehicle actor did not take the message: {e}")),
            None => Err("the vehicle actor is not running (restarting)".into()),
        }
    }
}
