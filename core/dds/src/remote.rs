//! The coordinator's side of the swarm protocol on DDS (`skein coordinator`): the agents'
//! vehicles as remote proxies.
//!
//! A vehicle joins when its first report arrives on `/skein/swarm/report`: the role
//! hands the coordinator ([`RemoteContext::joined`]) a [`RemoteJoin`] whose port
//! publishes on `/skein/swarm/target` and `/skein/swarm/command` with this candidate's id
//! and epoch (a standby's port refuses: only the active coordinator steers), and whose
//! snapshots and reports follow the agent's, converted into this process's swarm frame.
//! What the vehicles answer on `/skein/swarm/command_result` goes to the coordinator as
//! from a local vehicle, and their events on `/skein/swarm/events` to its event stream.
//! The topics and the watch channels live in [`Remotes`], outside the `DdsLink` actor,
//! so a restart of `coordinator/dds` keeps every proxy working.
//!
//! A vehicle whose agent falls silent is not removed: its last report ages, and the
//! coordinator shows it `Lost` once that report is older than its silence timeout; the
//! next report brings it back through the same channels (no second join).
//!
//! Under DDS Security each vehicle is bound to the identity (the enclave,
//! [`WriterIdentity`]) that first reported it: reports, answers and events about it from
//! any other enclave are dropped and counted (`protocol_forged`), so that one enrolled
//! agent cannot speak for another's vehicles. Binding to the enclave rather than to the
//! participant keeps a restarted agent (a new participant, the same enclave) its
//! vehicles; binding to the first reporter rather than to a vehicle list in the
//! permissions keeps enrolment to one certificate per companion computer.

use crate::carrier::{Carrier, Received, TopicReader, TopicWriter, WriterIdentity};
use crate::counters::DdsCounters;
use crate::envelope::{Envelope, ReportBody, body_or_drop, reframed_or_drop};
use crate::error::DdsError;
use crate::msgs::SwarmMessage;
use crate::reframe::{FrameSource, SwarmFrame, into_frame};
use crate::topics;
use skein_model::vehicle::VehicleSnapshot;
use skein_swarm::SwarmEvent;
use skein_swarm::clocks::PeerClocks;
use skein_swarm::election::{CoordinatorRole, ElectionStatus};
use skein_swarm::link_security::{LinkSecurity, ProvenAgent};
use skein_swarm::protocol::{FromVehicle, ToVehicle, VehiclePort, VehicleReport};
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, PoisonError, Weak};
use tokio::sync::watch;

/// A vehicle of an agent, joining this coordinator with its first report.
pub struct RemoteJoin {
    /// Vehicle id (`"uav-3"`).
    pub id: String,
    /// The agent that runs it (its id on the topics).
    pub agent: String,
    /// Where its [`ToVehicle`] messages go.
    pub port: Arc<dyn VehiclePort>,
    /// Its snapshots, swarm frame of this process.
    pub snapshots: watch::Receiver<VehicleSnapshot>,
    /// Its reports, swarm frame of this process (stamped by its agent).
    pub reports: watch::Receiver<VehicleReport>,
}

impl std::fmt::Debug for RemoteJoin {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RemoteJoin")
            .field("id", &self.id)
            .field("agent", &self.agent)
            .field("snapshot", &*self.snapshots.borrow())
            .field("report", &*self.reports.borrow())
            .finish_non_exhaustive()
    }
}

/// What the coordinator's remote vehicles need from this process.
pub trait RemoteContext: FrameSource {
    /// A vehicle of another process joins.
    fn joined(&self, vehicle: RemoteJoin);

    /// A remote vehicle's answer (acks, state changes, payload answers), as from a local
    /// one.
    fn answer(&self, msg: FromVehicle);

    /// A remote vehicle's event, for this process's event stream.
    fn event(&self, event: SwarmEvent);
}

/// One remote vehicle's channels.
struct Channels {
    snapshots: watch::Sender<VehicleSnapshot>,
    reports: watch::Sender<VehicleReport>,
}

/// The coordinator's protocol topics and the remote vehicles it has heard, by id.
pub struct Remotes {
    counters: Arc<DdsCounters>,
    vehicles: Mutex<BTreeMap<String, Channels>>,
    /// `/skein/swarm/report`, read.
    reports: TopicReader<SwarmMessage>,
    /// `/skein/swarm/target` and `/skein/swarm/command`, written.
    targets: TopicWriter<SwarmMessage>,
    commands: TopicWriter<SwarmMessage>,
    /// `/skein/swarm/command_result` and `/skein/swarm/events`, read.
    results: TopicReader<SwarmMessage>,
    events: TopicReader<SwarmMessage>,
    /// The agents' clocks: their reports' stamps are converted into this one's.
    clocks: Arc<PeerClocks>,
    /// Under DDS Security: the identity each vehicle was first reported by.
    owners: Mutex<BTreeMap<String, WriterIdentity>>,
    /// Under DDS Security: the record the API shows, and the enclaves this process's
    /// keystore names, by identity.
    security: Option<(Arc<LinkSecurity>, BTreeMap<WriterIdentity, String>)>,
}

