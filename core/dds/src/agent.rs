//! The agent's side of the swarm protocol on DDS (`skein agent`): the vehicles of this
//! computer, reached by the coordinators of the domain.
//!
//! The agent's coordinator actor supervises its vehicles; this role, run by the
//! `DdsLink` service (so it restarts with it), reaches them through an [`AgentContext`]
//! and:
//!
//! - publishes every local vehicle's report and snapshot on `/skein/swarm/report` at
//!   [`AgentConfig::report_rate_hz`];
//! - hears the leases on `/skein/coordinator` and obeys, from `/skein/swarm/target` and
//!   `/skein/swarm/command`, only the active coordinator of the highest epoch
//!   ([`skein_swarm::election::observer`]); other samples are counted and dropped;
//! - publishes what the vehicles answer (acks, state changes, payload answers) on
//!   `/skein/swarm/command_result`, and their events (state changes, command outcomes,
//!   status texts, link, geofence clamps, payload events) on `/skein/swarm/events`;
//! - takes the other agents' reports as neighbours, for the separation check;
//! - keeps the active coordinator's formation mirror (`/skein/formation`) and **rides
//!   through** its silences ([`crate::ride`]): a vehicle whose slot targets stop comes
//!   to fly its slot from the mirror for [`AgentConfig::ride_through`] (default 4 s)
//!   after its last target, and the other agents' silent members are predicted on
//!   theirs for the separation check;
//! - **without a coordinator** for the longer of [`AgentConfig::coordinator_timeout`]
//!   (default 1.5 s) and the ride-through, counted from when the next lease was due (a
//!   cut of the link shorter than that never makes it hold), commands every vehicle
//!   flying a slot or a go-to to hold where it is (offboard: the setpoint stream never
//!   stops), and after [`AgentConfig::lost_action_after`] more does
//!   [`AgentConfig::lost_action`] with the airborne ones. A coordinator that appears again
//!   takes them back (the formation joins hovering vehicles).

use crate::carrier::{Carrier, TopicReader, TopicWriter};
use crate::clock;
use crate::counters::DdsCounters;
use crate::envelope::{Envelope, ReportBody, body_or_drop, reframed_or_drop};
use crate::error::DdsError;
use crate::lease;
use crate::msgs::{CoordinatorLease, SwarmMessage};
use crate::reframe::{FrameSource, Reframe, SwarmFrame, into_frame};
use crate::ride::Riding;
use crate::topics;
use skein_model::fsm::VehicleState;
use skein_model::safety::Geofence;
use skein_model::vehicle::VehicleSnapshot;
use skein_swarm::SwarmEvent;
use skein_swarm::clocks::PeerClocks;
use skein_swarm::election::ElectionConfig;
use skein_swarm::election::observer::{Observer, Refusal};
use skein_swarm::protocol::{Command, FromVehicle, ToVehicle, VehicleReport, wall_us};
use std::collections::BTreeSet;
use std::future::Future;
use std::str::FromStr;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;
use tokio::sync::{broadcast, mpsc};
use tokio::task::JoinSet;

/// What an agent does once its coordinator has been gone for
/// [`AgentConfig::lost_action_after`] (`--coordinator-lost-action`, `[agent]
/// coordinator_lost_action`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LostAction {
    /// Keep holding (offboard) until a coordinator returns or the operator acts.
    Hold,
    /// Land where it is (PX4 AUTO.LAND).
    Land,
    /// Return to launch (PX4 AUTO.RTL).
    Rtl,
}

impl FromStr for LostAction {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "hold" => Ok(LostAction::Hold),
            "land" => Ok(LostAction::Land),
            "rtl" => Ok(LostAction::Rtl),
            _ => Err(format!("`{s}` is not a lost action (hold, land, rtl)")),
        }
    }
}

/// An agent's settings (`skein agent`, `[agent]` in the config).
#[derive(Debug, Clone, PartialEq)]
pub struct AgentConfig {
    /// Its id on the protocol topics (`--id`, default `<hostname>-<pid>`).
    pub agent_id: String,
    /// No lease claiming the role heard for this long past when the next one was due:
    /// the agent holds (default 1.5 s), unless it rides through for longer.
    pub coordinator_timeout: Duration,
    /// How long a vehicle flies its slot on from the formation mirror after its last
    /// slot target (default 4 s; zero: never, it holds after `coordinator_timeout`).
    pub ride_through: Duration,
    /// Then, after this much longer, it does [`AgentConfig::lost_action`] (default 30 s).
    pub lost_action_after: Duration,
    /// What it does then (default [`LostAction::Hold`]).
    pub lost_action: LostAction,
    /// Reports per second per vehicle (default 20).
    pub report_rate_hz: f64,
}

