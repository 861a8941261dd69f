//! The agent's side of the swarm protocol on DDS (`skein agent`): the vehicles of this
//! computer, reached by the coordinators of the domain.
//!
//! The agent's coordinator actor supervises its vehicles; this carrier, run by the
//! `DdsLink` service (so it restarts with it):
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
//! - **without a coordinator** for [`AgentConfig::coordinator_timeout`] (default 1.5 s),
//!   commands every vehicle flying a slot or a go-to to hold where it is (offboard: the
//!   setpoint stream never stops), and after [`AgentConfig::lost_action_after`] more does
//!   [`AgentConfig::lost_action`] with the airborne ones. A coordinator that appears again
//!   takes them back (the formation joins hovering vehicles).

use crate::envelope::{Envelope, ReportBody, body_or_drop, receive};
use crate::link::{DdsError, DdsShared, err};
use crate::msgs::{self, RosMessage};
use crate::reframe::{Reframe, into_view, reframed};
use crate::topics;
use ros2_client::{Name, Node, Subscription};
use skein_model::fsm::VehicleState;
use skein_swarm::election::observer::Observer;
use skein_swarm::election::{ElectionConfig, Lease};
use skein_swarm::protocol::{ToVehicle, VehicleCommand, VehicleReport};
use skein_swarm::view::SwarmView;
use skein_swarm::{CoordinatorMsg, DistributedMsg};
use std::collections::BTreeSet;
use std::str::FromStr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};
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
    /// No lease claiming the role heard for this long: the agent holds (default 1.5 s).
    pub coordinator_timeout: Duration,
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
            lost_action_after: Duration::from_secs(30),
            lost_action: LostAction::Hold,
            report_rate_hz: 20.0,
        }
    }
}

/// Counters of the agent's carrier (in `/metrics` as `skein_dds_samples{what=...}`).
#[derive(Debug, Default)]
pub struct AgentCounters {
    /// Targets and commands handed to a local vehicle.
    pub obeyed: AtomicU64,
    /// Targets and commands for a local vehicle dropped: not from the active
    /// coordinator, or of an old epoch.
    pub refused: AtomicU64,
}

/// The agent's state that outlives the `DdsLink` actor.
pub struct Agent {
    config: AgentConfig,
    leases: Subscription<msgs::CoordinatorLease>,
    observer: Mutex<Observer>,
    /// Ids of the vehicles of this process (from the last report tick).
    local: Mutex<BTreeSet<String>>,
    /// The carrier's counters.
    pub counters: AgentCounters,
}

impl Agent {
    /// Creates the lease reader on `node`.
    ///
    /// # Errors
    /// The topic or reader could not be created.
    pub(crate) fn new(node: &mut Node, config: AgentConfig) -> Result<Agent, DdsError> {
        let topic = node
            .create_topic(
                &Name::new(topics::NAMESPACE, "coordinator")
                    .map_err(|e| DdsError(format!("coordinator topic: {e:?}")))?,
                msgs::CoordinatorLease::type_name(),
                &topics::leases(),
            )
            .map_err(err("coordinator topic"))?;
        let leases = node
            .create_subscription(&topic, None)
            .map_err(err("coordinator subscription"))?;
        Ok(Agent {
            config,
            leases,
            observer: Mutex::new(Observer::new(ElectionConfig::default(), Instant::now())),
            local: Mutex::new(BTreeSet::new()),
            counters: AgentCounters::default(),
        })
    }

    fn is_local(&self, id: &str) -> bool {
        self.local
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .contains(id)
    }

    fn drain_leases(&self, shared: &DdsShared) {
        let now = Instant::now();
        let mut o = self.observer.lock().unwrap_or_else(PoisonError::into_inner);
        loop {
            match self.leases.take() {
                Ok(Some((l, _))) => o.heard(
                    Lease {
                        coordinator_id: l.coordinator_id,
                        priority: l.priority,
                        epoch: l.epoch,
                        active: l.active,
                        api_url: l.api_url,
                    },
                    now,
                ),
                Ok(None) => break,
                Err(e) => {
                    shared.counters.malformed.fetch_add(1, Ordering::Relaxed);
                    tracing::warn!("dds: a coordinator lease sample was dropped: {e:?}");
                }
            }
        }
    }
}

