//! The DDS link of `skein up --dds`, `skein coordinator` and `skein agent`: [`DdsRoles`]
//! composes the roles of this process, and the supervised `DdsLink` service runs them.
//!
//! [`DdsRoles::new`] joins the domain ([`Ros2Carrier`]) and opens each role's topics:
//! every process publishes its vehicles ([`crate::vehicles`]); a candidate runs the
//! election ([`crate::lease`]), steers the agents' vehicles ([`crate::remote`]) and
//! mirrors the formation ([`crate::mirror`]); an agent obeys the active coordinator
//! ([`crate::agent`]). Each role gets its own topics and the [`SwarmAdapter`] as its
//! context; the roles share nothing else but the counters. What outlives a restart of
//! the service (`coordinator/dds`, restart policy `[supervision.dds]`) is the roles'
//! state: the participant (so peers need not rediscover it), the topics, the election,
//! the remote vehicles' channels. The service actor spawns the roles' tasks when it
//! starts and aborts them when it stops.

use crate::agent::{self, Agent, AgentConfig};
use crate::carrier::ros2::Ros2Carrier;
use crate::counters::DdsCounters;
use crate::error::DdsError;
use crate::lease::{Candidate, ElectionLink};
use crate::mirror::{self, Mirror};
use crate::remote::{self, Remotes};
use crate::swarm_adapter::SwarmAdapter;
use crate::vehicles::{self, Vehicles};
use ractor::{Actor, ActorCell, ActorProcessingErr, ActorRef};
use skein_model::supervision::ChildKind;
use skein_swarm::election::ElectionStatus;
use skein_swarm::metrics::Metrics;
use skein_swarm::{CoordinatorMsg, ServiceMsg, ServiceSpec, SwarmEvent};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::{broadcast, watch};
use tokio::task::JoinSet;

/// What the DDS link is told at start (`[dds]` in the config, `--dds*` flags).
#[derive(Debug, Clone, PartialEq)]
pub struct DdsConfig {
    /// DDS domain (`--domain-id`, else `ROS_DOMAIN_ID`, else 0); 0–232.
    pub domain_id: u16,
    /// Node name (`skein_up_<pid>`), in namespace `/skein`.
    pub node_name: String,
    /// Pose, navsat and state publications per second (battery a tenth of it).
    pub publish_rate_hz: f64,
    /// Obey `skein_msgs/Command`s from the domain (off by default: DDS has no
    /// authentication, so the domain must be a trusted network).
    pub accept_commands: bool,
    /// Local addresses of the interfaces DDS may use for multicast discovery and
    /// advertise to peers (RustDDS `with_only_networks`); empty = every interface.
    /// `127.0.0.1` alone keeps DDS on this host (unicast discovery over loopback).
    pub networks: Vec<std::net::IpAddr>,
    /// With `skein coordinator`: this process is a candidate in the coordinator election
    /// on `/skein/coordinator` ([`crate::lease`]), and steers the agents' vehicles
    /// ([`crate::remote`]).
    pub candidate: Option<Candidate>,
    /// With `skein agent`: this process's vehicles obey the active coordinator of the
    /// domain ([`crate::agent`]).
    pub agent: Option<AgentConfig>,
}

/// A candidate's roles: the election, the remote vehicles, the formation mirror.
struct CandidateRoles {
    election: Arc<ElectionLink>,
    remotes: Arc<Remotes>,
    mirror: Arc<Mirror>,
}

/// The roles of this process, with their topics on one DDS participant (see the module
/// docs).
pub struct DdsRoles {
    publish_period: Duration,
    counters: Arc<DdsCounters>,
    swarm: Arc<SwarmAdapter>,
    vehicles: Arc<Vehicles<Ros2Carrier>>,
    candidate: Option<CandidateRoles>,
    agent: Option<Arc<Agent>>,
}

