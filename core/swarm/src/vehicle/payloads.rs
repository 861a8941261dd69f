//! A vehicle's payload slots over time: which slots start (or wait for a plugin), what
//! happens when plugins are loaded and unloaded, and run-time attach and detach.
//!
//! - A slot whose kind no loaded provider offers is not started: it waits
//!   ([`ChildStatus::WaitingForPlugin`](skein_model::supervision::ChildStatus), with the
//!   kind named in the listing) and spends no restart budget.
//! - [`VehicleMsg::PluginsChanged`] (a plugin was loaded or unloaded in this process)
//!   starts every waiting slot that a provider now offers, and stops every running
//!   payload whose library is gone (its driver's `shutdown` runs first); those slots
//!   wait again, or start from another provider of their kind. This message is local to
//!   the vehicle's process, not part of the swarm protocol: payload instances and the
//!   plugin manager that creates them live in the vehicle's process.
//! - [`ToVehicle::AttachPayload`](crate::protocol::ToVehicle) adds a slot and answers once
//!   its driver exists (a config the plugin refuses removes the slot again and is answered
//!   naming `config`); [`ToVehicle::DetachPayload`](crate::protocol::ToVehicle) runs the
//!   driver's `shutdown`, then removes the slot. Both last until skein restarts: the
//!   vehicle model in the configuration is what a restart starts from.

use super::VehicleActorState;
use super::messages::{AfterStop, Child, VehicleMsg};
use super::shared::payload_json;
use crate::payload::{PayloadMsg, PayloadShared, Placement, check_attach, placement};
use crate::protocol::{FromVehicle, PayloadCommandError};
use crate::supervision::Exit;
use ractor::{ActorProcessingErr, ActorRef};
use skein_model::supervision::{ChildKind, ChildStatus};
use skein_payload::PayloadSpec;

impl VehicleActorState {
    /// The supervision status of the payload in `slot`.
    fn payload_status(&self, slot: &str) -> Option<ChildStatus> {
        let path = self.children.path(&Child::Payload(slot.to_string()));
        self.children.supervision().record(&path).map(|r| r.status)
    }

    /// Starts the payload in `slot` if a loaded provider offers its kind; otherwise
    /// marks it waiting for a plugin. `ready` is told once its driver exists.
    pub(super) async fn start_payload(
        &mut self,
        myself: &ActorRef<VehicleMsg>,
        slot: &str,
        ready: Option<tokio::sync::oneshot::Sender<()>>,
    ) -> Result<(), ActorProcessingErr> {
        let Some(shared) = self.shared.payload(slot) else {
            return Ok(());
        };
        let providers = self.context.services.payloads.providers();
        let child = Child::Payload(slot.to_string());
        match placement(&shared.spec, &providers) {
            Placement::Wait(why) => {
                tracing::info!(vehicle = %self.shared.id, slot, "{why}");
                shared.set_waiting(Some(why));
                self.children
                    .supervision()
                    .waiting(&self.children.path(&child), ChildKind::Payload);
                Ok(())
            }
            Placement::Create(_) => {
                shared.set_waiting(None);
                let handle = self.spawn(myself, &child, ready).await?;
                self.children.started(child, handle);
                Ok(())
            }
        }
    }

    /// True when the payload in `slot` is not running now because it waits for a plugin.
    pub(super) fn is_waiting(&self, slot: &str) -> bool {
        self.payload_status(slot) == Some(ChildStatus::WaitingForPlugin)
    }

    /// A plugin was loaded or unloaded: start the waiting slots a provider now offers, and
    /// stop the payloads whose library is no longer loaded.
    pub(super) async fn plugins_changed(
        &mut self,
        myself: &ActorRef<VehicleMsg>,
    ) -> Result<(), ActorProcessingErr> {
        let providers = self.context.services.payloads.providers();
        let payloads = self.shared.payloads();
        for (slot, p) in payloads.iter() {
            if self.stopping.contains(slot) || self.attaching.contains_key(slot) {
                continue;
            }
            let child = Child::Payload(slot.clone());
            if self.children.get(&child).is_some() {
                let gone = match p.served_by() {
                    Some(by) => !providers.iter().any(|pr| pr.name == by.plugin),
                    None => matches!(placement(&p.spec, &providers), Placement::Wait(_)),
                };
                if gone {
                    self.stop_payload(myself, slot, AfterStop::Reevaluate);
                }
            } else if self.is_waiting(slot)
                && let Err(e) = self.start_payload(myself, slot, None).await
            {
                let exit = Exit::Failed(format!("start failed: {e}"));
                self.child_ended(myself, child, exit).await?;
            }
        }
        Ok(())
    }

