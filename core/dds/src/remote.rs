//! The coordinator's side of the swarm protocol on DDS (`skein coordinator`): the agents'
//! vehicles as remote proxies.
//!
//! A vehicle joins when its first report arrives on `/skein/swarm/report`: the carrier
//! gives the coordinator a [`RemoteVehicle`] whose port publishes on
//! `/skein/swarm/target` and `/skein/swarm/command` with this candidate's id and epoch
//! (a standby's port refuses: only the active coordinator steers), and whose snapshots
//! and reports follow the agent's, converted into this process's swarm frame. What the
//! vehicles answer on `/skein/swarm/command_result` goes to the coordinator's mailbox as
//! from a local vehicle, and their events on `/skein/swarm/events` to its event stream. The watch channels live in [`Remotes`], outside the `DdsLink`
//! actor, so a restart of `coordinator/dds` keeps every proxy working.

use crate::envelope::{Envelope, ReportBody, body_or_drop, receive};
use crate::link::DdsShared;
use crate::reframe::{into_view, reframed};
use skein_model::vehicle::VehicleSnapshot;
use skein_swarm::election::{CoordinatorRole, ElectionStatus};
use skein_swarm::protocol::{FromVehicle, ToVehicle, VehiclePort, VehicleReport};
use skein_swarm::view::SwarmView;
use skein_swarm::{CoordinatorMsg, DistributedMsg, RemoteVehicle, SwarmEvent};
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, PoisonError, Weak};
use tokio::sync::watch;

/// One remote vehicle's channels.
struct Channels {
    snapshots: watch::Sender<VehicleSnapshot>,
    reports: watch::Sender<VehicleReport>,
}

/// The remote vehicles this coordinator has heard, by id.
#[derive(Default)]
pub struct Remotes {
    vehicles: Mutex<BTreeMap<String, Channels>>,
}

impl Remotes {
    /// True for a vehicle of another process.
    pub fn contains(&self, id: &str) -> bool {
        self.vehicles
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .contains_key(id)
    }
}

/// The port of one remote vehicle: publishes on the protocol topics while this candidate
/// is active.
struct DdsPort {
    shared: Weak<DdsShared>,
    vehicle_id: String,
    election: watch::Receiver<ElectionStatus>,
    view: Arc<SwarmView>,
}

impl VehiclePort for DdsPort {
    fn send(&self, msg: ToVehicle) -> Result<(), String> {
        let shared = self.shared.upgrade().ok_or("the DDS link has stopped")?;
        let topics = shared.protocol().ok_or("no swarm protocol topics")?;
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
        let topic = topics.to_vehicle_topic(&msg);
        let m = Envelope::message(&self.vehicle_id, &id, epoch, self.view.frame(), &msg)
            .map_err(|e| e.to_string())?;
        let r = topic.writer.publish(m);
        let failed = r.is_err();
        shared.count(r);
        if failed {
            return Err(format!("DDS write to {} failed", self.vehicle_id));
        }
        Ok(())
    }
}

/// Runs the coordinator's carrier until the task is aborted (see the module docs).
pub(crate) async fn run(shared: Arc<DdsShared>) {
    let (Some(topics), Some(election)) = (shared.protocol(), shared.election()) else {
        return;
    };
    let Some(view) = shared.view().await else {
        tracing::error!("dds: the coordinator did not answer: no remote vehicles");
        return;
    };
    let answers = tokio::spawn(forward(
        shared.clone(),
        topics.command_result.reader.clone(),
        "answer",
        |s, msg: FromVehicle| {
            let _ = s.coordinator().cast(CoordinatorMsg::FromVehicle(msg));
        },
    ));
    let forwarded = tokio::spawn(forward(
        shared.clone(),
        topics.events.reader.clone(),
        "event",
        |s, ev: SwarmEvent| {
            let _ = s.events().send(ev);
        },
    ));
    // Aborted with this task.
    let _tasks = (AbortOnDrop(answers), AbortOnDrop(forwarded));
    loop {
        let env = receive(&shared, &topics.report.reader, "report").await;
        let Some(body) = body_or_drop::<ReportBody>(&shared, &env, "report") else {
            continue;
        };
        // A coordinator without vehicles of its own anchors at the first agent's origin.
        let reframe = into_view(&view, env.origin);
        let report = reframed(body.report, reframe.as_ref(), |r, x| r.report(x));
        let snapshot = reframed(body.snapshot, reframe.as_ref(), |r, x| r.snapshot(x));
        let mut map = shared
            .remotes()
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
            shared: Arc::downgrade(&shared),
            vehicle_id: env.vehicle_id.clone(),
            election: election.clone(),
            view: view.clone(),
        };
        let _ = shared.coordinator().cast(CoordinatorMsg::Distributed(
            DistributedMsg::AddRemoteVehicle(RemoteVehicle {
                id: env.vehicle_id,
                port: Arc::new(port),
                snapshots: snapshots_rx,
                reports: reports_rx,
                agent: env.sender_id,
            }),
        ));
    }
}

/// Hands every `B` sample of `reader` about a remote vehicle to `deliver`; samples about
/// other vehicles are skipped, unreadable ones counted and dropped.
async fn forward<B: for<'de> serde::Deserialize<'de>>(
    shared: Arc<DdsShared>,
    reader: Arc<ros2_client::Subscription<crate::msgs::SwarmMessage>>,
    what: &'static str,
    deliver: impl Fn(&DdsShared, B),
) {
    loop {
        let env = receive(&shared, &reader, what).await;
        if shared.remotes().contains(&env.vehicle_id)
            && let Some(b) = body_or_drop::<B>(&shared, &env, what)
        {
            deliver(&shared, b);
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
