//! The `DdsLink` service actor of `skein up --dds`: the swarm on ROS 2 topics.
//!
//! Supervised by the coordinator like the API (`coordinator/dds`, restart policy
//! `[supervision.dds]`). What outlives a restart is in [`DdsShared`]: the DDS participant
//! (so peers need not rediscover it), the node, the publishers and the command
//! subscriptions. The actor runs one task:
//!
//! - at the publish rate it asks the coordinator for every vehicle and publishes its
//!   pose, navsat and state (battery at a tenth of the rate), creating a vehicle's
//!   topics the first time it is seen; every other tick it publishes the tracks;
//! - with `accept_commands`, it takes `skein_msgs/Command`s from each vehicle's
//!   `command` topic, hands each to the coordinator as the API would, and answers on
//!   `command_result` (a malformed sample is counted and dropped; a command the vehicle
//!   state forbids is refused with the FSM's reason).

use crate::agent::Agent;
use crate::convert;
use crate::envelope::ProtocolTopics;
use crate::lease::ElectionLink;
use crate::msgs::{self, CommandResult, RosMessage};
use crate::remote::Remotes;
use crate::topics;
use ractor::{Actor, ActorCell, ActorProcessingErr, ActorRef};
use ros2_client::builtin_interfaces::Time;
use ros2_client::dds::rustdds::DomainParticipantBuilder;
use ros2_client::{Context, Name, Node, NodeName, NodeOptions, QosProfile};
use ros2_client::{Publisher, Subscription};
use skein_model::supervision::ChildKind;
use skein_model::vehicle::VehicleSnapshot;
use skein_swarm::election::ElectionStatus;
use skein_swarm::metrics::Metrics;
use skein_swarm::protocol::VehicleReport;
use skein_swarm::view::SwarmView;
use skein_swarm::{CoordinatorMsg, DistributedMsg, ServiceMsg, ServiceSpec};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;
use tokio::task::JoinSet;

/// How long a coordinator query may take before the tick is skipped.
const COORDINATOR_TIMEOUT: Duration = Duration::from_secs(1);

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
    pub candidate: Option<crate::lease::Candidate>,
    /// With `skein agent`: this process's vehicles obey the active coordinator of the
    /// domain ([`crate::agent`]).
    pub agent: Option<crate::agent::AgentConfig>,
}

/// Counters of the DDS link (in `/metrics` as `skein_dds_samples{what="published"}` …).
#[derive(Debug, Default)]
pub struct DdsCounters {
    /// Samples written.
    pub published: AtomicU64,
    /// Writes that failed (a full reliable queue, a closed participant).
    pub publish_errors: AtomicU64,
    /// Commands taken from the domain.
    pub commands: AtomicU64,
    /// Command samples that could not be read or did not parse (dropped).
    pub malformed: AtomicU64,
}

/// A vehicle's command reader and result writer.
type CommandTopics = (
    Arc<Subscription<msgs::Command>>,
    Arc<Publisher<CommandResult>>,
);

/// One vehicle's writers and, with commands on, its command reader.
struct VehicleTopics {
    pose: Publisher<msgs::PoseStamped>,
    navsat: Publisher<msgs::NavSatFix>,
    battery: Publisher<msgs::BatteryState>,
    state: Publisher<msgs::VehicleState>,
    command: Option<CommandTopics>,
}

/// What outlives the actor: the participant, the node, the topics.
pub struct DdsShared {
    config: DdsConfig,
    coordinator: ActorRef<CoordinatorMsg>,
    metrics: Arc<Metrics>,
    // Kept alive for the node's life (dropping it leaves the domain).
    _context: Context,
    node: Mutex<Node>,
    tracks: Publisher<msgs::Tracks>,
    vehicles: Mutex<BTreeMap<String, Arc<VehicleTopics>>>,
    election: Option<ElectionLink>,
    /// The swarm protocol topics, for a candidate or an agent.
    protocol: Option<ProtocolTopics>,
    agent: Option<Agent>,
    remotes: Remotes,
    /// The event bus of this process (an agent forwards its vehicles' events from it, a
    /// coordinator puts the agents' on it).
    events: tokio::sync::broadcast::Sender<skein_swarm::SwarmEvent>,
    /// The link's counters.
    pub counters: DdsCounters,
}

/// Why the DDS link could not start.
#[derive(Debug)]
pub struct DdsError(pub String);

impl std::fmt::Display for DdsError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for DdsError {}

pub(crate) fn err<E: std::fmt::Debug>(what: &str) -> impl FnOnce(E) -> DdsError + '_ {
    move |e| DdsError(format!("{what}: {e:?}"))
}