    /// Stops the running payload in `slot` on purpose: its driver's `shutdown` runs on its
    /// thread (within the call deadline), then [`VehicleMsg::PayloadStopped`] comes back.
    /// The slot shows as waiting meanwhile.
    fn stop_payload(&mut self, myself: &ActorRef<VehicleMsg>, slot: &str, after: AfterStop) {
        let child = Child::Payload(slot.to_string());
        self.stopping.insert(slot.to_string());
        if let Some(p) = self.shared.payload(slot) {
            p.set_waiting(Some(format!(
                "stopping; then waiting for a plugin providing payload kind `{}`",
                p.spec.kind
            )));
        }
        self.children
            .supervision()
            .waiting(&self.children.path(&child), ChildKind::Payload);
        let actor = self.children.take(&child).map(|h| h.actor::<PayloadMsg>());
        let me = myself.clone();
        let deadline = self.children.supervision().config.watchdog_deadline();
        let slot = slot.to_string();
        tokio::spawn(async move {
            if let Some(actor) = actor {
                // A driver that does not shut down in time fails its actor (its thread is
                // abandoned); the slot goes on either way.
                let _ = actor.call(PayloadMsg::Shutdown, Some(deadline)).await;
                actor.stop(None);
            }
            let _ = me.cast(VehicleMsg::PayloadStopped(slot, after));
        });
    }

    /// A payload stopped on purpose is gone: finish what stopping it was for.
    pub(super) async fn payload_stopped(
        &mut self,
        myself: &ActorRef<VehicleMsg>,
        slot: String,
        after: AfterStop,
    ) -> Result<(), ActorProcessingErr> {
        self.stopping.remove(&slot);
        match after {
            AfterStop::Reevaluate => {
                // Back to waiting, or on another provider of its kind at once.
                let child = Child::Payload(slot.clone());
                if self.children.get(&child).is_none()
                    && let Err(e) = self.start_payload(myself, &slot, None).await
                {
                    let exit = Exit::Failed(format!("start failed: {e}"));
                    self.child_ended(myself, child, exit).await?;
                }
            }
            AfterStop::Detach(request_id) => {
                let removed = self.forget_payload(&slot);
                (self.uplink)(FromVehicle::PayloadResult {
                    id: self.shared.id.clone(),
                    request_id,
                    result: Ok(serde_json::json!({
                        "detached": slot,
                        "kind": removed.map(|p| p.spec.kind.clone()),
                    })),
                });
            }
        }
        Ok(())
    }

    /// Removes `slot` from the vehicle and from the supervision tree.
    fn forget_payload(&mut self, slot: &str) -> Option<std::sync::Arc<PayloadShared>> {
        let path = self.children.path(&Child::Payload(slot.to_string()));
        self.children.supervision().remove(&path);
        self.shared.remove_payload(slot)
    }

