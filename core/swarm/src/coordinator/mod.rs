//! The `Coordinator` actor: root of the actor tree, registry of the swarm, formation
//! engine (the paper's CoordinatorUAVModel), and, in `skein up`, supervisor of the
//! Vehicle actors of this process and of services such as the HTTP API.
//!
//! It reaches vehicles only through the swarm protocol ([`crate::protocol`]): each
//! vehicle is a [`VehicleProxy`] (a port for [`ToVehicle`](crate::protocol::ToVehicle)
//! messages and the vehicle's latest report). Commands fan out to every target at once
//! and are answered from the acknowledgements as they come ([`fan_out`]); nothing in
//! `handle` waits for a vehicle.
//!
//! A failed Vehicle actor is restarted by policy on the same persistent part, so its FSM
//! state, target and stream carry on; when its budget is spent the vehicle is commanded
//! to HOLD (or LAND) through a separate safe-mode link ([`escalation`]). A service (the
//! API) that keeps failing fails the coordinator itself: the process exits non-zero and
//! its outer supervisor (systemd, Docker) restarts it.
//!
//! `handle` only routes: [`CoordinatorMsg`] has one variant per concept, carrying that
//! concept's message enum, which is defined and handled in the concept's module:
//!
//! | Variant | Enum | Module |
//! |---|---|---|
//! | `Fleet` | [`FleetMsg`] | [`fleet`]: vehicles, links, the ground-station forwarder |
//! | `Command` | [`CommandMsg`] | [`fan_out`]: commands for one vehicle or all |
//! | `Formation` | [`FormationMsg`] | [`formation_control`]: formation requests, its tick |
//! | `Geofence` | [`GeofenceMsg`] | [`geofence`]: the fence in force, changes to it |
//! | `Payload` | [`PayloadMsg`] | [`payloads`]: payloads and payload plugins |
//! | `Tracking` | [`TrackingMsg`] | [`counter_uas`]: tracks, swarms, observation |
//! | `Admin` | [`AdminMsg`] | [`admin`]: supervision, faults, health, metrics, load |
//! | `Distributed` | [`DistributedMsg`] | [`distributed`]: the distributed roles' carrier |
//!
//! A new operation adds a variant to its concept's enum and an arm to its handler.
//!
//! The API's pure reads (vehicles, formation, supervision, air picture) do not go through
//! the mailbox: the coordinator publishes them after each message that may change them
//! ([`published`], [`SwarmReads`]).
//!
//! - [`messages`]: what the API and vehicles tell the coordinator, and the answers' shapes;
//! - [`discovery`]: vehicles joining from their first heartbeat;
//! - [`proxy`]: the coordinator's view of a vehicle;
//! - [`fan_out`]: fan-out of commands and payload requests;
//! - [`formation_control`]: formation and leader-motion requests;
//! - [`formation_loop`]: the formation tick;
//! - [`hazards`]: lost vehicles the formation plans around;
//! - [`validation`]: formation and leader-motion requests, checked;
//! - [`geofence`]: changing the geofence, tried on every autopilot, then committed;
//! - [`supervisor`]: supervision of vehicles and services, fault routing;
//! - [`escalation`]: what happens to a vehicle whose actor keeps failing;
//! - [`distributed`]: vehicles of other processes, and an agent's carrier;
//! - [`published`]: what it publishes for reads that do not wait in its mailbox;
//! - [`swarm`]: starting and stopping it all;
//! - [`status`]: health, metrics and link counters it reports.

pub mod admin;
pub mod counter_uas;
pub mod discovery;
pub mod distributed;
pub mod escalation;
pub mod fan_out;
pub mod fleet;
pub mod formation_control;
pub mod formation_loop;
pub mod geofence;
pub mod hazards;
pub mod messages;
pub mod missions;
pub mod observe;
pub mod payloads;
pub mod proxy;
pub mod published;
pub mod stations;
pub mod status;
pub mod supervisor;
pub mod swarm;
pub mod track_leader;
pub mod validation;

pub use discovery::{EndpointSpec, VehicleSpec};
pub use distributed::{DistributedMsg, RemoteVehicle};
pub use fan_out::{CommandOutcome, Refused};
pub use messages::{
    AdminMsg, CommandMsg, CoordinatorMsg, EndpointStats, FaultError, FieldError, FleetMsg,
    FormationMsg, GeofenceMsg, Health, PayloadMsg, ServiceMsg, ServiceSpawner, ServiceSpec,
    TrackingMsg,
};
pub use proxy::{VehicleProxy, VehicleReadout};
pub use published::{AirPicture, Observations, SwarmReads};
pub use supervisor::Node;
pub use swarm::{StartError, Swarm};

