//! The vehicle side of [`PayloadHost`]: what a payload driver may reach of its vehicle,
//! the swarm, the event stream and the simulator.

use super::PayloadShared;
use crate::events::SwarmEvent;
use crate::vehicle::VehicleShared;
use crate::view::SwarmView;
use serde_json::Value;
use skein_mavlink::MavMessage;
use skein_model::geo::NedFrame;
use skein_model::vehicle::VehicleSnapshot;
use skein_payload::{PayloadHost, PayloadState, SimAircraft};
use std::sync::Arc;
use tokio::sync::broadcast;

/// The in-process simulator as the swarm reaches it (implemented by the binary): the
/// simulated radio link's quality, the non-cooperative aircraft the simulated cameras
/// render, and the ground truth for evaluation.
pub trait SimulatorControl: Send + Sync {
    /// Sets the fraction of datagrams lost (0..1) and the one-way latency (ms) of the
    /// simulated vehicle `sysid`. Returns false when there is no such vehicle.
    fn set_link_quality(&self, sysid: u8, loss_fraction: f64, latency_ms: f64) -> bool;
    /// The simulator's intruders now, positions in `frame` (the swarm frame).
    fn intruders(&self, _frame: &NedFrame) -> Vec<SimAircraft> {
        Vec::new()
    }
    /// Ground truth of every simulated vehicle and intruder now, with swarm-frame
    /// positions when `frame` is known (`GET /api/v1/sim/truth`).
    fn truth(&self, _frame: Option<&NedFrame>) -> Value {
        Value::Null
    }
}

/// The vehicle side of [`PayloadHost`] for one payload slot.
pub struct VehiclePayloadHost {
    vehicle: Arc<VehicleShared>,
    view: Arc<SwarmView>,
    events: broadcast::Sender<SwarmEvent>,
    slot: String,
    shared: Arc<PayloadShared>,
}

impl VehiclePayloadHost {
    /// The host for the payload `shared` of `vehicle` (its siblings are looked up in the
    /// vehicle's current payloads, so slots attached later are visible).
    pub fn new(
        vehicle: Arc<VehicleShared>,
        view: Arc<SwarmView>,
        events: broadcast::Sender<SwarmEvent>,
        shared: Arc<PayloadShared>,
    ) -> Arc<Self> {
        Arc::new(VehiclePayloadHost {
            vehicle,
            view,
            events,
            slot: shared.spec.slot.clone(),
            shared,
        })
    }
}

impl PayloadHost for VehiclePayloadHost {
    fn vehicle_id(&self) -> &str {
        &self.vehicle.id
    }

    fn vehicle(&self) -> VehicleSnapshot {
        self.vehicle.snapshot()
    }

    fn swarm(&self) -> Vec<VehicleSnapshot> {
        self.view.snapshots()
    }

    fn simulated(&self) -> bool {
        self.vehicle.simulated
    }

    fn send_mavlink(&self, msg: &MavMessage) -> Result<(), String> {
        self.vehicle
            .link
            .endpoint
            .send(self.vehicle.link.sysid, msg)
            .map_err(|e| e.to_string())
    }

    fn emit_event(&self, kind: &str, data: Value) {
        let _ = self.events.send(SwarmEvent::PayloadEvent {
            id: self.vehicle.id.clone(),
            slot: self.slot.clone(),
            kind: kind.to_string(),
            data,
        });
    }

    fn publish_state(&self, state: PayloadState) {
        *self
            .shared
            .state
            .write()
            .unwrap_or_else(std::sync::PoisonError::into_inner) = Some(state);
    }

    fn payload_state(&self, slot: &str) -> Option<PayloadState> {
        self.vehicle.payload(slot).and_then(|p| p.state())
    }

    fn publish_frame(&self, jpeg: Vec<u8>) {
        self.shared
            .frames
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.shared.frame.send_replace(Some(Arc::new(jpeg)));
    }

    fn set_simulated_link(&self, loss_fraction: f64, latency_ms: f64) -> bool {
        match self.view.simulator() {
            Some(sim) if self.vehicle.simulated => {
                sim.set_link_quality(self.vehicle.link.sysid, loss_fraction, latency_ms)
            }
            _ => false,
        }
    }

    fn sim_aircraft(&self) -> Vec<SimAircraft> {
        match (self.view.simulator(), self.view.frame()) {
            (Some(sim), Some(frame)) if self.vehicle.simulated => sim.intruders(&frame),
            _ => Vec::new(),
        }
    }

    fn payload_frame(&self, slot: &str) -> Option<Arc<Vec<u8>>> {
        self.vehicle
            .payload(slot)
            .and_then(|p| p.frame.borrow().clone())
    }
}
