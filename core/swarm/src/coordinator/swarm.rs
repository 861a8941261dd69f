//! Starting and stopping a swarm: the endpoints, the coordinator, the event bus and the
//! metrics.

use super::discovery::EndpointSpec;
use super::messages::{AdminMsg, CoordinatorMsg, FleetMsg};
use super::{Coordinator, CoordinatorArgs};
use crate::config::SwarmConfig;
use crate::events::SwarmEvent;
use crate::load::LoadMonitor;
use crate::metrics::Metrics;
use crate::services::SwarmServices;
use ractor::{Actor, ActorRef};
use skein_link::{Endpoint, Identity};
use std::sync::Arc;
use tokio::sync::broadcast;

/// A running swarm: the coordinator, its endpoints, the event bus and the metrics.
pub struct Swarm {
    /// The coordinator actor.
    pub coordinator: ActorRef<CoordinatorMsg>,
    /// The event bus (subscribe for the stream).
    pub events: broadcast::Sender<SwarmEvent>,
    /// The opened endpoints, in configuration order.
    pub endpoints: Vec<Arc<Endpoint>>,
    /// The metrics registry (`GET /metrics`), for services that add to it.
    pub metrics: Arc<Metrics>,
    /// How late the process runs, and whether optional work is shed ([`crate::load`]).
    pub load: Arc<LoadMonitor>,
    /// What the coordinator publishes for the API's pure reads ([`super::published`]).
    pub reads: super::SwarmReads,
    /// This process's vehicles as they join (their links: what goes to every local
    /// vehicle, such as RTK corrections, reads them here).
    pub fleet: crate::vehicle::fleet::Fleet,
    handle: ractor::concurrency::JoinHandle<()>,
}

/// Why the swarm could not start.
#[derive(Debug)]
pub struct StartError(pub String);

impl std::fmt::Display for StartError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for StartError {}

impl Swarm {
    /// Opens every endpoint and starts the coordinator.
    ///
    /// # Errors
    /// An endpoint that cannot be opened (named with its connection string), or the
    /// coordinator failing to start.
    pub async fn start(
        config: SwarmConfig,
        services: SwarmServices,
        identity: Identity,
        endpoints: Vec<EndpointSpec>,
    ) -> Result<Swarm, StartError> {
        let mut opened = Vec::new();
        for spec in endpoints {
            let ep = Endpoint::open(spec.connection.clone(), identity)
                .await
                .map_err(|e| StartError(format!("{}: {e}", spec.connection)))?;
            for v in &spec.vehicles {
                if let Some(s) = &v.signing {
                    ep.set_signing(v.sysid, s.signing());
                }
            }
            opened.push((ep, spec));
        }
        let (events, _) = broadcast::channel(4096);
        let endpoints = opened.iter().map(|(e, _)| e.clone()).collect();
        let metrics = Arc::new(Metrics::new());
        let load = LoadMonitor::start();
        let registry = crate::vehicle::fleet::FleetRegistry::new();
        let fleet = registry.reader();
        let (coordinator, handle) = Actor::spawn(
            None,
            Coordinator,
            CoordinatorArgs {
                config,
                services,
                endpoints: opened,
                events: events.clone(),
                metrics: metrics.clone(),
                load: load.clone(),
                fleet: registry,
            },
        )
        .await
        .map_err(|e| StartError(format!("coordinator did not start: {e}")))?;
        let reads = match coordinator
            .call(
                |r| AdminMsg::GetReads(r).into(),
                Some(std::time::Duration::from_secs(10)),
            )
            .await
        {
            Ok(ractor::rpc::CallResult::Success(reads)) => reads,
            _ => {
                coordinator.stop(None);
                return Err(StartError("the coordinator did not answer".into()));
            }
        };
        Ok(Swarm {
            coordinator,
            events,
            endpoints,
            metrics,
            load,
            reads,
            fleet,
            handle,
        })
    }

