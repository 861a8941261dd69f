//! The agent ([`crate::agent`]): whom it obeys, and what it does without a coordinator.

use super::{Call, Calls, Peer, Process, origin_a, origin_b, since};
use crate::agent::{self, Agent, AgentConfig, LostAction};
use crate::carrier::TopicReader;
use crate::carrier::memory::MemoryBus;
use crate::counters::DdsCounters;
use crate::msgs::SwarmMessage;
use crate::topics;
use skein_model::fsm::VehicleState;
use skein_model::geo::Ned;
use skein_swarm::protocol::{Command, SlotTarget, ToVehicle};
use std::collections::BTreeSet;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;
use tokio::task::JoinHandle;

/// A slot target at `north_m` metres north of the sender's origin, 10 m up.
fn slot(north_m: f64) -> ToVehicle {
    let p = Ned::new(north_m, 0.0, -10.0);
    ToVehicle::Slot {
        target: Some(SlotTarget {
            slot: 1,
            leader: false,
            position: p,
            goal: p,
            velocity: Ned::ZERO,
            yaw_rad: 0.0,
            stamp_us: 1,
        }),
    }
}

fn command(command: Command) -> ToVehicle {
    ToVehicle::Command {
        command_id: 9,
        command,
    }
}

/// Starts agent `agent-a` of `process` with `config` on `bus`; returns once it has
/// published its first report (so it knows its own vehicles).
async fn start_agent(
    bus: &Arc<MemoryBus>,
    process: &Arc<Process>,
    config: AgentConfig,
) -> (Arc<DdsCounters>, JoinHandle<()>) {
    let counters = Arc::new(DdsCounters::default());
    let reports = TopicReader::<SwarmMessage>::open(
        bus.as_ref(),
        &topics::swarm_report(),
        &counters,
        "report",
    )
    .unwrap();
    let agent = Arc::new(Agent::open(bus.as_ref(), config, &counters).unwrap());
    let task = tokio::spawn(agent::run(agent, process.clone()));
    tokio::time::timeout(Duration::from_secs(1), reports.next())
        .await
        .expect("the agent reports its vehicles");
    (counters, task)
}

/// A process of one vehicle, `uav-1`, flying its slot 10 m up at the origin of frame A.
fn uav_1_in_formation() -> (Arc<Process>, Calls) {
    let (process, calls) = Process::new(Some(origin_a()));
    let process = process.with_vehicle(
        "uav-1",
        VehicleState::InFormation,
        Ned::new(0.0, 0.0, -10.0),
    );
    (process, calls)
}

fn config(lost_action: LostAction) -> AgentConfig {
    AgentConfig {
        lost_action_after: Duration::from_secs(4),
        lost_action,
        ..AgentConfig::new("agent-a".into())
    }
}

/// Every `ToVehicle` handed to the process within `within`, by vehicle.
async fn handed(calls: &mut Calls, within: Duration) -> Vec<(String, ToVehicle)> {
    let mut all = Vec::new();
    while let Some(c) = calls
        .within(within, |c| match c {
            Call::ToVehicle(id, msg) => Some((id, msg)),
            _ => None,
        })
        .await
    {
        all.push(c);
    }
    all
}

/// The ids of the vehicles the next `n` `command`s go to, the first one's protocol time
/// since `start`.
async fn commanded(
    calls: &mut Calls,
    n: usize,
    what: &Command,
    within: Duration,
    start: tokio::time::Instant,
) -> (BTreeSet<String>, f64) {
    let mut ids = BTreeSet::new();
    let mut first = None;
    for _ in 0..n {
        let id = calls
            .next(within, &format!("{what:?}"), |c| match c {
                Call::ToVehicle(id, ToVehicle::Command { command, .. }) if command == *what => {
                    Some(id)
                }
                Call::ToVehicle(id, msg) => panic!("{id} was handed {msg:?}"),
                _ => None,
            })
            .await;
        first.get_or_insert(since(start));
        ids.insert(id);
    }
    (ids, first.unwrap_or_default())
}