impl Remotes {
    /// Converts the agents' report stamps with `clocks` (without, they are taken as
    /// this process's).
    pub fn with_clocks(mut self, clocks: Arc<PeerClocks>) -> Self {
        self.clocks = clocks;
        self
    }

    /// Opens the coordinator's protocol topics on `carrier`, counting in `counters`.
    ///
    /// # Errors
    /// A topic, reader or writer could not be created.
    pub fn open(carrier: &impl Carrier, counters: &Arc<DdsCounters>) -> Result<Self, DdsError> {
        Ok(Remotes {
            reports: TopicReader::open(
                carrier,
                &topics::swarm_report(),
                counters,
                "report sample",
            )?,
            targets: TopicWriter::open(carrier, &topics::swarm_target(), counters)?,
            commands: TopicWriter::open(carrier, &topics::swarm_command(), counters)?,
            results: TopicReader::open(
                carrier,
                &topics::swarm_command_result(),
                counters,
                "answer sample",
            )?,
            events: TopicReader::open(carrier, &topics::swarm_events(), counters, "event sample")?,
            counters: counters.clone(),
            vehicles: Mutex::new(BTreeMap::new()),
            clocks: Arc::default(),
            owners: Mutex::new(BTreeMap::new()),
            security: None,
        })
    }

    /// Records each vehicle's binding in `record` for the API, naming the enclaves of
    /// `known` (identity → enclave name; [`crate::security::known_enclaves`]).
    pub fn with_security(
        mut self,
        record: Arc<LinkSecurity>,
        known: BTreeMap<WriterIdentity, String>,
    ) -> Self {
        self.security = Some((record, known));
        self
    }

    /// Whether a `what` about `vehicle` written by `from` may be read: always without DDS
    /// Security (`None`); under it, when `from` first reported the vehicle (a report binds
    /// an unbound vehicle to its writer, `binds`). A sample from another identity is
    /// counted (`protocol_forged`), logged and refused.
    fn said_by_owner(
        &self,
        env: &Envelope,
        from: Option<WriterIdentity>,
        binds: bool,
        what: &str,
    ) -> bool {
        let Some(from) = from else {
            return true;
        };
        let vehicle = env.vehicle_id.as_str();
        let mut owners = self.owners.lock().unwrap_or_else(PoisonError::into_inner);
        let owner = match owners.get(vehicle) {
            Some(o) => *o,
            None if binds => {
                owners.insert(vehicle.to_string(), from);
                if let Some((record, known)) = &self.security {
                    record.bound(
                        vehicle,
                        ProvenAgent {
                            agent: env.sender_id.clone(),
                            identity: from.to_string(),
                            enclave: known.get(&from).cloned(),
                        },
                    );
                }
                from
            }
            None => return true,
        };
        if owner == from {
            return true;
        }
        drop(owners);
        DdsCounters::add(&self.counters.protocol_forged);
        tracing::warn!(
            "dds: a {what} about {vehicle} from enclave identity {from} was dropped: \
             {vehicle} belongs to identity {owner}"
        );
        false
    }

    /// True for a vehicle of another process.
    pub fn contains(&self, id: &str) -> bool {
        self.vehicles
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .contains_key(id)
    }

    /// The topic that carries `msg`: slot targets go best-effort, the rest reliable.
    fn topic_of(&self, msg: &ToVehicle) -> &TopicWriter<SwarmMessage> {
        match msg {
            ToVehicle::Slot { .. } => &self.targets,
            _ => &self.commands,
        }
    }
}

/// The port of one remote vehicle: publishes on the protocol topics while this candidate
/// is active.
struct DdsPort {
    remotes: Weak<Remotes>,
    vehicle_id: String,
    election: watch::Receiver<ElectionStatus>,
    frame: Arc<dyn SwarmFrame>,
}

