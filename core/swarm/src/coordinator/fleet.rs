//! Vehicles and their links, as the coordinator is told of them ([`FleetMsg`]): discovery,
//! the vehicles' protocol messages, listings, a vehicle's `Px4Link`, link counters and
//! the ground-station forwarder.

use super::CoordinatorState;
use super::messages::{CoordinatorMsg, EndpointStats};
use crate::protocol::{FromVehicle, PayloadCommandError};
use ractor::{ActorProcessingErr, ActorRef, RpcReplyPort};
use skein_link::Px4LinkMsg;
use skein_link::endpoint::Discovery;
use skein_model::vehicle::VehicleSnapshot;
use std::sync::Arc;
use std::time::Duration;

/// Messages about the vehicles and their links (inside [`CoordinatorMsg::Fleet`]).
pub enum FleetMsg {
    /// An endpoint heard an autopilot it has no route for.
    Discovered {
        /// Index of the endpoint.
        endpoint: usize,
        /// What it heard.
        discovery: Discovery,
    },
    /// A vehicle's protocol message (acks, state changes, payload answers).
    FromVehicle(FromVehicle),
    /// All vehicles, sorted by id.
    ListVehicles(RpcReplyPort<Vec<VehicleSnapshot>>),
    /// A local vehicle's `Px4Link` actor (parameters); `Err` says why there is none.
    GetLink(
        String,
        RpcReplyPort<Result<ActorRef<Px4LinkMsg>, PayloadCommandError>>,
    ),
    /// Link statistics per endpoint.
    LinkStats(RpcReplyPort<Vec<EndpointStats>>),
    /// The ground-station forwarder, for its counters (see `Swarm::forward_to_gcs`).
    SetGcs(Arc<skein_link::GcsForwarder>),
}

impl CoordinatorState {
    /// Handles a [`FleetMsg`].
    pub(super) async fn handle_fleet(
        &mut self,
        myself: &ActorRef<CoordinatorMsg>,
        msg: FleetMsg,
    ) -> Result<(), ActorProcessingErr> {
        match msg {
            FleetMsg::Discovered {
                endpoint,
                discovery,
            } => self.on_discovered(myself, endpoint, discovery).await?,
            FleetMsg::FromVehicle(msg) => self.on_from_vehicle(msg),
            FleetMsg::ListVehicles(reply) => {
                let list = self.vehicles.values().map(|v| v.snapshot()).collect();
                let _ = reply.send(list);
            }
            FleetMsg::GetLink(id, reply) => self.get_link(id, reply),
            FleetMsg::LinkStats(reply) => {
                let _ = reply.send(self.link_stats());
            }
            FleetMsg::SetGcs(g) => self.gcs = Some(g),
        }
        Ok(())
    }

    fn on_from_vehicle(&mut self, msg: FromVehicle) {
        self.tap(&msg);
        match msg {
            FromVehicle::CommandAck {
                id,
                command_id,
                result,
            } => self.on_ack(id, command_id, result),
            FromVehicle::StateChanged { id, to, .. } => self.on_state_changed(&id, to),
            FromVehicle::PayloadResult {
                request_id, result, ..
            } => self.on_payload_result(request_id, Some(result)),
        }
    }

    /// The `Px4Link` of a vehicle of this process, asked from a task.
    fn get_link(
        &self,
        id: String,
        reply: RpcReplyPort<Result<ActorRef<Px4LinkMsg>, PayloadCommandError>>,
    ) {
        let Some(v) = self.vehicles.get(&id) else {
            let _ = reply.send(Err(PayloadCommandError::NotFound(format!(
                "no vehicle `{id}`"
            ))));
            return;
        };
        let actor = v.local.as_ref().and_then(|l| l.port.actor());
        tokio::spawn(async move {
            let link = match actor {
                Some(a) => match a
                    .call(
                        crate::vehicle::VehicleMsg::GetLink,
                        Some(Duration::from_secs(2)),
                    )
                    .await
                {
                    Ok(ractor::rpc::CallResult::Success(Some(link))) => Some(link),
                    _ => None,
                },
                None => None,
            };
            let _ = reply.send(link.ok_or_else(|| {
                PayloadCommandError::Unavailable(format!("the link of `{id}` is not running"))
            }));
        });
    }
}