#[tokio::test(start_paused = true)]
async fn an_agent_obeys_only_the_active_coordinator_of_the_highest_epoch() {
    let bus = MemoryBus::new();
    let (process, mut calls) = uav_1_in_formation();
    let (counters, _agent) = start_agent(&bus, &process, config(LostAction::Hold)).await;
    let leases = Peer::leases(&bus);
    leases.lease("gcs-old", 1, true); // the other side of a partition, not told yet
    leases.lease("gcs-a", 2, true);
    leases.lease("gcs-b", 2, false);
    let (targets, commands) = (
        Peer::open(&bus, &topics::swarm_target()),
        Peer::open(&bus, &topics::swarm_command()),
    );
    // From B's frame, 30 m north and 10 m east of the agent's.
    targets.send("uav-1", "gcs-old", 1, origin_b(), &slot(1.0));
    targets.send("uav-1", "gcs-b", 2, origin_b(), &slot(2.0));
    targets.send("uav-1", "gcs-a", 1, origin_b(), &slot(3.0));
    targets.send("uav-9", "gcs-a", 2, origin_b(), &slot(4.0)); // another agent's vehicle
    targets.send("uav-1", "gcs-a", 2, origin_b(), &slot(5.0));
    commands.send("uav-1", "gcs-b", 2, origin_b(), &command(Command::Land));
    commands.send("uav-1", "gcs-a", 2, origin_b(), &command(Command::Hold));

    let mut got = handed(&mut calls, Duration::from_millis(500)).await;
    got.sort_by_key(|(_, m)| matches!(m, ToVehicle::Command { .. }));
    let [
        (id, ToVehicle::Slot { target: Some(t) }),
        (id2, ToVehicle::Command { command, .. }),
    ] = got.as_slice()
    else {
        panic!("not one slot and one command for uav-1: {got:?}");
    };
    assert_eq!((id.as_str(), id2.as_str()), ("uav-1", "uav-1"));
    assert_eq!(*command, Command::Hold);
    // gcs-a's slot 5 m north of B's origin, in the agent's frame.
    assert!(
        (t.position - Ned::new(35.0, 10.0, -10.0)).norm() < 0.01,
        "{t:?}"
    );
    assert_eq!(counters.protocol_obeyed.load(Ordering::Relaxed), 2);
    assert_eq!(counters.protocol_refused.load(Ordering::Relaxed), 4);
}

#[tokio::test(start_paused = true)]
async fn an_agent_without_a_coordinator_holds_its_steered_vehicles_after_1_5_s_then_lands_the_airborne_ones_4_s_later()
 {
    let bus = MemoryBus::new();
    let (process, mut calls) = Process::new(Some(origin_a()));
    let process = process
        .with_vehicle(
            "uav-1",
            VehicleState::InFormation,
            Ned::new(0.0, 0.0, -10.0),
        )
        .with_vehicle("uav-2", VehicleState::GoTo, Ned::new(10.0, 0.0, -10.0))
        .with_vehicle("uav-3", VehicleState::Hovering, Ned::new(20.0, 0.0, -10.0))
        .with_vehicle("uav-4", VehicleState::Landed, Ned::new(30.0, 0.0, 0.0));
    let (_, _agent) = start_agent(&bus, &process, config(LostAction::Land)).await;
    // gcs-a is active for 3 s, at its lease period, then falls silent.
    let leases = Peer::leases(&bus);
    let mut period = tokio::time::interval(Duration::from_millis(200));
    for _ in 0..15 {
        period.tick().await;
        leases.lease("gcs-a", 1, true);
    }
    let silent = tokio::time::Instant::now();
    assert!(handed(&mut calls, Duration::ZERO).await.is_empty());

    let (held, at) = commanded(
        &mut calls,
        2,
        &Command::Hold,
        Duration::from_secs(2),
        silent,
    )
    .await;
    assert_eq!(held, BTreeSet::from(["uav-1".into(), "uav-2".into()]));
    assert!(
        (1.5..1.6).contains(&at),
        "held {at:.2} s after the last lease"
    );

    let (landed, at) = commanded(
        &mut calls,
        3,
        &Command::Land,
        Duration::from_secs(5),
        silent,
    )
    .await;
    assert_eq!(
        landed,
        BTreeSet::from(["uav-1".into(), "uav-2".into(), "uav-3".into()])
    );
    assert!(
        (5.5..5.6).contains(&at),
        "landed {at:.2} s after the last lease"
    );
    let more = handed(&mut calls, Duration::from_secs(10)).await;
    assert!(more.is_empty(), "{more:?}");
}

