//! The DDS link of `skein up --dds`, `skein coordinator` and `skein agent`: [`DdsRoles`]
//! composes the roles of this process, and the supervised `DdsLink` service runs them.
//!
//! [`DdsRoles::new`] joins the domain ([`Ros2Carrier`]) and opens each role's topics:
//! every process publishes its vehicles ([`crate::vehicles`]) and their TF frames
//! ([`crate::tf`]); a candidate runs the election ([`crate::lease`]), steers the agents'
//! vehicles ([`crate::remote`]), mirrors the formation and the flying mission
//! ([`crate::mirror`]) and, while active, relays its RTK corrections ([`crate::rtcm`], as
//! `skein up --dds` does); an agent obeys the active coordinator ([`crate::agent`]) and
//! takes the relayed corrections; candidates and agents exchange clock samples ([`crate::clocks`]). Each
//! role gets its own topics and the [`SwarmAdapter`] (the relay: the process's
//! corrections service) as its context; the roles share nothing else but the counters and the peers' clocks
//! (estimated by the clock exchange, used to age the others' stamps). What outlives a restart of
//! the service (`coordinator/dds`, restart policy `[supervision.dds]`) is the roles'
//! state: the participant (so peers need not rediscover it), the topics, the election,
//! the remote vehicles' channels. The service actor spawns the roles' tasks when it
//! starts and aborts them when it stops.
//!
//! A participant does not outlive a network interface ([`crate::interfaces`]): when one
//! it uses (one that carries a `--dds-network` address, or any without them) is removed
//! or created, a process that is no candidate (an agent, `skein up --dds`)
//! joins the domain again on a new participant and opens its roles there (their state
//! starts again: an agent's vehicles hold until it hears a coordinator again). A
//! candidate keeps its participant, for its election's sake, and says so in the log.

use crate::agent::{self, Agent, AgentConfig};
use crate::carrier::ros2::Ros2Carrier;
use crate::clocks::{self, Clocks};
use crate::counters::DdsCounters;
use crate::error::DdsError;
use crate::interfaces;
use crate::lease::{Candidate, ElectionLink};
use crate::mirror::{self, Mirror};
use crate::remote::{self, Remotes};
use crate::rtcm::{self, RtcmPublisher, RtcmReceiver};
use crate::swarm_adapter::SwarmAdapter;
use crate::tf::{self, Tf, TfConfig};
use crate::topics;
use crate::vehicles::{self, Vehicles};
use ractor::{Actor, ActorCell, ActorProcessingErr, ActorRef};
use skein_model::supervision::ChildKind;
use skein_rtk::RtkService;
use skein_swarm::clocks::PeerClocks;
use skein_swarm::coordinator::missions::MissionMirror;
use skein_swarm::election::ElectionStatus;
use skein_swarm::formation::FormationMirror;
use skein_swarm::link_security::LinkSecurity;
use skein_swarm::metrics::Metrics;
use skein_swarm::{CoordinatorMsg, ServiceMsg, ServiceSpec, SwarmEvent};
use std::sync::{Arc, Mutex, PoisonError};
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
    /// DDS Security (`--dds-keystore`, `--dds-enclave`, or ROS 2's `ROS_SECURITY_*`):
    /// `None` for an unsecured participant ([`crate::security`]).
    pub security: Option<crate::security::DdsSecurity>,
    /// The parent of the swarm frame on `/tf_static` (`--dds-tf-parent`): `None` for
    /// `earth` ([`crate::tf`]).
    pub tf_parent_frame: Option<String>,
}

/// A candidate's roles: the election, the remote vehicles, the formation's and the
/// mission's mirrors, the clock exchange, the corrections relay.
struct CandidateRoles {
    election: Arc<ElectionLink>,
    remotes: Arc<Remotes>,
    mirror: Arc<Mirror<FormationMirror>>,
    /// `None`: an enclave whose permissions predate `/skein/mission` (missions are not
    /// carried through a failover).
    mission: Option<Arc<Mirror<MissionMirror>>>,
    clocks: Arc<Clocks>,
    rtcm: Option<Arc<RtcmPublisher>>,
}