impl DdsRoles {
    /// Joins the domain and opens the roles' topics; the roles reach `coordinator`, its
    /// `metrics` and its event bus `events` through the [`SwarmAdapter`].
    ///
    /// # Errors
    /// The participant, node or a topic could not be created (sockets, names).
    pub fn new(
        config: DdsConfig,
        coordinator: ActorRef<CoordinatorMsg>,
        metrics: Arc<Metrics>,
        events: broadcast::Sender<SwarmEvent>,
    ) -> Result<Arc<DdsRoles>, DdsError> {
        let carrier = Arc::new(Ros2Carrier::join(
            config.domain_id,
            &config.networks,
            &config.node_name,
        )?);
        let counters = Arc::new(DdsCounters::default());
        let candidate = match config.candidate {
            Some(c) => Some(CandidateRoles {
                election: Arc::new(ElectionLink::open(carrier.as_ref(), c, &counters)?),
                remotes: Arc::new(Remotes::open(carrier.as_ref(), &counters)?),
                mirror: Arc::new(Mirror::open(carrier.as_ref(), &counters)?),
            }),
            None => None,
        };
        let agent = match config.agent {
            Some(a) => Some(Arc::new(Agent::open(carrier.as_ref(), a, &counters)?)),
            None => None,
        };
        // A remote vehicle is published by its agent.
        let remotes = candidate.as_ref().map(|c| c.remotes.clone());
        let elsewhere = move |id: &str| remotes.as_ref().is_some_and(|r| r.contains(id));
        let vehicles = Vehicles::open(
            carrier,
            &counters,
            config.publish_rate_hz,
            config.accept_commands,
            Box::new(elsewhere),
        )?;
        Ok(Arc::new(DdsRoles {
            publish_period: Duration::from_secs_f64(1.0 / config.publish_rate_hz.clamp(0.1, 100.0)),
            counters,
            swarm: Arc::new(SwarmAdapter::new(coordinator, metrics, events)),
            vehicles: Arc::new(vehicles),
            candidate,
            agent,
        }))
    }

    /// The coordinator election's status, when this process is a candidate.
    pub fn election(&self) -> Option<watch::Receiver<ElectionStatus>> {
        self.candidate.as_ref().map(|c| c.election.subscribe())
    }

    /// The service the coordinator starts and supervises as `coordinator/dds`.
    pub fn service(self: &Arc<Self>) -> ServiceSpec {
        let roles = self.clone();
        ServiceSpec {
            name: "dds".into(),
            kind: ChildKind::Dds,
            spawn: Arc::new(move |supervisor: ActorCell| {
                let r = roles.clone();
                Box::pin(async move {
                    let (actor, _) = Actor::spawn_linked(None, DdsLink, r, supervisor).await?;
                    Ok(actor)
                })
            }),
        }
    }

    /// Spawns every role's tasks into `tasks`.
    fn spawn(&self, tasks: &mut JoinSet<()>) {
        let swarm = &self.swarm;
        tasks.spawn(vehicles::run(self.vehicles.clone(), swarm.clone()));
        if let Some(c) = &self.candidate {
            tasks.spawn(c.election.clone().run(swarm.clone()));
            let status = c.election.subscribe();
            tasks.spawn(remote::run(
                c.remotes.clone(),
                status.clone(),
                swarm.clone(),
            ));
            tasks.spawn(mirror::run(c.mirror.clone(), status, swarm.clone()));
        }
        if let Some(a) = &self.agent {
            tasks.spawn(agent::run(a.clone(), swarm.clone()));
        }
        let (swarm, counters) = (swarm.clone(), self.counters.clone());
        let period = self.publish_period;
        tasks.spawn(async move {
            let mut tick = tokio::time::interval(period);
            tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
            loop {
                tick.tick().await;
                swarm.export_counters(&counters);
            }
        });
    }
}

/// The DDS link service actor: runs the roles' tasks while it lives (see the module
/// docs).
pub struct DdsLink;

/// State of [`DdsLink`]: the roles' tasks.
pub struct DdsLinkState {
    tasks: JoinSet<()>,
}

impl Actor for DdsLink {
    type Msg = ServiceMsg;
    type State = DdsLinkState;
    type Arguments = Arc<DdsRoles>;

    async fn pre_start(
        &self,
        _myself: ActorRef<Self::Msg>,
        roles: Arc<DdsRoles>,
    ) -> Result<Self::State, ActorProcessingErr> {
        let mut tasks = JoinSet::new();
        roles.spawn(&mut tasks);
        Ok(DdsLinkState { tasks })
    }

    async fn post_stop(
        &self,
        _myself: ActorRef<Self::Msg>,
        state: &mut Self::State,
    ) -> Result<(), ActorProcessingErr> {
        state.tasks.abort_all();
        Ok(())
    }

    async fn handle(
        &self,
        myself: ActorRef<Self::Msg>,
        msg: Self::Msg,
        _state: &mut Self::State,
    ) -> Result<(), ActorProcessingErr> {
        msg.serve(&myself, "coordinator/dds").await
    }
}
