//! The Vehicle actor as a supervisor: it spawns its `Px4Link` (restarted on failure with
//! the same [`skein_link::VehicleLink`], so the socket, telemetry and setpoint stream are
//! untouched) and one payload actor per slot, applies their restart policy through the
//! shared [`Children`](crate::supervision::Children) table, and routes injected faults.
//! A payload whose kind no loaded plugin provides is not restarted: it waits for a plugin
//! (see [`super::payloads`]) without spending its restart budget.

use super::VehicleActorState;
use super::messages::{Child, VehicleMsg};
use super::payload_host::VehiclePayloadHost;
use super::shared::VehicleShared;
use crate::payload::{PayloadActor, PayloadArgs, PayloadMsg, Placement, placement};
use crate::supervision::{ChildHandle, Exit, Next};
use ractor::{Actor, ActorProcessingErr, ActorRef};
use skein_link::{Px4Link, Px4LinkArgs, Px4LinkMsg};
use skein_model::supervision::{ChildKind, FaultKind};
use std::sync::Arc;
use std::time::Instant;

impl VehicleActorState {
    /// `coordinator/<id>`.
    pub(super) fn path(&self) -> String {
        self.children.parent().to_string()
    }

    /// Spawns `child` linked under this actor (`ready`: told once a payload's driver
    /// exists).
    pub(super) async fn spawn(
        &self,
        myself: &ActorRef<VehicleMsg>,
        child: &Child,
        ready: Option<tokio::sync::oneshot::Sender<()>>,
    ) -> Result<ChildHandle, ActorProcessingErr> {
        Ok(match child {
            Child::Link => ChildHandle::new(spawn_link(myself, &self.shared).await?, |r| {
                Px4LinkMsg::Ping(r)
            }),
            Child::Payload(slot) => {
                let shared = self
                    .shared
                    .payload(slot)
                    .ok_or_else(|| format!("no payload slot `{slot}`"))?;
                let spec = shared.spec.clone();
                let host = VehiclePayloadHost::new(
                    self.shared.clone(),
                    self.context.clone(),
                    self.fleet.clone(),
                    self.events.clone(),
                    shared.clone(),
                );
                let (actor, _) = Actor::spawn_linked(
                    None,
                    PayloadActor,
                    PayloadArgs {
                        spec,
                        factory: self.context.services.payloads.clone(),
                        host,
                        shared,
                        ready,
                        // Half the watchdog's deadline: a stuck driver call fails the
                        // payload naming the call before the watchdog calls it hung.
                        call_deadline: self.children.supervision().config.watchdog_deadline() / 2,
                        load: self.children.supervision().load.clone(),
                        ticker: self.context.ticker.clone(),
                    },
                    myself.get_cell(),
                )
                .await?;
                ChildHandle::new(actor, PayloadMsg::Ping)
            }
        })
    }

    /// Starts `child` for the first time.
    pub(super) async fn start_child(
        &mut self,
        myself: &ActorRef<VehicleMsg>,
        child: Child,
    ) -> Result<(), ActorProcessingErr> {
        let handle = self.spawn(myself, &child, None).await?;
        self.children.started(child, handle);
        Ok(())
    }

    /// Starts `child` again after a failure noticed at `noticed`.
    pub(super) async fn restart_child(
        &mut self,
        myself: &ActorRef<VehicleMsg>,
        child: Child,
        noticed: Instant,
        reason: String,
    ) -> Result<(), ActorProcessingErr> {
        // A payload whose plugin is gone meanwhile waits for one instead.
        if let Child::Payload(slot) = &child
            && let Some(p) = self.shared.payload(slot)
            && let Placement::Wait(why) =
                placement(&p.spec, &self.context.services.payloads.providers())
        {
            p.set_waiting(Some(why));
            let path = self.children.path(&child);
            self.children
                .supervision()
                .waiting(&path, ChildKind::Payload);
            return Ok(());
        }
        match self.spawn(myself, &child, None).await {
            Ok(handle) => {
                self.children
                    .started_after_failure(child, handle, noticed, reason);
                Ok(())
            }
            // The replacement did not even start: that is another failure.
            Err(e) => {
                Box::pin(self.child_ended(
                    myself,
                    child,
                    Exit::Failed(format!("restart failed: {e}")),
                ))
                .await
            }
        }
    }