/// Runs the agent's carrier until the task is aborted (see the module docs).
pub(crate) async fn run(shared: Arc<DdsShared>) {
    let (Some(agent), Some(topics)) = (shared.agent(), shared.protocol()) else {
        return;
    };
    let Some(view) = shared.view().await else {
        tracing::error!("dds: the agent's coordinator did not answer: no carrier");
        return;
    };
    let (tap, mut uplink) = tokio::sync::mpsc::unbounded_channel();
    let _ = shared
        .coordinator()
        .cast(CoordinatorMsg::Distributed(DistributedMsg::TapUplink(tap)));
    let mut tasks = JoinSet::new();
    for reader in [topics.target.reader.clone(), topics.command.reader.clone()] {
        let (s, v) = (shared.clone(), view.clone());
        tasks.spawn(async move { obey(&s, &v, &reader).await });
    }
    let (s, v) = (shared.clone(), view.clone());
    tasks.spawn(async move { neighbours(&s, &v).await });
    let s = shared.clone();
    tasks.spawn(async move {
        let id = s
            .agent()
            .map(|a| a.config.agent_id.clone())
            .unwrap_or_default();
        while let Some(msg) = uplink.recv().await {
            if let Some(p) = s.protocol()
                && let Ok(m) = Envelope::message(msg.vehicle_id(), &id, 0, None, &msg)
            {
                s.count(p.command_result.writer.publish(m));
            }
        }
    });
    let s = shared.clone();
    let mut events = shared.events().subscribe();
    tasks.spawn(async move {
        let id = s
            .agent()
            .map(|a| a.config.agent_id.clone())
            .unwrap_or_default();
        loop {
            let ev = match events.recv().await {
                Ok(ev) => ev,
                Err(tokio::sync::broadcast::error::RecvError::Lagged(n)) => {
                    tracing::warn!("dds: {n} events of this agent were not forwarded (lagged)");
                    continue;
                }
                Err(_) => return,
            };
            if let (Some(vehicle), Some(p)) = (ev.vehicle_id(), s.protocol())
                && let Ok(m) = Envelope::message(vehicle, &id, 0, None, &ev)
            {
                s.count(p.events.writer.publish(m));
            }
        }
    });
    let period = Duration::from_secs_f64(1.0 / agent.config.report_rate_hz.clamp(1.0, 100.0));
    let mut tick = tokio::time::interval(period);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut loss = Loss::default();
    loop {
        tick.tick().await;
        agent.drain_leases(&shared);
        let Some(reports) = shared.local_reports().await else {
            continue;
        };
        *agent.local.lock().unwrap_or_else(PoisonError::into_inner) =
            reports.iter().map(|(id, _)| id.clone()).collect();
        loss.check(&shared, agent, &reports);
        publish_reports(&shared, agent, &view, reports).await;
    }
}

/// Publishes each local vehicle's report with its snapshot.
async fn publish_reports(
    shared: &DdsShared,
    agent: &Agent,
    view: &SwarmView,
    reports: Vec<(String, VehicleReport)>,
) {
    let Some(topics) = shared.protocol() else {
        return;
    };
    let Some(snapshots) = shared.list_vehicles().await else {
        return;
    };
    for (id, report) in reports {
        let Some(snapshot) = snapshots.iter().find(|s| s.id == id).cloned() else {
            continue;
        };
        let body = ReportBody { report, snapshot };
        if let Ok(m) = Envelope::message(&id, &agent.config.agent_id, 0, view.frame(), &body) {
            shared.count(topics.report.writer.publish(m));
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
    fn check(&mut self, shared: &DdsShared, agent: &Agent, reports: &[(String, VehicleReport)]) {
        let lost = agent
            .observer
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .lost_for(Instant::now());
        let cfg = &agent.config;
        if lost < cfg.coordinator_timeout {
            if self.held {
                tracing::warn!("agent `{}`: a coordinator is active again", cfg.agent_id);
            }
            *self = Loss::default();
            return;
        }
        let send = |id: &str, command: VehicleCommand| {
            let _ = shared.coordinator().cast(CoordinatorMsg::Distributed(
                DistributedMsg::ToLocalVehicle(
                    id.to_string(),
                    ToVehicle::Command {
                        command_id: 0,
                        command,
                    },
                ),
            ));
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
                send(id, VehicleCommand::Hold);
            }
        }
        if !self.acted && lost >= cfg.coordinator_timeout + cfg.lost_action_after {
            self.acted = true;
            let command = match cfg.lost_action {
                LostAction::Hold => return,
                LostAction::Land => VehicleCommand::Land,
                LostAction::Rtl => VehicleCommand::Rtl,
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
async fn obey(shared: &DdsShared, view: &SwarmView, reader: &Subscription<msgs::SwarmMessage>) {
    let Some(agent) = shared.agent() else {
        return;
    };
    loop {
        let env = receive(shared, reader, "swarm protocol").await;
        if !agent.is_local(&env.vehicle_id) {
            continue; // another agent's vehicle
        }
        let Some(msg) = body_or_drop::<ToVehicle>(shared, &env, "message") else {
            continue;
        };
        agent.drain_leases(shared);
        let verdict = agent
            .observer
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .accepts(&env.sender_id, env.epoch, Instant::now());
        if let Err(why) = verdict {
            agent.counters.refused.fetch_add(1, Ordering::Relaxed);
            tracing::debug!(
                "dds: {} from `{}` (epoch {}) not obeyed: {why}",
                env.vehicle_id,
                env.sender_id,
                env.epoch
            );
            continue;
        }
        let reframe = into_view(view, env.origin);
        let msg = reframed(msg, reframe.as_ref(), |r, m| r.to_vehicle(m));
        agent.counters.obeyed.fetch_add(1, Ordering::Relaxed);
        let _ =
            shared
                .coordinator()
                .cast(CoordinatorMsg::Distributed(DistributedMsg::ToLocalVehicle(
                    env.vehicle_id,
                    msg,
                )));
    }
}

/// Gives the local coordinator the other agents' vehicles as neighbours.
async fn neighbours(shared: &DdsShared, view: &SwarmView) {
    let (Some(agent), Some(topics)) = (shared.agent(), shared.protocol()) else {
        return;
    };
    loop {
        let env = receive(shared, &topics.report.reader, "report").await;
        if env.sender_id == agent.config.agent_id || agent.is_local(&env.vehicle_id) {
            continue;
        }
        let Some(frame) = view.frame() else {
            continue; // no own frame yet: nothing of ours flies
        };
        let Some(body) = body_or_drop::<ReportBody>(shared, &env, "report") else {
            continue;
        };
        let reframe = Reframe::new(env.origin, frame);
        let report = reframed(body.report, reframe.as_ref(), |r, x| r.report(x));
        let _ = shared
            .coordinator()
            .cast(CoordinatorMsg::Distributed(DistributedMsg::Neighbour(
                env.vehicle_id,
                report,
            )));
    }
}
