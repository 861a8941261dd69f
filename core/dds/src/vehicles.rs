//! The vehicles of this process on their ROS 2 topics, for any ROS 2 node (`skein up
//! --dds`, and the agents' and coordinators' own vehicles):
//!
//! - at the publish rate it asks this process for every vehicle and publishes its pose,
//!   navsat and state (battery at a tenth of the rate, and at that rate still while
//!   rounds are shed: it is a tenth of the work, and a battery monitor must not go
//!   silent when the process is short of CPU) on `/skein/<vehicle>/*`, opening a
//!   vehicle's topics the first time it is seen; every other tick it publishes the
//!   tracks on `/skein/tracks`. A vehicle another process publishes (a coordinator's
//!   remote vehicle: its agent does) is skipped;
//! - with `accept_commands`, it takes `skein_msgs/Command`s from each vehicle's
//!   `command` topic, hands each to this process as the API would
//!   ([`VehiclesContext::command`]), and answers on `command_result` (a malformed sample
//!   is counted and dropped; a command the vehicle state forbids is refused with the
//!   FSM's reason).

use crate::carrier::{Carrier, TopicReader, TopicWriter};
use crate::convert;
use crate::counters::DdsCounters;
use crate::error::DdsError;
use crate::msgs::{self, CommandResult};
use crate::topics;
use ros2_client::builtin_interfaces::Time;
use skein_model::vehicle::VehicleSnapshot;
use skein_swarm::Command as OperatorCommand;
use skein_swarm::tracks::TrackView;
use std::collections::{BTreeMap, BTreeSet};
use std::future::Future;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;
use tokio::task::JoinSet;

/// What the vehicles' topics need from this process.
pub trait VehiclesContext: Send + Sync + 'static {
    /// Every vehicle, sorted by id (`None`: no answer).
    fn vehicles(&self) -> impl Future<Output = Option<Vec<VehicleSnapshot>>> + Send;

    /// The counter-UAS tracks (`None`: no answer).
    fn tracks(&self) -> impl Future<Output = Option<Vec<TrackView>>> + Send;

    /// Hands `command` to vehicle `vehicle_id` as `POST /api/v1/vehicles/{id}/commands`
    /// would: its command id when accepted, else why not (the FSM's reason, no such
    /// vehicle, no answer).
    fn command(
        &self,
        vehicle_id: String,
        command: OperatorCommand,
    ) -> impl Future<Output = Result<u64, String>> + Send;

    /// Whether publishing round `round` goes ahead: every round, unless the process is
    /// short of CPU and sheds optional work (see `skein_swarm::load`).
    fn keep_round(&self, _round: u64) -> impl Future<Output = bool> + Send {
        async { true }
    }
}

/// A vehicle's command reader and result writer.
type CommandTopics = (
    Arc<TopicReader<msgs::Command>>,
    Arc<TopicWriter<CommandResult>>,
);

/// One vehicle's writers and, with commands on, its command reader.
struct VehicleTopics {
    pose: TopicWriter<msgs::PoseStamped>,
    navsat: TopicWriter<msgs::NavSatFix>,
    battery: TopicWriter<msgs::BatteryState>,
    state: TopicWriter<msgs::VehicleState>,
    command: Option<CommandTopics>,
}

/// The vehicles' topics, opened as vehicles appear, and `/skein/tracks`.
pub struct Vehicles<C> {
    carrier: Arc<C>,
    counters: Arc<DdsCounters>,
    publish_rate_hz: f64,
    accept_commands: bool,
    /// True for a vehicle another process publishes.
    elsewhere: Box<dyn Fn(&str) -> bool + Send + Sync>,
    tracks: TopicWriter<msgs::Tracks>,
    vehicles: Mutex<BTreeMap<String, Arc<VehicleTopics>>>,
}