    /// Applies the policy to an ended child.
    pub(super) async fn child_ended(
        &mut self,
        myself: &ActorRef<VehicleMsg>,
        child: Child,
        exit: Exit,
    ) -> Result<(), ActorProcessingErr> {
        let noticed = Instant::now();
        let path = self.children.path(&child);
        let reason = exit.reason();
        if let Child::Payload(slot) = &child {
            // A slot being attached whose driver could not be created is removed again.
            if self.attach_failed(slot, &reason) {
                return Ok(());
            }
            // A payload whose plugin is gone is not a failure to count: it waits for one.
            if let Some(p) = self.shared.payload(slot)
                && let Placement::Wait(why) =
                    placement(&p.spec, &self.context.services.payloads.providers())
            {
                p.set_waiting(Some(why));
                self.children
                    .supervision()
                    .waiting(&path, ChildKind::Payload);
                return Ok(());
            }
        }
        match self.children.next(&child, exit) {
            Next::RestartNow => self.restart_child(myself, child, noticed, reason).await?,
            Next::RestartAfter(d) => {
                myself.send_after(d, move || VehicleMsg::RestartChild(child, noticed, reason));
            }
            Next::Escalate => match child {
                // Without its link the vehicle cannot work: fail, and let the coordinator
                // apply the vehicle's own policy (a new Vehicle starts a fresh link).
                Child::Link => {
                    return Err(format!("{path} keeps failing ({reason}): escalating").into());
                }
                Child::Payload(_) => self
                    .children
                    .supervision()
                    .escalated(&path, "payload disabled; the vehicle flies on"),
            },
            Next::Leave => {}
        }
        Ok(())
    }

    /// Routes a fault to `sub` (`"px4link"`, `"payload/<slot>"`).
    pub(super) fn inject(&self, sub: &str, kind: FaultKind) -> Result<(), String> {
        let unknown = || {
            let mut known = vec![
                format!("{}/px4link", self.path()),
                format!("{}/{}", self.path(), super::CONTROL_FAULT_TARGET),
            ];
            known.extend(
                self.shared
                    .payloads()
                    .keys()
                    .map(|s| format!("{}/payload/{s}", self.path())),
            );
            format!(
                "no actor `{}/{sub}` (known under this vehicle: {})",
                self.path(),
                known.join(", ")
            )
        };
        let child = match sub {
            "px4link" => Child::Link,
            other => match other.strip_prefix("payload/") {
                Some(slot) if self.shared.payload(slot).is_some() => {
                    Child::Payload(slot.to_string())
                }
                _ => return Err(unknown()),
            },
        };
        let not_running = || format!("{}/{sub} is not running", self.path());
        match child {
            Child::Link => self
                .children
                .actor::<Px4LinkMsg>(&child)
                .ok_or_else(not_running)?
                .cast(Px4LinkMsg::Fault(kind))
                .map_err(|e| e.to_string()),
            Child::Payload(_) => self
                .children
                .actor::<PayloadMsg>(&child)
                .ok_or_else(not_running)?
                .cast(PayloadMsg::Fault(kind))
                .map_err(|e| e.to_string()),
        }
    }

    /// The running payload actors.
    pub(super) fn payload_actors(&self) -> impl Iterator<Item = (&str, ActorRef<PayloadMsg>)> {
        self.children.iter().filter_map(|(k, h)| match k {
            Child::Payload(slot) => Some((slot.as_str(), h.actor::<PayloadMsg>())),
            Child::Link => None,
        })
    }
}

/// Message ids of the gimbal and camera protocols (GIMBAL_MANAGER_* 280–288, CAMERA_*
/// 259–263 and 271–276) that payloads want even when the autopilot sends them.
fn for_payloads(msg: &skein_mavlink::MavMessage) -> bool {
    let id = skein_mavlink::message_id(msg);
    (280..=288).contains(&id) || (259..=263).contains(&id) || (271..=276).contains(&id)
}

async fn spawn_link(
    myself: &ActorRef<VehicleMsg>,
    shared: &Arc<VehicleShared>,
) -> Result<ActorRef<Px4LinkMsg>, ActorProcessingErr> {
    let me = myself.clone();
    // Payloads may be attached at run time: the sink is always there, and forwards
    // nothing while the vehicle has no payload. It holds the vehicle weakly: the sink
    // lives in the endpoint's route, which the vehicle's link keeps alive, so a strong
    // reference would keep the vehicle (and its setpoint stream) alive for ever.
    let components: Option<skein_link::px4link::FrameSink> = {
        let me = myself.clone();
        let autopilot = shared.link.compid;
        let vehicle = Arc::downgrade(shared);
        Some(Arc::new(move |f: &skein_mavlink::Frame| {
            if (f.compid != autopilot || for_payloads(&f.msg))
                && vehicle.upgrade().is_some_and(|v| v.has_payloads())
            {
                let _ = me.cast(VehicleMsg::Component(Box::new(f.clone())));
            }
        }))
    };
    let (actor, _) = Actor::spawn_linked(
        None,
        Px4Link,
        Px4LinkArgs {
            link: shared.link.clone(),
            events: Arc::new(move |ev| {
                let _ = me.cast(VehicleMsg::Link(ev));
            }),
            components,
        },
        myself.get_cell(),
    )
    .await?;
    Ok(actor)
}