impl AgentConfig {
    /// The defaults, for agent `agent_id`.
    pub fn new(agent_id: String) -> Self {
        AgentConfig {
            agent_id,
            coordinator_timeout: Duration::from_millis(1500),
            ride_through: Duration::from_secs(4),
            lost_action_after: Duration::from_secs(30),
            lost_action: LostAction::Hold,
            report_rate_hz: 20.0,
        }
    }
}

/// What the agent needs from this process: its vehicles (their reports and snapshots,
/// their answers and events) and a way to hand them the coordinator's messages.
pub trait AgentContext: FrameSource {
    /// The latest report of every vehicle of this process, by id (`None`: no answer).
    fn reports(&self) -> impl Future<Output = Option<Vec<(String, VehicleReport)>>> + Send;

    /// The snapshot of every vehicle of this process (`None`: no answer).
    fn snapshots(&self) -> impl Future<Output = Option<Vec<VehicleSnapshot>>> + Send;

    /// Hands `msg` to local vehicle `vehicle_id` (dropped when there is no such vehicle).
    fn to_vehicle(&self, vehicle_id: String, msg: ToVehicle);

    /// Where another agent's vehicle is (its report, in this process's frame), for the
    /// separation check of this process's vehicles.
    fn neighbour(&self, vehicle_id: String, report: VehicleReport);

    /// A copy of every [`FromVehicle`] of this process's vehicles from now on.
    fn tap_uplink(&self) -> mpsc::UnboundedReceiver<FromVehicle>;

    /// This process's events from now on (the role forwards its vehicles' ones).
    fn vehicle_events(&self) -> broadcast::Receiver<SwarmEvent>;

    /// The geofence in force in this process (the ride-through keeps the formation's
    /// reference inside it, as the coordinator does); `None`: no answer.
    fn geofence(&self) -> impl Future<Output = Option<Geofence>> + Send;
}

/// The agent's topics and the state that outlives the `DdsLink` actor.
pub struct Agent {
    config: AgentConfig,
    counters: Arc<DdsCounters>,
    /// `/skein/coordinator`, read.
    leases: TopicReader<CoordinatorLease>,
    observer: Mutex<Observer>,
    /// Ids of the vehicles of this process (from the last report tick).
    local: Mutex<BTreeSet<String>>,
    /// `/skein/swarm/report`, written (this agent's vehicles) and read (the others').
    reports_out: TopicWriter<SwarmMessage>,
    reports_in: Arc<TopicReader<SwarmMessage>>,
    /// `/skein/swarm/target` and `/skein/swarm/command`, read.
    targets: Arc<TopicReader<SwarmMessage>>,
    commands: Arc<TopicReader<SwarmMessage>>,
    /// `/skein/swarm/command_result` and `/skein/swarm/events`, written.
    results: TopicWriter<SwarmMessage>,
    events: TopicWriter<SwarmMessage>,
    /// `/skein/formation`, read: the active coordinator's formation, for the ride-through.
    mirror: Arc<TopicReader<SwarmMessage>>,
    riding: Mutex<Riding>,
    /// The other processes' clocks: stamps from them are converted into this one's.
    clocks: Arc<PeerClocks>,
}

impl Agent {
    /// Opens the agent's topics on `carrier`, counting in `counters`.
    ///
    /// # Errors
    /// A topic, reader or writer could not be created.
    pub fn open(
        carrier: &impl Carrier,
        config: AgentConfig,
        counters: &Arc<DdsCounters>,
    ) -> Result<Agent, DdsError> {
        let read = |spec: &topics::TopicSpec, what: &str| {
            TopicReader::open(carrier, spec, counters, what).map(Arc::new)
        };
        Ok(Agent {
            leases: TopicReader::open(
                carrier,
                &topics::coordinator(),
                counters,
                "coordinator lease sample",
            )?,
            observer: Mutex::new(Observer::new(ElectionConfig::default(), clock::now())),
            local: Mutex::new(BTreeSet::new()),
            reports_out: TopicWriter::open(carrier, &topics::swarm_report(), counters)?,
            reports_in: read(&topics::swarm_report(), "report sample")?,
            targets: read(&topics::swarm_target(), "swarm protocol sample")?,
            commands: read(&topics::swarm_command(), "swarm protocol sample")?,
            results: TopicWriter::open(carrier, &topics::swarm_command_result(), counters)?,
            events: TopicWriter::open(carrier, &topics::swarm_events(), counters)?,
            mirror: read(&topics::formation(), "formation sample")?,
            riding: Mutex::new(Riding::new(config.ride_through)),
            clocks: Arc::default(),
            config,
            counters: counters.clone(),
        })
    }