use crate::config::SwarmConfig;
use crate::context::SwarmContext;
use crate::events::SwarmEvent;
use crate::formation::FormationEngine;
use crate::load::LoadMonitor;
use crate::metrics::Metrics;
use crate::neighbours::NeighbourBoard;
use crate::protocol::FromVehicle;
use crate::services::SwarmServices;
use crate::supervision::{self, Children, Supervision};
use crate::ticker::TickGate;
use crate::vehicle::fleet::FleetRegistry;
use fan_out::InFlight;
use ractor::{Actor, ActorProcessingErr, ActorRef, SupervisionEvent};
use skein_link::Endpoint;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::broadcast;

/// Arguments of [`Coordinator`].
pub struct CoordinatorArgs {
    /// Swarm configuration.
    pub config: SwarmConfig,
    /// Payload factory, simulator hooks.
    pub services: SwarmServices,
    /// Opened endpoints with their specs.
    pub endpoints: Vec<(Arc<Endpoint>, EndpointSpec)>,
    /// Event bus.
    pub events: broadcast::Sender<SwarmEvent>,
    /// Metrics registry.
    pub metrics: Arc<Metrics>,
    /// How late the process runs ([`crate::load`]).
    pub load: Arc<LoadMonitor>,
    /// The registry of this process's vehicles, filled as they join (its readers:
    /// [`Swarm::fleet`](super::Swarm)).
    pub fleet: FleetRegistry,
}

/// State of [`Coordinator`].
pub struct CoordinatorState {
    context: Arc<SwarmContext>,
    /// The registry of this process's vehicles (payload hosts and the tracker read it).
    fleet: FleetRegistry,
    /// Every vehicle's place, for the vehicles' separation checks.
    neighbours: NeighbourBoard,
    endpoints: Vec<(Arc<Endpoint>, EndpointSpec)>,
    gcs: Option<Arc<skein_link::GcsForwarder>>,
    vehicles: BTreeMap<String, VehicleProxy>,
    services: BTreeMap<String, ServiceSpec>,
    children: Children<Node>,
    formation: FormationEngine,
    events: broadcast::Sender<SwarmEvent>,
    metrics: Arc<Metrics>,
    supervision: Arc<Supervision>,
    in_flight: InFlight,
    hazards: hazards::Hazards,
    started: Instant,
    last_formation_tick: Instant,
    /// The counter-UAS tracker (its task stops with the coordinator).
    tracking: crate::tracking::TrackingService,
    /// Observing vehicle → (track or swarm id, gimbal slot), see [`observe`].
    observing: BTreeMap<String, (String, String)>,
    /// Target id → its observers' stations, see [`stations`].
    stations: BTreeMap<String, stations::StationTask>,
    /// An agent's carrier: gets a copy of every local vehicle's message ([`remote`]).
    uplink_tap: Option<tokio::sync::mpsc::UnboundedSender<FromVehicle>>,
    /// When hovering remote vehicles were last joined to the formation ([`remote`]).
    last_rejoin: Instant,
    /// The formation tick and the watchdog tick (see [`crate::ticker`]).
    formation_gate: TickGate,
    watch_gate: TickGate,
    /// A geofence change waiting for its vehicles' uploads ([`geofence`]).
    fence_change: Option<geofence::PendingFence>,
    /// The missions and the one flying ([`missions`]), and their tick.
    missions: missions::Store,
    mission_gate: TickGate,
    /// What the API reads without asking ([`published`]).
    published: published::Publisher,
}

/// The `Coordinator` actor (see module docs).
pub struct Coordinator;

impl CoordinatorState {
    fn emit(&self, ev: SwarmEvent) {
        let _ = self.events.send(ev);
    }

    /// Publishes the formation and the observations for the API's reads ([`published`]).
    fn publish(&self) {
        self.published.state(
            self.formation_status(),
            published::Observations {
                observing: self.observations(),
                stations: self.station_views(),
            },
        );
    }

    /// Publishes the list of vehicles, after one joined ([`published`]).
    fn publish_vehicles(&self) {
        let list = self
            .vehicles
            .iter()
            .map(|(id, v)| (id.clone(), v.readout().clone()))
            .collect();
        self.published.vehicles(list);
    }

    fn formation_changed(&self) {
        let status = serde_json::to_value(self.formation_status()).unwrap_or_default();
        self.emit(SwarmEvent::FormationChanged { formation: status });
    }
}

impl Actor for Coordinator {
    type Msg = CoordinatorMsg;
    type State = CoordinatorState;
    type Arguments = CoordinatorArgs;