    /// Forwards every endpoint's frames to a ground station at `address` and its frames
    /// back (see [`skein_link::gcs`]); the forwarder's counters join `GET /api/v1/links`
    /// and `/metrics`.
    ///
    /// # Errors
    /// The forwarder's socket could not be opened (named with its address).
    pub async fn forward_to_gcs(
        &self,
        address: skein_link::ConnectionAddress,
    ) -> Result<Arc<skein_link::GcsForwarder>, StartError> {
        let fwd = skein_link::GcsForwarder::start(address.clone(), self.endpoints.clone())
            .await
            .map_err(|e| StartError(format!("ground-station forward {address}: {e}")))?;
        let _ = self.coordinator.cast(FleetMsg::SetGcs(fwd.clone()).into());
        Ok(fwd)
    }

    /// Resolves when the coordinator has stopped or failed (for the process to exit).
    pub async fn stopped(&mut self) {
        let _ = (&mut self.handle).await;
    }

    /// True when the coordinator is still running.
    pub fn is_running(&self) -> bool {
        !self.handle.is_finished()
    }

    /// Stops the coordinator (and with it every actor under it) and waits for it.
    pub async fn stop(self) {
        self.coordinator.stop(None);
        let _ = self.handle.await;
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use skein_link::ConnectionAddress;
    use skein_mavlink::dialect::{HEARTBEAT_DATA, MavAutopilot, MavType};
    use skein_mavlink::{Encoder, MavMessage};
    use std::time::{Duration, Instant};

    /// A swarm of defaults on one `udpin` endpoint of a free loopback port (the tests of
    /// the coordinator's start, stop and reads).
    pub(crate) async fn swarm_on_udp() -> Swarm {
        let local: std::net::SocketAddr = "127.0.0.1:0".parse().unwrap();
        Swarm::start(
            SwarmConfig::default(),
            SwarmServices::default(),
            Identity::default(),
            vec![EndpointSpec {
                connection: ConnectionAddress::UdpIn(local),
                vehicles: Vec::new(),
                simulated: false,
            }],
        )
        .await
        .expect("swarm starts")
    }

    /// A PX4 of sysid 1 for `swarm`'s first endpoint: each call sends one `HEARTBEAT`.
    pub(crate) fn px4_heartbeats(swarm: &Swarm) -> impl FnMut() + use<> {
        let port = swarm.endpoints[0].local_addr().expect("udp endpoint");
        let px4 = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let mut enc = Encoder::new(1, 1);
        let heartbeat = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            mavtype: MavType::MAV_TYPE_QUADROTOR,
            autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
            ..Default::default()
        });
        move || {
            px4.send_to(enc.encode(&heartbeat).as_bytes(), port)
                .unwrap();
        }
    }

    /// A stopped swarm lets go of everything its vehicles held: their setpoint streams
    /// stop and their endpoints' ports are free again. Each vehicle's payload sink lives
    /// in its endpoint's route, which the vehicle's link keeps; a sink holding the
    /// vehicle strongly made a cycle, and a stopped swarm went on streaming its last
    /// setpoints, unsupervised, from ports nobody could bind again.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_stopped_swarm_frees_its_vehicles_and_their_ports() {
        let swarm = swarm_on_udp().await;
        let port = swarm.endpoints[0].local_addr().expect("udp endpoint");
        // A PX4 that announces itself until the coordinator has made its vehicle.
        let mut heartbeat = px4_heartbeats(&swarm);
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            heartbeat();
            let listed = swarm
                .coordinator
                .call(
                    |r| FleetMsg::ListVehicles(r).into(),
                    Some(Duration::from_secs(5)),
                )
                .await;
            if matches!(listed, Ok(ractor::rpc::CallResult::Success(v)) if v.len() == 1) {
                break;
            }
            assert!(Instant::now() < deadline, "the vehicle never joined");
            tokio::time::sleep(Duration::from_millis(50)).await;
        }

        swarm.stop().await;
        let deadline = Instant::now() + Duration::from_secs(5);
        while let Err(e) = std::net::UdpSocket::bind(port) {
            assert!(
                Instant::now() < deadline,
                "{port} still bound 5 s after the swarm stopped: {e}"
            );
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }
}