    /// Converts stamps from other processes with `clocks` (without, they are taken as
    /// this process's).
    pub fn with_clocks(mut self, clocks: Arc<PeerClocks>) -> Self {
        self.clocks = clocks;
        self
    }

    /// Takes over what `old` (this agent on the participant it replaces, after a change
    /// of the network interfaces) knew: the coordinators' leases (so the silence since
    /// the last one, the highest epoch and the hold that follows are counted from the
    /// last lease heard, not from the rejoin) and the formation it rides through.
    pub fn carry_over(&self, old: &Agent) {
        let observer = std::mem::replace(
            &mut *old.observer.lock().unwrap_or_else(PoisonError::into_inner),
            Observer::new(ElectionConfig::default(), clock::now()),
        );
        *self.observer.lock().unwrap_or_else(PoisonError::into_inner) = observer;
        let riding = std::mem::replace(&mut *old.riding(), Riding::new(old.config.ride_through));
        *self.riding() = riding;
    }

    fn is_local(&self, id: &str) -> bool {
        self.local
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .contains(id)
    }

    fn riding(&self) -> std::sync::MutexGuard<'_, Riding> {
        self.riding.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Whether to obey a sample from `env`'s sender now (the leases heard so far taken
    /// in first): only the active coordinator of the highest epoch.
    fn verdict(&self, env: &Envelope) -> Result<(), Refusal> {
        self.drain_leases();
        self.observer
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .accepts(&env.sender_id, env.epoch, clock::now())
    }

    fn drain_leases(&self) {
        let now = clock::now();
        let mut o = self.observer.lock().unwrap_or_else(PoisonError::into_inner);
        while let Some(l) = self.leases.try_next() {
            o.heard(lease::from_msg(l), now);
        }
    }
}

/// Runs the agent until the task is aborted (see the module docs).
pub async fn run<C: AgentContext>(agent: Arc<Agent>, ctx: Arc<C>) {
    let Some(frame) = ctx.swarm_frame().await else {
        tracing::error!("dds: the agent's coordinator did not answer: no carrier");
        return;
    };
    let mut uplink = ctx.tap_uplink();
    let mut tasks = JoinSet::new();
    for reader in [agent.targets.clone(), agent.commands.clone()] {
        let (a, c, f) = (agent.clone(), ctx.clone(), frame.clone());
        tasks.spawn(async move { obey(&a, c.as_ref(), f.as_ref(), &reader).await });
    }
    let (a, c, f) = (agent.clone(), ctx.clone(), frame.clone());
    tasks.spawn(async move { neighbours(&a, c.as_ref(), f.as_ref()).await });
    let (a, c, f) = (agent.clone(), ctx.clone(), frame.clone());
    tasks.spawn(async move { formation(&a, c.as_ref(), f.as_ref()).await });
    let a = agent.clone();
    tasks.spawn(async move {
        let id = &a.config.agent_id;
        while let Some(msg) = uplink.recv().await {
            if let Ok(m) = Envelope::message(msg.vehicle_id(), id, 0, None, &msg) {
                let _ = a.results.publish(m);
            }
        }
    });
    let a = agent.clone();
    let mut events = ctx.vehicle_events();
    tasks.spawn(async move {
        let id = &a.config.agent_id;
        loop {
            let ev = match events.recv().await {
                Ok(ev) => ev,
                Err(broadcast::error::RecvError::Lagged(n)) => {
                    tracing::warn!("dds: {n} events of this agent were not forwarded (lagged)");
                    continue;
                }
                Err(_) => return,
            };
            if let Some(vehicle) = ev.vehicle_id()
                && let Ok(m) = Envelope::message(vehicle, id, 0, None, &ev)
            {
                let _ = a.events.publish(m);
            }
        }
    });
    let period = Duration::from_secs_f64(1.0 / agent.config.report_rate_hz.clamp(1.0, 100.0));
    let mut tick = tokio::time::interval(period);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut loss = Loss::default();
    loop {
        tick.tick().await;
        agent.drain_leases();
        let Some(reports) = ctx.reports().await else {
            continue;
        };
        *agent.local.lock().unwrap_or_else(PoisonError::into_inner) =
            reports.iter().map(|(id, _)| id.clone()).collect();
        loss.check(&agent, ctx.as_ref(), &reports);
        ride(&agent, ctx.as_ref());
        publish_reports(&agent, ctx.as_ref(), frame.as_ref(), reports).await;
    }
}