impl VehiclePort for DdsPort {
    fn send(&self, msg: ToVehicle) -> Result<(), String> {
        let remotes = self.remotes.upgrade().ok_or("the DDS link has stopped")?;
        let (id, epoch) = {
            let status = self.election.borrow();
            if status.role != CoordinatorRole::Active {
                return Err(format!(
                    "this coordinator is a standby (active: {})",
                    status
                        .active
                        .as_ref()
                        .map_or("none", |a| a.coordinator_id.as_str())
                ));
            }
            (status.this.coordinator_id.clone(), status.this.epoch)
        };
        let m = Envelope::message(&self.vehicle_id, &id, epoch, self.frame.frame(), &msg)
            .map_err(|e| e.to_string())?;
        remotes
            .topic_of(&msg)
            .publish(m)
            .map_err(|_| format!("DDS write to {} failed", self.vehicle_id))
    }
}

/// Runs the coordinator's remote vehicles until the task is aborted (see the module
/// docs); `election` is this candidate's status.
pub async fn run<C: RemoteContext>(
    remotes: Arc<Remotes>,
    election: watch::Receiver<ElectionStatus>,
    ctx: Arc<C>,
) {
    let Some(frame) = ctx.swarm_frame().await else {
        tracing::error!("dds: the coordinator did not answer: no remote vehicles");
        return;
    };
    let answers = tokio::spawn(forward(
        remotes.clone(),
        ctx.clone(),
        |r| &r.results,
        "answer",
        |c, msg| c.answer(msg),
    ));
    let forwarded = tokio::spawn(forward(
        remotes.clone(),
        ctx.clone(),
        |r| &r.events,
        "event",
        |c, ev| c.event(ev),
    ));
    // Aborted with this task.
    let _tasks = (AbortOnDrop(answers), AbortOnDrop(forwarded));
    loop {
        let (msg, from) = remotes.reports.next_from().await;
        let env = Envelope::from_msg(msg);
        // Read first: an unreadable report binds no vehicle.
        let Some(body) = body_or_drop::<ReportBody>(&remotes.counters, &env, "report") else {
            continue;
        };
        if !remotes.said_by_owner(&env, from, true, "report") {
            continue;
        }
        // A coordinator without vehicles of its own anchors at the first agent's origin.
        let reframe = into_frame(frame.as_ref(), env.origin);
        let c = &remotes.counters;
        let (Some(mut report), Some(snapshot)) = (
            reframed_or_drop(c, &env, "report", body.report, reframe.as_ref(), |r, x| {
                r.report(x)
            }),
            reframed_or_drop(
                c,
                &env,
                "report",
                body.snapshot,
                reframe.as_ref(),
                |r, x| r.snapshot(x),
            ),
        ) else {
            continue;
        };
        report.stamp_us = remotes.clocks.to_local_us(&env.sender_id, report.stamp_us);
        let mut map = remotes
            .vehicles
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        if let Some(c) = map.get(&env.vehicle_id) {
            c.snapshots.send_replace(snapshot);
            c.reports.send_replace(report);
            continue;
        }
        let (snapshots, snapshots_rx) = watch::channel(snapshot);
        let (reports, reports_rx) = watch::channel(report);
        map.insert(env.vehicle_id.clone(), Channels { snapshots, reports });
        drop(map);
        let port = DdsPort {
            remotes: Arc::downgrade(&remotes),
            vehicle_id: env.vehicle_id.clone(),
            election: election.clone(),
            frame: frame.clone(),
        };
        ctx.joined(RemoteJoin {
            id: env.vehicle_id,
            agent: env.sender_id,
            port: Arc::new(port),
            snapshots: snapshots_rx,
            reports: reports_rx,
        });
    }
}

/// Hands every `B` sample (a `what`) of the topic `reader` picks about a remote vehicle
/// to `deliver`; samples about other vehicles are skipped, unreadable ones counted and
/// dropped.
async fn forward<C, B: for<'de> serde::Deserialize<'de>>(
    remotes: Arc<Remotes>,
    ctx: Arc<C>,
    reader: impl Fn(&Remotes) -> &TopicReader<SwarmMessage>,
    what: &str,
    deliver: impl Fn(&C, B),
) {
    loop {
        let (msg, from): Received<SwarmMessage> = reader(&remotes).next_from().await;
        let env = Envelope::from_msg(msg);
        if remotes.contains(&env.vehicle_id)
            && remotes.said_by_owner(&env, from, false, what)
            && let Some(b) = body_or_drop::<B>(&remotes.counters, &env, what)
        {
            deliver(&ctx, b);
        }
    }
}

/// Aborts a task when dropped.
struct AbortOnDrop(tokio::task::JoinHandle<()>);

impl Drop for AbortOnDrop {
    fn drop(&mut self) {
        self.0.abort();
    }
}