/// The roles of this process, with their topics on one DDS participant (see the module
/// docs).
pub struct DdsRoles {
    publish_period: Duration,
    counters: Arc<DdsCounters>,
    swarm: Arc<SwarmAdapter>,
    candidate: Option<CandidateRoles>,
    /// The roles every process has, on the current participant.
    local: Mutex<Arc<LocalRoles>>,
    /// What a new participant needs (not for a candidate, whose roles stay on the first).
    rejoin: Option<DdsConfig>,
    /// The local addresses the participant is held to (empty: every interface): only
    /// their interfaces are watched ([`interfaces::current_on`]).
    networks: Vec<std::net::IpAddr>,
    /// The peers' clocks as the clock exchange estimates them (outlives participants).
    peer_clocks: Arc<PeerClocks>,
    /// Under DDS Security, a candidate's record of who its remote vehicles' agents are.
    link_security: Option<Arc<LinkSecurity>>,
    /// This process's RTK corrections, relayed by [`crate::rtcm`].
    rtk: Arc<RtkService>,
}

/// The roles on a participant that may be replaced: this process's vehicles and their
/// TF frames, an agent's obedience to the active coordinator, clock exchange and relayed
/// corrections, and the corrections relay of `skein up --dds`.
struct LocalRoles {
    vehicles: Arc<Vehicles<Ros2Carrier>>,
    tf: Arc<Tf>,
    agent: Option<Arc<Agent>>,
    clocks: Option<Arc<Clocks>>,
    rtcm_in: Option<Arc<RtcmReceiver>>,
    rtcm_out: Option<Arc<RtcmPublisher>>,
}

/// The corrections relay's local side: an agent takes the relayed corrections (a
/// receiver); `skein up --dds`, no candidate, always relays its own (a publisher); a
/// candidate relays them while active (`CandidateRoles`).
type LocalRtcm = (Option<Arc<RtcmReceiver>>, Option<Arc<RtcmPublisher>>);

/// Opens the local side of the corrections relay (see [`LocalRtcm`]).
fn open_rtcm(carrier: &Ros2Carrier, config: &DdsConfig, counters: &Arc<DdsCounters>) -> LocalRtcm {
    match (&config.agent, &config.candidate) {
        (Some(_), _) => (
            without_relay(
                RtcmReceiver::open(carrier, counters),
                "RTK corrections relay",
                topics::rtcm(),
            )
            .map(Arc::new),
            None,
        ),
        (None, None) => (
            None,
            without_relay(
                RtcmPublisher::open(carrier, counters),
                "RTK corrections relay",
                topics::rtcm(),
            )
            .map(Arc::new),
        ),
        (None, Some(_)) => (None, None),
    }
}

/// A role's side `opened` (`what`, on `topic`: the corrections relay, the mission
/// mirror), or `None`, said in the log, when it could not be: the rest of the link runs
/// without it. Under DDS Security that is an enclave made before skein had the topic,
/// whose permissions do not grant it.
fn without_relay<T>(
    opened: Result<T, DdsError>,
    what: &str,
    topic: impl std::fmt::Display,
) -> Option<T> {
    opened
        .map_err(|e| {
            tracing::error!(
                "dds: no {what} on {topic}: {e} (under DDS Security: make this enclave \
                 again, its permissions predate the topic)"
            );
        })
        .ok()
}

impl LocalRoles {
    /// Opens the vehicles', their TF frames', the agent's and the corrections relay's
    /// topics on `carrier`; the agent's stamps are aged with `peer_clocks`.
    fn open(
        carrier: Arc<Ros2Carrier>,
        config: &DdsConfig,
        counters: &Arc<DdsCounters>,
        remotes: Option<Arc<Remotes>>,
        peer_clocks: &Arc<PeerClocks>,
    ) -> Result<LocalRoles, DdsError> {
        let (agent, clocks) = match &config.agent {
            Some(a) => (
                Some(Arc::new(
                    Agent::open(carrier.as_ref(), a.clone(), counters)?
                        .with_clocks(peer_clocks.clone()),
                )),
                Some(Arc::new(Clocks::open(
                    carrier.as_ref(),
                    a.agent_id.clone(),
                    peer_clocks.clone(),
                    counters,
                )?)),
            ),
            None => (None, None),
        };
        // A remote vehicle is published by its agent.
        let remotes_tf = remotes.clone();
        let elsewhere = move |id: &str| remotes.as_ref().is_some_and(|r| r.contains(id));
        let tf = Tf::open(
            carrier.as_ref(),
            counters,
            TfConfig {
                publish_rate_hz: config.publish_rate_hz,
                parent_frame: config.tf_parent_frame.clone(),
            },
            Box::new(move |id: &str| remotes_tf.as_ref().is_some_and(|r| r.contains(id))),
        )?;
        let (rtcm_in, rtcm_out) = open_rtcm(carrier.as_ref(), config, counters);
        let vehicles = Vehicles::open(
            carrier,
            counters,
            config.publish_rate_hz,
            config.accept_commands,
            Box::new(elsewhere),
        )?;
        Ok(LocalRoles {
            vehicles: Arc::new(vehicles),
            tf: Arc::new(tf),
            agent,
            clocks,
            rtcm_in,
            rtcm_out,
        })
    }