/// One tick of the ride-through: slot targets for the local vehicles that ride, and
/// the silent members of other agents predicted on their slots (see [`crate::ride`]).
fn ride(agent: &Agent, ctx: &impl AgentContext) {
    let now = wall_us();
    let tick = agent.riding().tick(now);
    let me = &agent.config.agent_id;
    for id in &tick.started {
        let riding = agent.riding();
        let (reference, motion) = riding.describe();
        let slot = riding.describe_slot(id, now);
        drop(riding);
        tracing::warn!(
            "agent `{me}`: no slot target for {id} for {} ms: it rides through on its slot \
             from the formation's mirror ({motion}, reference at {reference}; {slot})",
            crate::ride::RIDE_AFTER.as_millis()
        );
    }
    for id in &tick.predicting {
        let silent = agent.riding().describe_neighbour(id, now);
        tracing::warn!("agent `{me}`: {id} predicted on its slot for separation ({silent})");
    }
    for id in &tick.ended {
        tracing::warn!("agent `{me}`: {id} no longer rides through");
    }
    for (id, target) in tick.targets {
        ctx.to_vehicle(
            id,
            ToVehicle::Slot {
                target: Some(target),
            },
        );
    }
    for (id, report) in tick.neighbours {
        ctx.neighbour(id, report);
    }
}

/// Keeps the active coordinator's formation mirror (in this process's frame) for the
/// ride-through.
async fn formation(agent: &Agent, ctx: &impl AgentContext, frame: &dyn SwarmFrame) {
    loop {
        let env = Envelope::from_msg(agent.mirror.next().await);
        if agent.verdict(&env).is_err() {
            continue; // a standby's, or an old epoch's
        }
        let Some(mirror) =
            crate::mirror::received_mirror(&agent.counters, &agent.clocks, frame, &env)
        else {
            continue;
        };
        let Some(fence) = ctx.geofence().await else {
            continue;
        };
        agent.riding().on_mirror(mirror, &fence);
    }
}

/// Publishes each local vehicle's report with its snapshot.
async fn publish_reports(
    agent: &Agent,
    ctx: &impl AgentContext,
    frame: &dyn SwarmFrame,
    reports: Vec<(String, VehicleReport)>,
) {
    let Some(snapshots) = ctx.snapshots().await else {
        return;
    };
    for (id, report) in reports {
        let Some(snapshot) = snapshots.iter().find(|s| s.id == id).cloned() else {
            continue;
        };
        let report = VehicleReport {
            ride_through_s: Some(agent.config.ride_through.as_secs_f64()),
            ..report
        };
        let body = ReportBody { report, snapshot };
        if let Ok(m) = Envelope::message(&id, &agent.config.agent_id, 0, frame.frame(), &body) {
            let _ = agent.reports_out.publish(m);
        }
    }
}

/// What the agent did about a missing coordinator.
#[derive(Debug, Default)]
struct Loss {
    held: bool,
    acted: bool,
}

