//! Escalation of a vehicle whose actor keeps failing: the vehicle is commanded to HOLD
//! (or LAND, `[supervision] vehicle_escalation`) through a separate safe-mode `Px4Link`
//! that does not depend on the failing actor, its stream stops once PX4 has switched,
//! and it is marked failed (it gets no more commands; its telemetry still shows).

use super::CoordinatorState;
use super::messages::CoordinatorMsg;
use crate::supervision::{self, VehicleEscalation};
use ractor::{Actor, ActorRef};
use skein_link::{LinkCommand, Px4Link, Px4LinkArgs, Px4LinkMsg};
use skein_model::px4::Px4Mode;
use std::sync::Arc;

impl CoordinatorState {
    /// Commands the vehicle to HOLD or LAND through a fresh link actor (the Vehicle actor
    /// and its own link are gone), stops its setpoint stream once PX4 has switched, and
    /// marks it failed.
    pub(super) async fn escalate_vehicle(&mut self, myself: &ActorRef<CoordinatorMsg>, name: &str) {
        let Some(v) = self.vehicles.get_mut(name) else {
            return;
        };
        v.failed = true;
        let Some(local) = v.local.as_ref() else {
            return;
        };
        let shared = local.shared.clone();
        let action = self.context.config.supervision.vehicle_escalation;
        let events: skein_link::EventSink = Arc::new(|_| {});
        let spawned = Actor::spawn_linked(
            None,
            Px4Link,
            Px4LinkArgs {
                link: shared.link.clone(),
                events,
                components: None,
            },
            myself.get_cell(),
        )
        .await;
        let path = format!("{}/{name}", supervision::ROOT);
        let mode = match action {
            VehicleEscalation::Hold => Px4Mode::Hold,
            VehicleEscalation::Land => Px4Mode::Land,
        };
        match spawned {
            Ok((link, _)) => {
                if let Some(local) = self.vehicles.get_mut(name).and_then(|v| v.local.as_mut()) {
                    local.safe_link = Some(link.clone());
                }
                let sup = self.supervision.clone();
                tokio::spawn(async move {
                    let r = ractor::call_t!(
                        link,
                        Px4LinkMsg::Command,
                        15_000,
                        LinkCommand::SetMode(mode)
                    );
                    match r {
                        Ok(Ok(())) => {
                            // PX4 flies on its own now: the stream may stop.
                            shared.link.stream().set(None);
                            sup.escalated(
                                &path,
                                &format!("vehicle commanded to {mode} through a safe-mode link"),
                            );
                        }
                        other => {
                            let why = match other {
                                Ok(Err(e)) => e.to_string(),
                                Err(e) => e.to_string(),
                                Ok(Ok(())) => unreachable!(),
                            };
                            // Keep streaming the last (held) setpoint: PX4 stays in
                            // OFFBOARD holding position rather than failing safe.
                            sup.escalated(
                                &path,
                                &format!(
                                    "{mode} not confirmed ({why}); the stream keeps holding the last setpoint"
                                ),
                            );
                        }
                    }
                });
            }
            Err(e) => {
                self.supervision.escalated(
                    &path,
                    &format!("no safe-mode link ({e}); the stream keeps holding the last setpoint"),
                );
            }
        }
    }
}