    /// Spawns their tasks into `tasks`; the relayed corrections go to and come from `rtk`.
    fn spawn(&self, tasks: &mut JoinSet<()>, swarm: &Arc<SwarmAdapter>, rtk: &Arc<RtkService>) {
        tasks.spawn(vehicles::run(self.vehicles.clone(), swarm.clone()));
        tasks.spawn(tf::run(self.tf.clone(), swarm.clone()));
        if let Some(a) = &self.agent {
            tasks.spawn(agent::run(a.clone(), swarm.clone()));
        }
        if let Some(c) = &self.clocks {
            tasks.spawn(clocks::run(c.clone()));
        }
        if let Some(r) = &self.rtcm_in {
            tasks.spawn(rtcm::receive(r.clone(), rtk.clone()));
        }
        if let Some(p) = &self.rtcm_out {
            tasks.spawn(rtcm::publish(p.clone(), None, rtk.clone()));
        }
    }
}

impl DdsRoles {
    /// Joins the domain and opens the roles' topics; the roles reach `coordinator`, its
    /// `metrics` and its event bus `events` through the [`SwarmAdapter`], and this
    /// process's RTK corrections `rtk` ([`crate::rtcm`]).
    ///
    /// # Errors
    /// The participant, node or a topic could not be created (sockets, names).
    pub fn new(
        config: DdsConfig,
        coordinator: ActorRef<CoordinatorMsg>,
        metrics: Arc<Metrics>,
        events: broadcast::Sender<SwarmEvent>,
        rtk: Arc<RtkService>,
    ) -> Result<Arc<DdsRoles>, DdsError> {
        let carrier = Arc::new(Ros2Carrier::join(
            config.domain_id,
            &config.networks,
            &config.node_name,
            config.security.as_ref(),
        )?);
        let counters = Arc::new(DdsCounters::default());
        let peer_clocks = Arc::new(PeerClocks::default());
        let link_security = match (&config.candidate, &config.security) {
            (Some(_), Some(s)) => Some(Arc::new(LinkSecurity::new(s.enclave.clone()))),
            _ => None,
        };
        let candidate = match &config.candidate {
            Some(c) => Some(CandidateRoles {
                election: Arc::new(ElectionLink::open(carrier.as_ref(), c.clone(), &counters)?),
                remotes: Arc::new({
                    let r = Remotes::open(carrier.as_ref(), &counters)?
                        .with_clocks(peer_clocks.clone());
                    match (&link_security, &config.security) {
                        (Some(record), Some(s)) => r.with_security(
                            record.clone(),
                            crate::security::known_enclaves(&s.keystore),
                        ),
                        _ => r,
                    }
                }),
                mirror: Arc::new(
                    Mirror::open(carrier.as_ref(), &counters)?.with_clocks(peer_clocks.clone()),
                ),
                mission: without_relay(
                    Mirror::open(carrier.as_ref(), &counters),
                    "mission mirror",
                    topics::mission(),
                )
                .map(|m| Arc::new(m.with_clocks(peer_clocks.clone()))),
                clocks: Arc::new(Clocks::open(
                    carrier.as_ref(),
                    c.coordinator_id.clone(),
                    peer_clocks.clone(),
                    &counters,
                )?),
                rtcm: without_relay(
                    RtcmPublisher::open(carrier.as_ref(), &counters),
                    "RTK corrections relay",
                    topics::rtcm(),
                )
                .map(Arc::new),
            }),
            None => None,
        };
        let remotes = candidate.as_ref().map(|c| c.remotes.clone());
        let local = LocalRoles::open(carrier, &config, &counters, remotes, &peer_clocks)?;
        Ok(Arc::new(DdsRoles {
            publish_period: Duration::from_secs_f64(1.0 / config.publish_rate_hz.clamp(0.1, 100.0)),
            counters,
            swarm: Arc::new(SwarmAdapter::new(coordinator, metrics, events)),
            networks: config.networks.clone(),
            rejoin: candidate.is_none().then_some(config),
            candidate,
            local: Mutex::new(Arc::new(local)),
            peer_clocks,
            link_security,
            rtk,
        }))
    }