impl Loss {
    fn check(
        &mut self,
        agent: &Agent,
        ctx: &impl AgentContext,
        reports: &[(String, VehicleReport)],
    ) {
        // Silence past when the next lease was due: a cut of the link shorter than the
        // timeout never makes the agent hold.
        let lost = agent
            .observer
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .lost_for(clock::now())
            .saturating_sub(ElectionConfig::default().publish_period);
        let cfg = &agent.config;
        let hold_after = cfg.coordinator_timeout.max(cfg.ride_through);
        if lost < hold_after {
            if self.held {
                tracing::warn!("agent `{}`: a coordinator is active again", cfg.agent_id);
            }
            *self = Loss::default();
            return;
        }
        let send = |id: &str, command: Command| {
            ctx.to_vehicle(
                id.to_string(),
                ToVehicle::Command {
                    command_id: 0,
                    command,
                },
            );
        };
        if !self.held {
            self.held = true;
            let steered: Vec<&str> = reports
                .iter()
                .filter(|(_, r)| matches!(r.state, VehicleState::InFormation | VehicleState::GoTo))
                .map(|(id, _)| id.as_str())
                .collect();
            tracing::warn!(
                "agent `{}`: no coordinator for {:.1} s: holding {}",
                cfg.agent_id,
                lost.as_secs_f64(),
                if steered.is_empty() {
                    "nothing (no vehicle flies a slot or a go-to)".to_string()
                } else {
                    steered.join(", ")
                }
            );
            for id in steered {
                send(id, Command::Hold);
            }
        }
        if !self.acted && lost >= hold_after + cfg.lost_action_after {
            self.acted = true;
            let command = match cfg.lost_action {
                LostAction::Hold => return,
                LostAction::Land => Command::Land,
                LostAction::Rtl => Command::Rtl,
            };
            for (id, r) in reports.iter().filter(|(_, r)| {
                matches!(
                    r.state,
                    VehicleState::Hovering | VehicleState::InFormation | VehicleState::GoTo
                )
            }) {
                tracing::warn!(
                    "agent `{}`: no coordinator for {:.1} s: {id} ({}) does {}",
                    cfg.agent_id,
                    lost.as_secs_f64(),
                    r.state.name(),
                    command.name()
                );
                send(id, command.clone());
            }
        }
    }
}

/// Hands the active coordinator's targets or commands to the local vehicles.
async fn obey(
    agent: &Agent,
    ctx: &impl AgentContext,
    frame: &dyn SwarmFrame,
    reader: &TopicReader<SwarmMessage>,
) {
    loop {
        let env = Envelope::from_msg(reader.next().await);
        if !agent.is_local(&env.vehicle_id) {
            continue; // another agent's vehicle
        }
        let Some(msg) = body_or_drop::<ToVehicle>(&agent.counters, &env, "message") else {
            continue;
        };
        if let Err(why) = agent.verdict(&env) {
            DdsCounters::add(&agent.counters.protocol_refused);
            tracing::debug!(
                "dds: {} from `{}` (epoch {}) not obeyed: {why}",
                env.vehicle_id,
                env.sender_id,
                env.epoch
            );
            continue;
        }
        let reframe = into_frame(frame, env.origin);
        let c = &agent.counters;
        let Some(mut msg) = reframed_or_drop(c, &env, "message", msg, reframe.as_ref(), |r, m| {
            r.to_vehicle(m)
        }) else {
            continue;
        };
        if let ToVehicle::Slot {
            target: Some(target),
        } = &mut msg
        {
            target.stamp_us = agent.clocks.to_local_us(&env.sender_id, target.stamp_us);
        }
        DdsCounters::add(&agent.counters.protocol_obeyed);
        match &msg {
            ToVehicle::Slot {
                target: Some(target),
            } => agent.riding().on_target(&env.vehicle_id, *target),
            ToVehicle::Slot { target: None } | ToVehicle::Command { .. } => {
                agent.riding().forget(&env.vehicle_id)
            }
            _ => {}
        }
        ctx.to_vehicle(env.vehicle_id, msg);
    }
}

/// Gives the local coordinator the other agents' vehicles as neighbours.
async fn neighbours(agent: &Agent, ctx: &impl AgentContext, frame: &dyn SwarmFrame) {
    loop {
        let env = Envelope::from_msg(agent.reports_in.next().await);
        if env.sender_id == agent.config.agent_id || agent.is_local(&env.vehicle_id) {
            continue;
        }
        let Some(own) = frame.frame() else {
            continue; // no own frame yet: nothing of ours flies
        };
        let Some(body) = body_or_drop::<ReportBody>(&agent.counters, &env, "report") else {
            continue;
        };
        let reframe = Reframe::new(env.origin, own);
        let c = &agent.counters;
        let Some(mut report) =
            reframed_or_drop(c, &env, "report", body.report, reframe.as_ref(), |r, x| {
                r.report(x)
            })
        else {
            continue;
        };
        report.stamp_us = agent.clocks.to_local_us(&env.sender_id, report.stamp_us);
        agent.riding().on_neighbour(&env.vehicle_id, report);
        ctx.neighbour(env.vehicle_id, report);
    }
}