impl DdsShared {
    /// Joins the domain and creates the node and the swarm-wide topics; `events` carries
    /// the election's `coordinator_role_changed` (with a candidate).
    ///
    /// # Errors
    /// The participant, node or a topic could not be created (sockets, names).
    pub fn new(
        config: DdsConfig,
        coordinator: ActorRef<CoordinatorMsg>,
        metrics: Arc<Metrics>,
        events: tokio::sync::broadcast::Sender<skein_swarm::SwarmEvent>,
    ) -> Result<Arc<DdsShared>, DdsError> {
        let mut participant = DomainParticipantBuilder::new(config.domain_id);
        if !config.networks.is_empty() {
            participant = participant.with_only_networks(config.networks.iter().copied());
        }
        let participant = participant.build().map_err(err("DDS participant"))?;
        let context =
            Context::from_domain_participant(participant).map_err(err("ROS 2 context"))?;
        let mut node = context
            .new_node(
                NodeName::new(topics::NAMESPACE, &config.node_name)
                    .map_err(|e| DdsError(format!("node name: {e:?}")))?,
                NodeOptions::new().enable_rosout(false),
            )
            .map_err(err("ROS 2 node"))?;
        let tracks = publisher::<msgs::Tracks>(
            &mut node,
            topics::NAMESPACE,
            "tracks",
            &topics::latest_state(),
        )?;
        let election = match config.candidate.clone() {
            Some(c) => Some(ElectionLink::new(&mut node, c, events.clone())?),
            None => None,
        };
        let agent = match config.agent.clone() {
            Some(a) => Some(Agent::new(&mut node, a)?),
            None => None,
        };
        let protocol = if election.is_some() || agent.is_some() {
            Some(ProtocolTopics::new(&mut node)?)
        } else {
            None
        };
        Ok(Arc::new(DdsShared {
            election,
            protocol,
            agent,
            remotes: Remotes::default(),
            events,
            config,
            coordinator,
            metrics,
            _context: context,
            node: Mutex::new(node),
            tracks,
            vehicles: Mutex::new(BTreeMap::new()),
            counters: DdsCounters::default(),
        }))
    }

    /// The coordinator election's status, when this process is a candidate.
    pub fn election(&self) -> Option<tokio::sync::watch::Receiver<ElectionStatus>> {
        self.election.as_ref().map(ElectionLink::subscribe)
    }

    /// The agent's carrier state, with `skein agent`.
    pub fn agent(&self) -> Option<&Agent> {
        self.agent.as_ref()
    }

    /// The swarm protocol topics (a candidate or an agent).
    pub(crate) fn protocol(&self) -> Option<&ProtocolTopics> {
        self.protocol.as_ref()
    }

    /// The event bus of this process.
    pub(crate) fn events(&self) -> &tokio::sync::broadcast::Sender<skein_swarm::SwarmEvent> {
        &self.events
    }

    /// The vehicles of other processes this coordinator steers.
    pub(crate) fn remotes(&self) -> &Remotes {
        &self.remotes
    }

    /// The coordinator actor of this process.
    pub(crate) fn coordinator(&self) -> &ActorRef<CoordinatorMsg> {
        &self.coordinator
    }

