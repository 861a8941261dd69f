//! Discovery: a vehicle joins when its first heartbeat reaches an endpoint. The
//! coordinator names it from the endpoint's specs, creates its persistent part
//! ([`VehicleShared`]: link route, telemetry, setpoint stream) and its proxy, and starts
//! its Vehicle actor under itself.

use super::CoordinatorState;
use super::messages::CoordinatorMsg;
use super::proxy::VehicleProxy;
use super::supervisor::Node;
use crate::events::SwarmEvent;
use crate::vehicle::VehicleShared;
use ractor::{ActorProcessingErr, ActorRef};
use skein_link::endpoint::Discovery;
use skein_link::{ConnectionAddress, VehicleLink};

/// How one configured vehicle on an endpoint is named.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct VehicleSpec {
    /// The id users see; default `uav-<sysid>`.
    pub id: Option<String>,
    /// Only the vehicle with this sysid gets this spec; `None` = the first one heard.
    pub sysid: Option<u8>,
    /// Model name (default `generic`).
    pub model: Option<String>,
    /// MAVLink 2 signing of its link: installed on the endpoint for `sysid` (for every
    /// vehicle of the endpoint when `sysid` is `None`) before the first frame is read.
    pub signing: Option<skein_link::SigningSpec>,
}

/// An endpoint to open and the vehicles expected on it.
#[derive(Debug, Clone, PartialEq)]
pub struct EndpointSpec {
    /// Connection string.
    pub connection: ConnectionAddress,
    /// Names and models for vehicles heard there (others get defaults).
    pub vehicles: Vec<VehicleSpec>,
    /// True when the endpoint leads to the in-process simulator.
    pub simulated: bool,
}

impl CoordinatorState {
    pub(super) async fn on_discovered(
        &mut self,
        myself: &ActorRef<CoordinatorMsg>,
        endpoint_index: usize,
        d: Discovery,
    ) -> Result<(), ActorProcessingErr> {
        let Some((endpoint, spec)) = self.endpoints.get(endpoint_index) else {
            return Ok(());
        };
        let endpoint = endpoint.clone();
        let simulated = spec.simulated;
        let taken: Vec<&str> = self.vehicles.keys().map(String::as_str).collect();
        let vspec = spec
            .vehicles
            .iter()
            .find(|s| s.sysid == Some(d.sysid))
            .or_else(|| {
                spec.vehicles.iter().find(|s| {
                    s.sysid.is_none() && s.id.as_deref().is_none_or(|id| !taken.contains(&id))
                })
            })
            .cloned()
            .unwrap_or_default();
        let mut id = vspec.id.unwrap_or_else(|| format!("uav-{}", d.sysid));
        if self.vehicles.contains_key(&id) {
            id = format!("{id}-{endpoint_index}");
        }
        if self.vehicles.contains_key(&id) {
            return Ok(());
        }
        let model = self
            .context
            .config
            .model(vspec.model.as_deref().unwrap_or("generic"));
        let link = VehicleLink::new(
            endpoint.clone(),
            d.sysid,
            d.compid,
            self.context.config.stream_rate_hz,
            self.context.config.link_setup.clone(),
        );
        link.follow_fence(self.context.fence_plans());
        let shared = VehicleShared::new(id.clone(), model, link, simulated);
        self.fleet.add(shared.clone());
        self.vehicles
            .insert(id.clone(), VehicleProxy::local(shared));
        self.metrics.vehicles.set(self.vehicles.len() as i64);
        self.publish_vehicles();
        self.start_child(myself, Node::Vehicle(id.clone())).await?;
        tracing::info!("{id} joined (sysid {}, {})", d.sysid, endpoint.address());
        self.emit(SwarmEvent::VehicleJoined {
            id: id.clone(),
            sysid: d.sysid,
            connection: endpoint.address().to_string(),
        });
        Ok(())
    }
}