    async fn pre_start(
        &self,
        myself: ActorRef<Self::Msg>,
        args: CoordinatorArgs,
    ) -> Result<Self::State, ActorProcessingErr> {
        for (i, (endpoint, _)) in args.endpoints.iter().enumerate() {
            let me = myself.clone();
            endpoint.set_discovery(Arc::new(move |d| {
                let _ = me.cast(
                    FleetMsg::Discovered {
                        endpoint: i,
                        discovery: d,
                    }
                    .into(),
                );
            }));
        }
        let period = Duration::from_secs_f64(1.0 / args.config.formation_rate_hz.max(1.0));
        let supervision = Supervision::new(
            args.config.supervision.clone(),
            args.load.clone(),
            args.metrics.clone(),
            args.events.clone(),
        );
        let watchdog_period = supervision.config.watchdog_period();
        let separation_m = args.config.setpoint_separation_m();
        let mut formation = FormationEngine::new(separation_m);
        formation.set_replan_after_s(args.config.hazards.replan_after_s);
        let control_period = Duration::from_secs_f64(1.0 / args.config.control_rate_hz.max(1.0));
        let context = Arc::new(SwarmContext::new(args.config, args.services));
        args.load.attach_ticker(&context.ticker);
        let me = myself.clone();
        let formation_gate = context.ticker.every(period, move || {
            me.cast(FormationMsg::FormationTick.into()).is_ok()
        });
        let me = myself.clone();
        let watch_gate = context.ticker.every(watchdog_period, move || {
            me.cast(AdminMsg::WatchTick.into()).is_ok()
        });
        let me = myself.clone();
        let mission_gate = context.ticker.every(missions::MISSION_TICK, move || {
            me.cast(missions::MissionMsg::Tick.into()).is_ok()
        });
        let missions = missions::Store::open(context.config.missions_dir.clone());
        let fleet = args.fleet;
        let tracking = crate::tracking::TrackingService::spawn(
            crate::tracking::TrackerConfig::default(),
            fleet.reader(),
            args.events.clone(),
            args.metrics.clone(),
        );
        let published = published::Publisher::new(
            formation.status_with(&[], &BTreeMap::new()),
            supervision.clone(),
            tracking.shared().clone(),
        );
        Ok(CoordinatorState {
            published,
            context,
            fleet,
            neighbours: NeighbourBoard::new(control_period),
            tracking,
            observing: BTreeMap::new(),
            stations: BTreeMap::new(),
            uplink_tap: None,
            last_rejoin: Instant::now(),
            fence_change: None,
            endpoints: args.endpoints,
            gcs: None,
            vehicles: BTreeMap::new(),
            services: BTreeMap::new(),
            children: Children::new(supervision::ROOT, supervision.clone()),
            formation,
            events: args.events,
            metrics: args.metrics,
            supervision,
            in_flight: InFlight::default(),
            hazards: hazards::Hazards::default(),
            started: Instant::now(),
            last_formation_tick: Instant::now(),
            formation_gate,
            watch_gate,
            missions,
            mission_gate,
        })
    }

    async fn handle(
        &self,
        myself: ActorRef<Self::Msg>,
        msg: Self::Msg,
        state: &mut Self::State,
    ) -> Result<(), ActorProcessingErr> {
        let publish = msg.may_change_reads();
        match msg {
            CoordinatorMsg::Fleet(msg) => state.handle_fleet(&myself, msg).await?,
            CoordinatorMsg::Command(msg) => state.handle_command(&myself, msg),
            CoordinatorMsg::Formation(msg) => state.handle_formation(msg),
            CoordinatorMsg::Geofence(msg) => state.handle_geofence(&myself, msg),
            CoordinatorMsg::Payload(msg) => state.handle_payload(&myself, msg),
            CoordinatorMsg::Tracking(msg) => state.handle_tracking(msg),
            CoordinatorMsg::Admin(msg) => state.handle_admin(&myself, msg).await?,
            CoordinatorMsg::Distributed(msg) => state.on_distributed(msg),
            CoordinatorMsg::Mission(msg) => state.handle_mission(msg),
        }
        if publish {
            state.publish();
        }
        Ok(())
    }

    async fn handle_supervisor_evt(
        &self,
        myself: ActorRef<Self::Msg>,
        evt: SupervisionEvent,
        state: &mut Self::State,
    ) -> Result<(), ActorProcessingErr> {
        if let Some((node, exit)) = state.children.ended(&evt) {
            state.child_ended(&myself, node, exit).await?;
        }
        Ok(())
    }
}