    /// Asks the coordinator; `None` when it does not answer within
    /// [`COORDINATOR_TIMEOUT`].
    async fn ask<T: Send + 'static>(
        &self,
        msg: impl FnOnce(ractor::RpcReplyPort<T>) -> CoordinatorMsg,
    ) -> Option<T> {
        match self.coordinator.call(msg, Some(COORDINATOR_TIMEOUT)).await {
            Ok(ractor::rpc::CallResult::Success(v)) => Some(v),
            _ => None,
        }
    }

    /// The coordinator's swarm view (`None` if it does not answer).
    pub(crate) async fn view(&self) -> Option<Arc<SwarmView>> {
        self.ask(|r| CoordinatorMsg::Distributed(DistributedMsg::GetView(r)))
            .await
    }

    /// The formation to mirror (`Some(None)`: none is flown; `None`: no answer).
    pub(crate) async fn formation_mirror(
        &self,
    ) -> Option<Option<skein_swarm::formation::FormationMirror>> {
        self.ask(|r| CoordinatorMsg::Distributed(DistributedMsg::GetFormationMirror(r)))
            .await
    }

    /// The latest report of every vehicle of this process.
    pub(crate) async fn local_reports(&self) -> Option<Vec<(String, VehicleReport)>> {
        self.ask(|r| CoordinatorMsg::Distributed(DistributedMsg::ListReports(r)))
            .await
    }

    /// The service the coordinator starts and supervises as `coordinator/dds`.
    pub fn service(self: &Arc<Self>) -> ServiceSpec {
        let shared = self.clone();
        ServiceSpec {
            name: "dds".into(),
            kind: ChildKind::Dds,
            spawn: Arc::new(move |supervisor: ActorCell| {
                let s = shared.clone();
                Box::pin(async move {
                    let (actor, _) = Actor::spawn_linked(None, DdsLink, s, supervisor).await?;
                    Ok(actor)
                })
            }),
        }
    }

    /// The topics of vehicle `id`, created on first use.
    ///
    /// # Errors
    /// A topic could not be created, or another vehicle already publishes under the
    /// same ROS name (`uav-1` and `uav.1` are both `uav_1`): the second is not published,
    /// and the error names both.
    fn vehicle(&self, id: &str) -> Result<Arc<VehicleTopics>, DdsError> {
        let mut map = self.vehicles.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(t) = map.get(id) {
            return Ok(t.clone());
        }
        if let Some(other) = topics::same_ros_name(map.keys().map(String::as_str), id) {
            return Err(DdsError(format!(
                "vehicle `{id}` is not published: `{other}` already publishes under the ROS \
                 name `{}` (rename one of them)",
                topics::ros_name(id)
            )));
        }
        let ns = topics::vehicle_namespace(id);
        let mut node = self.node.lock().unwrap_or_else(PoisonError::into_inner);
        let sensor = topics::sensor();
        let command = if self.config.accept_commands {
            let topic = node
                .create_topic(
                    &Name::new(&ns, "command").map_err(|e| DdsError(format!("{e:?}")))?,
                    msgs::Command::type_name(),
                    &topics::commands(),
                )
                .map_err(err("command topic"))?;
            let sub = node
                .create_subscription::<msgs::Command>(&topic, None)
                .map_err(err("command subscription"))?;
            let result =
                publisher::<CommandResult>(&mut node, &ns, "command_result", &topics::commands())?;
            Some((Arc::new(sub), Arc::new(result)))
        } else {
            None
        };
        let t = Arc::new(VehicleTopics {
            pose: publisher(&mut node, &ns, "pose", &sensor)?,
            navsat: publisher(&mut node, &ns, "navsat", &sensor)?,
            battery: publisher(&mut node, &ns, "battery", &sensor)?,
            state: publisher(&mut node, &ns, "state", &topics::latest_state())?,
            command,
        });
        map.insert(id.to_string(), t.clone());
        Ok(t)
    }

    /// Copies the counters into `/metrics` (`skein_dds_samples{what=...}`).
    fn export_counters(&self) {
        let c = &self.counters;
        let zero = AtomicU64::new(0);
        let (obeyed, refused) = match &self.agent {
            Some(a) => (&a.counters.obeyed, &a.counters.refused),
            None => (&zero, &zero),
        };
        for (what, n) in [
            ("published", &c.published),
            ("publish_errors", &c.publish_errors),
            ("commands", &c.commands),
            ("malformed", &c.malformed),
            ("protocol_obeyed", obeyed),
            ("protocol_refused", refused),
        ] {
            self.metrics
                .dds_samples
                .get_or_create(&Metrics::label("what", what))
                .set(n.load(Ordering::Relaxed) as i64);
        }
    }

    /// Counts a write as published or failed.
    pub(crate) fn count<M>(&self, r: Result<(), M>) {
        let c = match r {
            Ok(()) => &self.counters.published,
            Err(_) => &self.counters.publish_errors,
        };
        c.fetch_add(1, Ordering::Relaxed);
    }

    /// Publishes one vehicle's topics (battery when `battery`).
    fn publish_vehicle(&self, t: &VehicleTopics, v: &VehicleSnapshot, battery: bool) {
        let now = Time::now();
        if let Some(m) = convert::pose(v, now) {
            self.count(t.pose.publish(m));
        }
        if let Some(m) = convert::navsat(v, now) {
            self.count(t.navsat.publish(m));
        }
        if battery && let Some(m) = convert::battery(v, now) {
            self.count(t.battery.publish(m));
        }
        self.count(t.state.publish(convert::state(v, now)));
    }

    pub(crate) async fn list_vehicles(&self) -> Option<Vec<VehicleSnapshot>> {
        self.ask(CoordinatorMsg::ListVehicles).await
    }

    async fn publish_tracks(&self) {
        if let Some((views, _)) = self.ask(CoordinatorMsg::GetTracks).await {
            self.count(self.tracks.publish(convert::tracks(&views, Time::now())));
        }
    }
}

fn publisher<M: RosMessage>(
    node: &mut Node,
    namespace: &str,
    name: &str,
    qos: &QosProfile,
) -> Result<Publisher<M>, DdsError> {
    let topic = node
        .create_topic(
            &Name::new(namespace, name).map_err(|e| DdsError(format!("{name}: {e:?}")))?,
            M::type_name(),
            qos,
        )
        .map_err(err(name))?;
    node.create_publisher(&topic, None)
        .map_err(err("publisher"))
}