impl<C: Carrier> Vehicles<C> {
    /// Opens `/skein/tracks` on `carrier` (the vehicles' topics come as vehicles do),
    /// counting in `counters`; publishes `publish_rate_hz` times a second (0.1–100);
    /// with `accept_commands`, reads the vehicles' commands; skips the vehicles for which
    /// `elsewhere` is true.
    ///
    /// # Errors
    /// The tracks topic or writer could not be created.
    pub fn open(
        carrier: Arc<C>,
        counters: &Arc<DdsCounters>,
        publish_rate_hz: f64,
        accept_commands: bool,
        elsewhere: Box<dyn Fn(&str) -> bool + Send + Sync>,
    ) -> Result<Self, DdsError> {
        Ok(Vehicles {
            tracks: TopicWriter::open(carrier.as_ref(), &topics::tracks(), counters)?,
            carrier,
            counters: counters.clone(),
            publish_rate_hz,
            accept_commands,
            elsewhere,
            vehicles: Mutex::new(BTreeMap::new()),
        })
    }

    /// The topics of vehicle `id`, opened on first use.
    ///
    /// # Errors
    /// A topic could not be created, or another vehicle already publishes under the
    /// same ROS name (`uav-1` and `uav.1` are both `uav_1`): the second is not published,
    /// and the error names both.
    fn topics(&self, id: &str) -> Result<Arc<VehicleTopics>, DdsError> {
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
        let (carrier, counters) = (self.carrier.as_ref(), &self.counters);
        let command = if self.accept_commands {
            let sub = TopicReader::open(
                carrier,
                &topics::command(id),
                counters,
                format!("command sample for {id}"),
            )?;
            let result = TopicWriter::open(carrier, &topics::command_result(id), counters)?;
            Some((Arc::new(sub), Arc::new(result)))
        } else {
            None
        };
        let t = Arc::new(VehicleTopics {
            pose: TopicWriter::open(carrier, &topics::pose(id), counters)?,
            navsat: TopicWriter::open(carrier, &topics::navsat(id), counters)?,
            battery: TopicWriter::open(carrier, &topics::battery(id), counters)?,
            state: TopicWriter::open(carrier, &topics::state(id), counters)?,
            command,
        });
        map.insert(id.to_string(), t.clone());
        Ok(t)
    }
}

/// Publishes one vehicle's topics (battery when `battery`).
fn publish_vehicle(t: &VehicleTopics, v: &VehicleSnapshot, battery: bool) {
    let now = Time::now();
    if let Some(m) = convert::pose(v, now) {
        let _ = t.pose.publish(m);
    }
    if let Some(m) = convert::navsat(v, now) {
        let _ = t.navsat.publish(m);
    }
    if battery && let Some(m) = convert::battery(v, now) {
        let _ = t.battery.publish(m);
    }
    let _ = t.state.publish(convert::state(v, now));
}

/// Publishes at the rate and serves commands until the task is aborted (see the module
/// docs); the command tasks are in a local `JoinSet`, so aborting this task aborts them
/// too.
pub async fn run<C: Carrier, X: VehiclesContext>(vehicles: Arc<Vehicles<C>>, ctx: Arc<X>) {
    let mut commands = JoinSet::new();
    let period = Duration::from_secs_f64(1.0 / vehicles.publish_rate_hz.clamp(0.1, 100.0));
    let mut tick = tokio::time::interval(period);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut n: u64 = 0;
    // The battery goes out with the first round published once ten periods have passed
    // since the last (half a period early counts: the ticks jitter), so it keeps its
    // rate while rounds are shed. Counted in rounds, it fell to a fifth of it (a ROS 2
    // node's 3 s window then saw no second sample), or with `n % 10` never met the one
    // kept round in five at all.
    let battery_period = period * 10 - period / 2;
    let mut battery_due = tokio::time::Instant::now();
    let mut serving: BTreeSet<String> = BTreeSet::new();
    // Vehicles whose topics could not be made: logged once each.
    let mut refused: BTreeSet<String> = BTreeSet::new();
    loop {
        tick.tick().await;
        n += 1;
        // Optional work: a fifth of the rounds while the process is short of CPU.
        if !ctx.keep_round(n).await {
            continue;
        }
        let Some(list) = ctx.vehicles().await else {
            continue;
        };
        let now = tokio::time::Instant::now();
        let battery = now >= battery_due;
        if battery {
            battery_due = now + battery_period;
        }
        for v in list.iter().filter(|v| !(vehicles.elsewhere)(&v.id)) {
            let topics = match vehicles.topics(&v.id) {
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
                    ctx.clone(),
                    vehicles.counters.clone(),
                    v.id.clone(),
                    sub.clone(),
                    results.clone(),
                ));
            }
            publish_vehicle(&topics, v, battery);
        }
        if n.is_multiple_of(2)
            && let Some(views) = ctx.tracks().await
        {
            let _ = vehicles
                .tracks
                .publish(convert::tracks(&views, Time::now()));
        }
    }
}

