//! What the coordinator is told about the vehicles' payloads ([`PayloadMsg`]): a payload's
//! state, commands for it, slots attached and detached at run time (fanned out like
//! commands, see [`super::fan_out`]), and payload plugins loaded, unloaded or reloaded.

use super::CoordinatorState;
use super::messages::CoordinatorMsg;
use crate::payload::PayloadShared;
use crate::protocol::{PayloadCommandError, ToVehicle};
use crate::vehicle::VehicleMsg;
use ractor::{ActorRef, RpcReplyPort};
use std::sync::Arc;
use std::time::Instant;

/// Messages about the vehicles' payloads (inside [`CoordinatorMsg::Payload`]).
pub enum PayloadMsg {
    /// A vehicle's payload (state, frames); `Err` names what is missing.
    GetPayload(
        String,
        String,
        RpcReplyPort<Result<Arc<PayloadShared>, String>>,
    ),
    /// A command for a vehicle's payload; the payload's answer or why there is none.
    PayloadCommand(
        String,
        String,
        serde_json::Value,
        RpcReplyPort<Result<serde_json::Value, PayloadCommandError>>,
    ),
    /// Attach a payload slot to a vehicle at run time (until restart): the payload as
    /// listed once its driver exists, or why not (naming the field).
    AttachPayload(
        String,
        skein_payload::PayloadSpec,
        RpcReplyPort<Result<serde_json::Value, PayloadCommandError>>,
    ),
    /// Detach a vehicle's payload slot (its driver's `shutdown` runs first).
    DetachPayload(
        String,
        String,
        RpcReplyPort<Result<serde_json::Value, PayloadCommandError>>,
    ),
    /// A payload plugin was loaded or unloaded in this process: every local vehicle starts
    /// the slots now provided and stops the payloads whose library is gone.
    PluginsChanged,
    /// Payload instances (vehicle id, slot) whose plugin was reloaded at this instant: their
    /// vehicles re-create them on the new build (those created since are left alone).
    RefreshPayloads(Vec<(String, String)>, Instant),
    /// A payload command's vehicle had its time to answer.
    PayloadTimeout(u64),
}

impl CoordinatorState {
    /// Handles a [`PayloadMsg`].
    pub(super) fn handle_payload(&mut self, myself: &ActorRef<CoordinatorMsg>, msg: PayloadMsg) {
        match msg {
            PayloadMsg::GetPayload(id, slot, reply) => {
                let _ = reply.send(self.payload(&id, &slot));
            }
            PayloadMsg::PayloadCommand(id, slot, command, reply) => {
                let make = move |request_id| ToVehicle::PayloadCommand {
                    request_id,
                    slot,
                    command,
                };
                self.payload_request(myself, id, make, reply);
            }
            PayloadMsg::AttachPayload(id, spec, reply) => {
                let make = move |request_id| ToVehicle::AttachPayload { request_id, spec };
                self.payload_request(myself, id, make, reply);
            }
            PayloadMsg::DetachPayload(id, slot, reply) => {
                let make = move |request_id| ToVehicle::DetachPayload { request_id, slot };
                self.payload_request(myself, id, make, reply);
            }
            PayloadMsg::PluginsChanged => self.plugins_changed(),
            PayloadMsg::RefreshPayloads(instances, at) => self.refresh_payloads(instances, at),
            PayloadMsg::PayloadTimeout(request_id) => {
                self.on_payload_result(request_id, None);
            }
        }
    }

    /// The payload in `slot` of local vehicle `id`, or what is missing.
    fn payload(&self, id: &str, slot: &str) -> Result<Arc<PayloadShared>, String> {
        match self.vehicles.get(id) {
            None => Err(format!("no vehicle `{id}`")),
            Some(v) => v
                .local
                .as_ref()
                .and_then(|l| l.shared.payload(slot))
                .ok_or_else(|| self.no_slot(id, slot)),
        }
    }

    fn no_slot(&self, id: &str, slot: &str) -> String {
        let slots = self
            .vehicles
            .get(id)
            .and_then(|v| v.local.as_ref())
            .map(|l| l.shared.payloads().keys().cloned().collect::<Vec<_>>())
            .unwrap_or_default();
        format!(
            "vehicle {id} has no payload slot `{slot}` (slots: {})",
            slots.join(", ")
        )
    }

    /// Tells every local vehicle that the payload plugins changed.
    fn plugins_changed(&self) {
        // Local to this process: its vehicles create their payloads from the plugin
        // manager of this process.
        for v in self.vehicles.values() {
            if let Some(a) = v.local.as_ref().and_then(|l| l.port.actor()) {
                let _ = a.cast(VehicleMsg::PluginsChanged);
            }
        }
    }

    /// Tells the local vehicles of `instances` to re-create those payloads.
    fn refresh_payloads(&self, instances: Vec<(String, String)>, at: Instant) {
        for (id, slot) in instances {
            let actor = self
                .vehicles
                .get(&id)
                .and_then(|v| v.local.as_ref())
                .and_then(|l| l.port.actor());
            if let Some(a) = actor {
                let _ = a.cast(VehicleMsg::RefreshPayload(slot, at));
            }
        }
    }
}