    /// Under DDS Security, a candidate's record of its remote vehicles' agents, as their
    /// certificates prove them (`dds_security` in `GET /api/v1/coordinator`).
    pub fn link_security(&self) -> Option<Arc<LinkSecurity>> {
        self.link_security.clone()
    }

    /// The coordinator election's status, when this process is a candidate.
    pub fn election(&self) -> Option<watch::Receiver<ElectionStatus>> {
        self.candidate.as_ref().map(|c| c.election.subscribe())
    }

    /// This process's estimates of its peers' clocks (empty in `skein up --dds`, which
    /// exchanges none).
    pub fn peer_clocks(&self) -> Arc<PeerClocks> {
        self.peer_clocks.clone()
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
    fn spawn(self: &Arc<Self>, tasks: &mut JoinSet<()>) {
        let swarm = &self.swarm;
        tasks.spawn(self.clone().run_local());
        if let Some(c) = &self.candidate {
            tasks.spawn(c.election.clone().run(swarm.clone()));
            let status = c.election.subscribe();
            tasks.spawn(remote::run(
                c.remotes.clone(),
                status.clone(),
                swarm.clone(),
            ));
            tasks.spawn(mirror::run(c.mirror.clone(), status.clone(), swarm.clone()));
            if let Some(m) = &c.mission {
                tasks.spawn(mirror::run(m.clone(), status.clone(), swarm.clone()));
            }
            tasks.spawn(clocks::run(c.clocks.clone()));
            if let Some(p) = &c.rtcm {
                tasks.spawn(rtcm::publish(p.clone(), Some(status), self.rtk.clone()));
            }
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

    /// Runs the local roles on the current participant, and on a new one after a change
    /// of the network interfaces (see the module docs).
    async fn run_local(self: Arc<Self>) {
        let mut seen = interfaces::current_on(&self.networks);
        loop {
            let local = self
                .local
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .clone();
            let mut tasks = JoinSet::new();
            local.spawn(&mut tasks, &self.swarm, &self.rtk);
            let now = loop {
                tokio::time::sleep(INTERFACE_POLL).await;
                let first = interfaces::current_on(&self.networks);
                if first == seen {
                    continue;
                }
                // Acted on once it holds (`interfaces::settled`): rejoining the domain
                // costs the agent its coordinator's samples for a moment.
                tokio::time::sleep(INTERFACE_CONFIRM).await;
                let now = interfaces::current_on(&self.networks);
                if let Some(what) = interfaces::settled(&seen, &first, &now) {
                    if self.rejoin.is_some() {
                        tracing::warn!(
                            "dds: network interfaces changed ({what}): joining the domain again"
                        );
                        break now;
                    }
                    tracing::warn!(
                        "dds: network interfaces changed ({what}): this coordinator candidate \
                         keeps its participant, which hears no peer on a new interface; \
                         restart it if it must"
                    );
                    seen = now;
                }
            };
            seen = now;
            let Some(config) = self.rejoin.clone() else {
                continue;
            };
            let counters = self.counters.clone();
            let peer_clocks = self.peer_clocks.clone();
            let joined = tokio::task::spawn_blocking(move || {
                let carrier = Arc::new(Ros2Carrier::join(
                    config.domain_id,
                    &config.networks,
                    &config.node_name,
                    config.security.as_ref(),
                )?);
                LocalRoles::open(carrier, &config, &counters, None, &peer_clocks)
            })
            .await;
            match joined {
                Ok(Ok(new)) => {
                    tasks.abort_all();
                    while tasks.join_next().await.is_some() {}
                    if let (Some(new), Some(old)) = (&new.agent, &local.agent) {
                        new.carry_over(old);
                    }
                    let old = std::mem::replace(
                        &mut *self.local.lock().unwrap_or_else(PoisonError::into_inner),
                        Arc::new(new),
                    );
                    // Leaving the domain joins the old participant's threads.
                    drop(local);
                    let _ = tokio::task::spawn_blocking(move || drop(old)).await;
                    tracing::warn!("dds: joined the domain again on the new interfaces");
                }
                Ok(Err(e)) => tracing::error!(
                    "dds: could not join the domain again ({e}); on the old participant until \
                     the interfaces change again"
                ),
                Err(e) => tracing::error!("dds: joining the domain again failed: {e}"),
            }
        }
    }
}

/// How often the network interfaces are looked at.
const INTERFACE_POLL: Duration = Duration::from_secs(1);
/// How long a change of the interfaces must hold before it is acted on.
const INTERFACE_CONFIRM: Duration = Duration::from_millis(300);

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
