//! The `Px4Link` actor's mission protocol and fence: mission messages from the vehicle
//! into the [`MissionClient`](crate::mission::MissionClient), its transmissions and
//! deadlines out, and the fence syncs ([`crate::fence_sync`]) started on connect, on a
//! new plan and on demand.

use super::fence_autopilot::LinkAutopilot;
use super::{Px4LinkMsg, Px4LinkState, VehicleLink};
use crate::command::LinkError;
use crate::fence_sync;
use crate::mission::{MISSION_TIMEOUT, MissionOp, MissionTransmit};
use ractor::ActorRef;
use skein_mavlink::MavMessage;
use std::sync::Arc;

/// Casts [`Px4LinkMsg::SyncFence`] to `myself` on every new plan the link follows, until
/// the actor or the plans are gone.
pub(super) fn watch_plans(link: &VehicleLink, myself: &ActorRef<Px4LinkMsg>) {
    let Some(mut plans) = link.fence().plans().cloned() else {
        return;
    };
    let me = myself.clone();
    tokio::spawn(async move {
        while plans.changed().await.is_ok() {
            if me
                .cast(Px4LinkMsg::SyncFence {
                    only_if_changed: true,
                })
                .is_err()
            {
                break;
            }
        }
    });
}

impl Px4LinkState {
    fn transmit_missions(&self, myself: &ActorRef<Px4LinkMsg>, out: Vec<MissionTransmit>) {
        for t in out {
            let _ = self.link.endpoint.send(self.link.sysid, &t.msg);
            if let Some((kind, generation)) = t.deadline {
                myself.send_after(MISSION_TIMEOUT, move || {
                    Px4LinkMsg::MissionDeadline(kind, generation)
                });
            }
        }
    }

    /// A frame of the autopilot: the mission client's, if it is a mission message.
    #[allow(deprecated)] // MISSION_REQUEST, which PX4 may still send
    pub(super) fn on_mission_message(&mut self, myself: &ActorRef<Px4LinkMsg>, msg: &MavMessage) {
        if !matches!(
            msg,
            MavMessage::MISSION_REQUEST_INT(_)
                | MavMessage::MISSION_REQUEST(_)
                | MavMessage::MISSION_ACK(_)
                | MavMessage::MISSION_COUNT(_)
                | MavMessage::MISSION_ITEM_INT(_)
        ) {
            return;
        }
        let identity = self.link.endpoint.identity();
        let out = self
            .missions
            .on_message(msg, (identity.sysid, identity.compid), self.target());
        self.transmit_missions(myself, out);
    }

    /// The mission and fence messages of [`Px4LinkMsg`].
    pub(super) fn on_mission_msg(&mut self, myself: &ActorRef<Px4LinkMsg>, msg: Px4LinkMsg) {
        let target = self.target();
        match msg {
            Px4LinkMsg::MissionUpload(kind, items, reply) => {
                if self.link.is_lost() {
                    let _ = reply.send(Err(LinkError::NoLink));
                    return;
                }
                let out = self
                    .missions
                    .start(kind, MissionOp::Upload(items, Some(reply)), target);
                self.transmit_missions(myself, out);
            }
            Px4LinkMsg::MissionDownload(kind, reply) => {
                if self.link.is_lost() {
                    let _ = reply.send(Err(LinkError::NoLink));
                    return;
                }
                let out = self
                    .missions
                    .start(kind, MissionOp::Download(Some(reply)), target);
                self.transmit_missions(myself, out);
            }
            Px4LinkMsg::MissionDeadline(kind, generation) => {
                let out = self.missions.on_deadline(kind, generation, target);
                self.transmit_missions(myself, out);
            }
            Px4LinkMsg::SyncFence { only_if_changed } => {
                // Nothing to hold yet (no swarm origin), or nobody heard: the next plan
                // or the greeting brings it.
                let heard = self.link.with_telemetry(|t| t.heartbeat.is_some());
                if let (Some(plan), true) = (self.link.fence().current(), heard) {
                    let autopilot = LinkAutopilot {
                        link: myself.clone(),
                        vehicle: self.link.clone(),
                    };
                    tokio::spawn(fence_sync::sync(autopilot, plan, only_if_changed));
                }
            }
            Px4LinkMsg::TryFence(plan, reply) => {
                let autopilot = LinkAutopilot {
                    link: myself.clone(),
                    vehicle: Arc::clone(&self.link),
                };
                tokio::spawn(async move {
                    let status = fence_sync::sync(autopilot, plan, false).await;
                    let _ = reply.send(status);
                });
            }
            _ => {}
        }
    }
}
