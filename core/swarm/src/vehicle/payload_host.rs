//! The vehicle side of [`PayloadHost`]: what a payload driver may reach of its vehicle,
//! the swarm, the event stream and the simulator.

use super::VehicleShared;
use super::fleet::Fleet;
use crate::context::SwarmContext;
use crate::events::SwarmEvent;
use crate::payload::PayloadShared;
use serde_json::Value;
use skein_mavlink::MavMessage;
use skein_model::vehicle::VehicleSnapshot;
use skein_payload::{PayloadHost, PayloadState, SimAircraft};
use std::sync::Arc;
use tokio::sync::broadcast;

/// The vehicle side of [`PayloadHost`] for one payload slot.
pub struct VehiclePayloadHost {
    vehicle: Arc<VehicleShared>,
    context: Arc<SwarmContext>,
    fleet: Fleet,
    events: broadcast::Sender<SwarmEvent>,
    slot: String,
    shared: Arc<PayloadShared>,
}

impl VehiclePayloadHost {
    /// The host for the payload `shared` of `vehicle` (its siblings are looked up in the
    /// vehicle's current payloads, so slots attached later are visible); `fleet` is the
    /// swarm its driver sees.
    pub fn new(
        vehicle: Arc<VehicleShared>,
        context: Arc<SwarmContext>,
        fleet: Fleet,
        events: broadcast::Sender<SwarmEvent>,
        shared: Arc<PayloadShared>,
    ) -> Arc<Self> {
        Arc::new(VehiclePayloadHost {
            vehicle,
            context,
            fleet,
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
        self.fleet.snapshots()
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
        self.shared.publish_state(state);
    }

    fn payload_state(&self, slot: &str) -> Option<PayloadState> {
        self.vehicle.payload(slot).and_then(|p| p.state())
    }

    fn publish_frame(&self, jpeg: Vec<u8>) {
        self.shared.publish_frame(jpeg);
    }

    fn set_simulated_link(&self, loss_fraction: f64, latency_ms: f64) -> bool {
        match self.context.simulator() {
            Some(sim) if self.vehicle.simulated => {
                sim.set_link_quality(self.vehicle.link.sysid, loss_fraction, latency_ms)
            }
            _ => false,
        }
    }

    fn sim_aircraft(&self) -> Vec<SimAircraft> {
        match (self.context.simulator(), self.context.frame()) {
            (Some(sim), Some(frame)) if self.vehicle.simulated => sim.intruders(&frame),
            _ => Vec::new(),
        }
    }

    fn payload_frame(&self, slot: &str) -> Option<Arc<Vec<u8>>> {
        self.vehicle.payload(slot).and_then(|p| p.frame())
    }
}