/// Takes a vehicle's commands until the task is aborted.
async fn serve_commands(
    shared: Arc<DdsShared>,
    id: String,
    sub: Arc<Subscription<msgs::Command>>,
    results: Arc<Publisher<CommandResult>>,
) {
    loop {
        let cmd = match sub.async_take().await {
            Ok((cmd, _info)) => cmd,
            Err(e) => {
                shared.counters.malformed.fetch_add(1, Ordering::Relaxed);
                tracing::warn!("dds: a command sample for {id} was dropped: {e:?}");
                continue;
            }
        };
        shared.counters.commands.fetch_add(1, Ordering::Relaxed);
        let result = obey(&shared, &id, &cmd).await;
        shared.count(results.publish(result));
    }
}

/// Hands one command to the coordinator; the answer for `command_result`.
async fn obey(shared: &DdsShared, id: &str, cmd: &msgs::Command) -> CommandResult {
    let refused = |reason: String| CommandResult {
        request_id: cmd.request_id,
        command_id: 0,
        accepted: false,
        reason,
    };
    let command = match convert::command(cmd) {
        Ok(c) => c,
        Err(e) => {
            shared.counters.malformed.fetch_add(1, Ordering::Relaxed);
            return refused(e.to_string());
        }
    };
    tracing::info!(
        "dds: {} from `{}` for {id} (request {})",
        command.name(),
        cmd.source,
        cmd.request_id
    );
    let id_owned = id.to_string();
    match shared
        .coordinator
        .call(
            move |r| CoordinatorMsg::VehicleCommand(id_owned, command, r),
            Some(Duration::from_secs(5)),
        )
        .await
    {
        Ok(ractor::rpc::CallResult::Success(Ok(outcome))) => CommandResult {
            request_id: cmd.request_id,
            command_id: outcome.command_id,
            accepted: true,
            reason: String::new(),
        },
        Ok(ractor::rpc::CallResult::Success(Err(Some(reason)))) => refused(reason),
        Ok(ractor::rpc::CallResult::Success(Err(None))) => refused(format!("no vehicle `{id}`")),
        _ => refused("the coordinator did not answer in 5 s".into()),
    }
}

/// The DDS link actor (see the module docs).
pub struct DdsLink;

/// State of [`DdsLink`].
pub struct DdsLinkState {
    tasks: JoinSet<()>,
}

impl DdsLink {
    /// Publishes at the rate and serves commands; the command tasks are in a local
    /// `JoinSet`, so aborting this task aborts them too.
    async fn run(shared: Arc<DdsShared>) {
        let mut commands = JoinSet::new();
        let period = Duration::from_secs_f64(1.0 / shared.config.publish_rate_hz.clamp(0.1, 100.0));
        let mut tick = tokio::time::interval(period);
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        let mut n: u64 = 0;
        let mut serving: std::collections::BTreeSet<String> = Default::default();
        // Vehicles whose topics could not be made: logged once each.
        let mut refused: std::collections::BTreeSet<String> = Default::default();
        loop {
            tick.tick().await;
            n += 1;
            let Some(vehicles) = shared.list_vehicles().await else {
                continue;
            };
            // Another process's vehicle is published by its agent.
            for v in vehicles.iter().filter(|v| !shared.remotes.contains(&v.id)) {
                let topics = match shared.vehicle(&v.id) {
                    Ok(t) => t,
                    Err(e) => {
                        if refused.insert(v.id.clone()) {
                            tracing::error!("dds: no topics for {}: {e}", v.id);
                        }
                        continue;
                    }
                };
                if let Some((sub, results)) = &topics.command
                    && serving.insert(v.id.clone())
                {
                    commands.spawn(serve_commands(
                        shared.clone(),
                        v.id.clone(),
                        sub.clone(),
                        results.clone(),
                    ));
                }
                shared.publish_vehicle(&topics, v, n % 10 == 1);
            }
            if n.is_multiple_of(2) {
                shared.publish_tracks().await;
            }
            shared.export_counters();
        }
    }
}

impl Actor for DdsLink {
    type Msg = ServiceMsg;
    type State = DdsLinkState;
    type Arguments = Arc<DdsShared>;

    async fn pre_start(
        &self,
        _myself: ActorRef<Self::Msg>,
        shared: Arc<DdsShared>,
    ) -> Result<Self::State, ActorProcessingErr> {
        let mut tasks = JoinSet::new();
        let s = shared.clone();
        tasks.spawn(async move {
            if let Some(e) = &s.election {
                e.run(&s.counters).await;
            }
        });
        tasks.spawn(crate::agent::run(shared.clone()));
        tasks.spawn(crate::remote::run(shared.clone()));
        tasks.spawn(crate::mirror::run(shared.clone()));
        tasks.spawn(Self::run(shared));
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