/// Takes a vehicle's commands until the task is aborted.
async fn serve_commands<X: VehiclesContext>(
    ctx: Arc<X>,
    counters: Arc<DdsCounters>,
    id: String,
    sub: Arc<TopicReader<msgs::Command>>,
    results: Arc<TopicWriter<CommandResult>>,
) {
    loop {
        let cmd = sub.next().await;
        DdsCounters::add(&counters.commands);
        let result = obey(ctx.as_ref(), &counters, &id, &cmd).await;
        let _ = results.publish(result);
    }
}

/// Hands one command to this process; the answer for `command_result`.
async fn obey(
    ctx: &impl VehiclesContext,
    counters: &DdsCounters,
    id: &str,
    cmd: &msgs::Command,
) -> CommandResult {
    let refused = |reason: String| CommandResult {
        request_id: cmd.request_id,
        command_id: 0,
        accepted: false,
        reason,
    };
    let command = match convert::command(cmd) {
        Ok(c) => c,
        Err(e) => {
            DdsCounters::add(&counters.malformed);
            return refused(e.to_string());
        }
    };
    tracing::info!(
        "dds: {} from `{}` for {id} (request {})",
        command.name(),
        cmd.source,
        cmd.request_id
    );
    match ctx.command(id.to_string(), command).await {
        Ok(command_id) => CommandResult {
            request_id: cmd.request_id,
            command_id,
            accepted: true,
            reason: String::new(),
        },
        Err(reason) => refused(reason),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::carrier::memory::MemoryBus;
    use skein_model::geo::{GeoPoint, Ned, NedFrame};
    use skein_model::vehicle::Battery;

    /// A process short of CPU: one publishing round in five goes ahead, the ones
    /// `skein_swarm::load` keeps while shedding.
    struct Shedding(VehicleSnapshot);

    impl VehiclesContext for Shedding {
        async fn vehicles(&self) -> Option<Vec<VehicleSnapshot>> {
            Some(vec![self.0.clone()])
        }

        async fn tracks(&self) -> Option<Vec<TrackView>> {
            None
        }

        async fn command(&self, _: String, _: OperatorCommand) -> Result<u64, String> {
            Err("no commands here".into())
        }

        async fn keep_round(&self, round: u64) -> bool {
            round.is_multiple_of(5)
        }
    }

    /// While shedding, the battery keeps its rate, a tenth of the publish rate: 10 Hz shed
    /// to 2 Hz still gives the battery 1 Hz. (Counted in all rounds, the kept fifth never
    /// fell on a battery round, and a ROS 2 node saw no battery at all while skein was
    /// short of CPU; counted in published rounds, 0.2 Hz left a 3 s window one sample.)
    #[tokio::test(start_paused = true)]
    async fn the_battery_keeps_its_rate_while_shedding() {
        let bus = MemoryBus::new();
        let counters = Arc::new(DdsCounters::default());
        let vehicles =
            Vehicles::open(bus.clone(), &counters, 10.0, false, Box::new(|_| false)).unwrap();
        let frame = NedFrame::new(GeoPoint::new(47.397742, 8.545594, 488.0));
        let mut uav = VehicleSnapshot::hovering_at("uav-1", 1, &frame, Ned::new(0.0, 0.0, -5.0));
        uav.battery = Some(Battery {
            percent: 80.0,
            voltage_v: 15.8,
        });
        let read = |spec: &topics::TopicSpec| {
            TopicReader::<msgs::BatteryState>::open(bus.as_ref(), spec, &counters, "sample")
                .unwrap()
        };
        let battery = read(&topics::battery("uav-1"));
        let task = tokio::spawn(run(Arc::new(vehicles), Arc::new(Shedding(uav))));
        // 100 s of rounds at 10 Hz: 200 published, 100 of them with the battery.
        let mut batteries = 0;
        for _ in 0..1000 {
            tokio::time::sleep(Duration::from_millis(100)).await;
            batteries += std::iter::from_fn(|| battery.try_next()).count();
        }
        task.abort();
        assert!(
            (99..=101).contains(&batteries),
            "{batteries} battery samples"
        );
    }
}