#[tokio::test(start_paused = true)]
async fn an_agent_that_holds_obeys_a_coordinator_of_a_new_epoch_and_then_does_no_lost_action() {
    let bus = MemoryBus::new();
    let (process, mut calls) = uav_1_in_formation();
    let (counters, _agent) = start_agent(&bus, &process, config(LostAction::Land)).await;
    let leases = Arc::new(Peer::leases(&bus));
    leases.lease("gcs-a", 1, true);
    let start = tokio::time::Instant::now();
    commanded(&mut calls, 1, &Command::Hold, Duration::from_secs(2), start).await;

    // A standby claims the role in epoch 2 and keeps it.
    let l = leases.clone();
    let _gcs_b = tokio::spawn(async move {
        let mut period = tokio::time::interval(Duration::from_millis(200));
        loop {
            period.tick().await;
            l.lease("gcs-b", 2, true);
        }
    });
    tokio::task::yield_now().await;
    let targets = Peer::open(&bus, &topics::swarm_target());
    targets.send("uav-1", "gcs-a", 1, origin_a(), &slot(1.0));
    targets.send("uav-1", "gcs-b", 2, origin_a(), &slot(2.0));
    let got = handed(&mut calls, Duration::from_millis(500)).await;
    assert!(
        matches!(got.as_slice(), [(_, ToVehicle::Slot { target: Some(t) })] if t.position.north_m == 2.0),
        "{got:?}"
    );
    assert_eq!(counters.protocol_refused.load(Ordering::Relaxed), 1);
    // Past the lost action's time: gcs-b is there, so nothing lands.
    let more = handed(&mut calls, Duration::from_secs(6)).await;
    assert!(more.is_empty(), "{more:?}");
}

#[tokio::test(start_paused = true)]
async fn an_agent_gives_its_coordinator_the_other_agents_vehicles_as_neighbours_in_its_frame() {
    let bus = MemoryBus::new();
    let (a, mut a_calls) = Process::new(Some(origin_a()));
    let a = a.with_vehicle("uav-1", VehicleState::Hovering, Ned::new(0.0, 0.0, -10.0));
    let (b, _) = Process::new(Some(origin_b()));
    let b = b.with_vehicle("uav-2", VehicleState::Hovering, Ned::new(0.0, 0.0, -10.0));
    start_agent(&bus, &a, config(LostAction::Hold)).await;
    let other = Agent::open(
        bus.as_ref(),
        AgentConfig::new("agent-b".into()),
        &Default::default(),
    );
    tokio::spawn(agent::run(Arc::new(other.unwrap()), b));
    let (id, report) = a_calls
        .next(Duration::from_millis(100), "a neighbour", |c| match c {
            Call::Neighbour(id, r) => Some((id, r)),
            _ => None,
        })
        .await;
    assert_eq!(id, "uav-2");
    // B's origin is 30 m north and 10 m east of A's.
    let p = report.position.unwrap();
    assert!((p - Ned::new(30.0, 10.0, -10.0)).norm() < 0.01, "{p:?}");
}
