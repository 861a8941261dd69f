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

/// An agent that does `lost_action` 4 s after holding, and does not ride through (the
/// ride-through has its own scenario, in real time: it runs on the wall clock of the
/// targets' stamps).
fn config(lost_action: LostAction) -> AgentConfig {
    AgentConfig {
        lost_action_after: Duration::from_secs(4),
        lost_action,
        ride_through: Duration::ZERO,
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
async fn an_agent_without_a_coordinator_holds_its_steered_vehicles_1_5_s_after_the_next_lease_was_due_then_lands_the_airborne_ones_4_s_later()
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
    let silent = leases.lease_then_fall_silent("gcs-a", 1, 15).await;
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
    // The next lease was due 0.2 s after the last: a cut of under 1.5 s never holds.
    assert!(
        (1.7..1.8).contains(&at),
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
        (5.7..5.8).contains(&at),
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

/// In real time (the ride runs on the wall clock the targets are stamped with): gcs-a
/// flies a wedge north at 5 m/s and falls silent. The agent flies uav-1 on its slot from
/// the mirror, 10 Hz or more, the targets moving north at 5 m/s from where the last one
/// was, for the ride-through (1 s) after its last target; it holds 1 s after the next
/// lease was due (the ride-through is longer than its 0.5 s timeout), and no sooner.
#[tokio::test]
async fn an_agent_whose_coordinator_falls_silent_rides_its_vehicle_on_its_slot_then_holds() {
    use skein_swarm::formation::{FormationMirror, FormationSpec, LeaderMotion, Reference};
    use skein_swarm::protocol::wall_us;
    let bus = MemoryBus::new();
    let (process, mut calls) = uav_1_in_formation();
    let cfg = AgentConfig {
        coordinator_timeout: Duration::from_millis(500),
        ride_through: Duration::from_secs(1),
        lost_action_after: Duration::from_secs(60),
        ..AgentConfig::new("agent-a".into())
    };
    let (_, _agent) = start_agent(&bus, &process, cfg).await;
    let leases = Peer::leases(&bus);
    let (mirror, targets) = (
        Peer::open(&bus, &topics::formation()),
        Peer::open(&bus, &topics::swarm_target()),
    );
    let spec: FormationSpec = serde_json::from_value(serde_json::json!({
        "shape": "wedge", "spacing_m": 6.0, "leader": "virtual", "altitude_m": 10.0,
        "heading_deg": 0.0, "frame": "leader", "offsets": []
    }))
    .unwrap();
    // The reference 4.24 m ahead of uav-1's slot (its first rank), cruising north.
    let reference_at = |t0: u64, now: u64| {
        let dt = now.saturating_sub(t0) as f64 / 1e6;
        Ned::new(4.24 + 5.0 * dt, 4.24, -10.0)
    };
    let t0 = wall_us();
    let mut period = tokio::time::interval(Duration::from_millis(100));
    let mut last = Ned::ZERO;
    for _ in 0..5 {
        period.tick().await;
        let now = wall_us();
        leases.lease("gcs-a", 1, true);
        let r = reference_at(t0, now);
        let m = FormationMirror {
            spec: spec.clone(),
            reference: Reference {
                position: r,
                velocity: Ned::new(5.0, 0.0, 0.0),
                heading_rad: 0.0,
                heading_rate_rad_s: 0.0,
                motion: LeaderMotion::GoTo {
                    target: Ned::new(500.0, 4.24, -10.0),
                    speed_m_s: 5.0,
                },
            },
            leader: None,
            pattern_heading_rad: Some(0.0),
            assignment: [("uav-1".to_string(), 1)].into_iter().collect(),
            stamp_us: now,
        };
        mirror.send("", "gcs-a", 1, origin_a(), &Some(m));
        last = Ned::new(r.north_m - 4.24, 0.0, -10.0);
        let target = ToVehicle::Slot {
            target: Some(SlotTarget {
                slot: 1,
                leader: false,
                position: last,
                goal: last,
                velocity: Ned::new(5.0, 0.0, 0.0),
                yaw_rad: 0.0,
                stamp_us: now,
            }),
        };
        targets.send("uav-1", "gcs-a", 1, origin_a(), &target);
    }
    let silent = std::time::Instant::now();
    let silent_us = wall_us();
    // What the agent hands uav-1 from now on: the obeyed targets first, then its own.
    let mut rides = Vec::new();
    let held = loop {
        let c = calls
            .next(
                Duration::from_secs(3),
                "a ride target or a hold",
                |c| match c {
                    Call::ToVehicle(_, msg) => Some(msg),
                    _ => None,
                },
            )
            .await;
        match c {
            ToVehicle::Slot {
                target: Some(t), ..
            } if t.stamp_us > silent_us => rides.push(t),
            ToVehicle::Command {
                command: Command::Hold,
                ..
            } => break silent.elapsed(),
            _ => {}
        }
    };
    assert!(rides.len() >= 6, "{} ride targets: {rides:?}", rides.len());
    for t in &rides {
        let flown_s = t.stamp_us.saturating_sub(silent_us) as f64 / 1e6;
        let expected = last.north_m + 5.0 * flown_s;
        assert!(
            (t.position.north_m - expected).abs() < 0.3 && t.position.east_m.abs() < 0.01,
            "{t:?}: expected {expected:.2} m north"
        );
        assert!((t.velocity.north_m - 5.0).abs() < 0.01);
        // Within the ride-through after its last target.
        assert!(flown_s < 1.0 + 0.1, "{t:?}");
    }
    let hold_s = held.as_secs_f64();
    assert!(
        (1.1..1.6).contains(&hold_s),
        "held {hold_s:.2} s after the last lease"
    );
}

#[tokio::test(start_paused = true)]
async fn an_agent_that_joins_the_domain_again_keeps_its_coordinators_silence_and_epoch() {
    let (process, mut calls) = uav_1_in_formation();
    let old_bus = MemoryBus::new();
    let counters = Arc::new(DdsCounters::default());
    let old = Arc::new(Agent::open(old_bus.as_ref(), config(LostAction::Hold), &counters).unwrap());
    let old_task = tokio::spawn(agent::run(old.clone(), process.clone()));
    let silent = Peer::leases(&old_bus)
        .lease_then_fall_silent("gcs-a", 3, 5)
        .await;
    // 1 s into the silence (virtual time: the scenario's clock, not a wait for anything)
    // the network interfaces change: a new participant (a new bus here), the old agent's
    // tasks stopped, what it knew carried over.
    tokio::time::sleep(Duration::from_secs(1)).await;
    old_task.abort();
    let _ = old_task.await;
    let bus = MemoryBus::new();
    let new = Arc::new(Agent::open(bus.as_ref(), config(LostAction::Hold), &counters).unwrap());
    new.carry_over(&old);
    let _new_task = tokio::spawn(agent::run(new, process.clone()));
    // The hold comes when it would have without the rejoin, not 1 s later.
    let (held, at) = commanded(
        &mut calls,
        1,
        &Command::Hold,
        Duration::from_secs(2),
        silent,
    )
    .await;
    assert_eq!(held, BTreeSet::from(["uav-1".into()]));
    assert!(
        (1.7..1.8).contains(&at),
        "held {at:.2} s after the last lease"
    );
    // A coordinator of an older epoch, heard first on the new participant, is not obeyed.
    Peer::leases(&bus).lease("gcs-old", 2, true);
    Peer::open(&bus, &topics::swarm_target()).send("uav-1", "gcs-old", 2, origin_a(), &slot(1.0));
    let more = handed(&mut calls, Duration::from_millis(500)).await;
    assert!(more.is_empty(), "{more:?}");
}