    /// [`ToVehicle::AttachPayload`](crate::protocol::ToVehicle): checks the request, adds
    /// the slot and starts it; answered when the driver exists (or could not be created).
    pub(super) async fn attach_payload(
        &mut self,
        myself: &ActorRef<VehicleMsg>,
        request_id: u64,
        spec: PayloadSpec,
    ) -> Result<(), ActorProcessingErr> {
        let answer = |this: &Self, result| {
            (this.uplink)(FromVehicle::PayloadResult {
                id: this.shared.id.clone(),
                request_id,
                result,
            });
        };
        let providers = self.context.services.payloads.providers();
        let payloads = self.shared.payloads();
        if let Err(r) = check_attach(&spec, payloads.keys().map(String::as_str), &providers) {
            let (field, error) = (r.field.to_string(), r.error);
            let e = if r.conflict {
                PayloadCommandError::Conflict { field, error }
            } else {
                PayloadCommandError::Invalid { field, error }
            };
            answer(self, Err(e));
            return Ok(());
        }
        let slot = spec.slot.clone();
        if !self.shared.insert_payload(PayloadShared::new(spec)) {
            answer(
                self,
                Err(PayloadCommandError::Conflict {
                    field: "slot".into(),
                    error: format!("slot `{slot}` exists already on this vehicle"),
                }),
            );
            return Ok(());
        }
        let (tx, rx) = tokio::sync::oneshot::channel();
        self.attaching.insert(slot.clone(), request_id);
        if let Err(e) = self.start_payload(myself, &slot, Some(tx)).await {
            let exit = Exit::Failed(format!("start failed: {e}"));
            return self.child_ended(myself, Child::Payload(slot), exit).await;
        }
        let me = myself.clone();
        tokio::spawn(async move {
            // Dropped unanswered when the driver could not be created: the actor's failure
            // answers the attach then (see `attach_failed`).
            if rx.await.is_ok() {
                let _ = me.cast(VehicleMsg::PayloadReady(slot));
            }
        });
        tracing::info!(vehicle = %self.shared.id, "payload attached at run time (until restart)");
        Ok(())
    }

    /// The driver of an attached slot exists: the attach is answered with the payload.
    pub(super) fn payload_ready(&mut self, slot: &str) {
        let Some(request_id) = self.attaching.remove(slot) else {
            return;
        };
        let result = match self.shared.payload(slot) {
            Some(p) => Ok(payload_json(&p, self.payload_status(slot))),
            None => Err(PayloadCommandError::NotFound(format!(
                "slot `{slot}` was detached meanwhile"
            ))),
        };
        (self.uplink)(FromVehicle::PayloadResult {
            id: self.shared.id.clone(),
            request_id,
            result,
        });
    }

    /// If `slot` was being attached, its first driver could not be created: the slot is
    /// removed again and the attach answered naming the config (which is what a plugin
    /// refuses at creation). Returns false for any other slot.
    pub(super) fn attach_failed(&mut self, slot: &str, reason: &str) -> bool {
        let Some(request_id) = self.attaching.remove(slot) else {
            return false;
        };
        self.forget_payload(slot);
        (self.uplink)(FromVehicle::PayloadResult {
            id: self.shared.id.clone(),
            request_id,
            result: Err(PayloadCommandError::Invalid {
                field: "config".into(),
                error: reason.to_string(),
            }),
        });
        true
    }

    /// [`ToVehicle::DetachPayload`](crate::protocol::ToVehicle): runs the driver's
    /// `shutdown`, then removes the slot and answers.
    pub(super) async fn detach_payload(
        &mut self,
        myself: &ActorRef<VehicleMsg>,
        request_id: u64,
        slot: String,
    ) -> Result<(), ActorProcessingErr> {
        let refuse = |this: &Self, e| {
            (this.uplink)(FromVehicle::PayloadResult {
                id: this.shared.id.clone(),
                request_id,
                result: Err(e),
            });
        };
        if self.shared.payload(&slot).is_none() {
            let slots: Vec<String> = self.shared.payloads().keys().cloned().collect();
            refuse(
                self,
                PayloadCommandError::NotFound(format!(
                    "vehicle {} has no payload slot `{slot}` (slots: {})",
                    self.shared.id,
                    slots.join(", ")
                )),
            );
            return Ok(());
        }
        if self.stopping.contains(&slot) || self.attaching.contains_key(&slot) {
            refuse(
                self,
                PayloadCommandError::Conflict {
                    field: "slot".into(),
                    error: format!("payload `{slot}` is being attached or stopped: try again"),
                },
            );
            return Ok(());
        }
        if self.children.get(&Child::Payload(slot.clone())).is_some() {
            self.stop_payload(myself, &slot, AfterStop::Detach(request_id));
            Ok(())
        } else {
            // Waiting, failed or between restarts: nothing runs, nothing to shut down.
            self.payload_stopped(myself, slot, AfterStop::Detach(request_id))
                .await
        }
    }
}
