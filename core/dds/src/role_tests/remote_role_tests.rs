//! A coordinator's remote vehicles ([`crate::remote`]), with a real agent
//! ([`crate::agent`]) or the test playing one.

use super::{Call, Calls, Peer, Process, origin_a, origin_b, report, snapshot};
use crate::agent::{self, Agent, AgentConfig};
use crate::carrier::WriterIdentity;
use crate::carrier::memory::MemoryBus;
use crate::counters::DdsCounters;
use crate::envelope::ReportBody;
use crate::remote::{self, RemoteJoin, Remotes};
use crate::topics;
use skein_model::fsm::VehicleState;
use skein_model::geo::{Ned, NedFrame};
use skein_swarm::SwarmEvent;
use skein_swarm::coordinator::VehicleProxy;
use skein_swarm::election::{CoordinatorRole, ElectionStatus, Lease};
use skein_swarm::protocol::{FromVehicle, SlotTarget, ToVehicle, wall_us};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;
use tokio::sync::watch;

/// This coordinator's status: `gcs-a` in `role`, epoch 1.
fn status(role: CoordinatorRole) -> ElectionStatus {
    let this = Lease {
        coordinator_id: "gcs-a".into(),
        priority: 1,
        epoch: 1,
        active: role == CoordinatorRole::Active,
        api_url: String::new(),
    };
    ElectionStatus {
        active: (role == CoordinatorRole::Active).then(|| this.clone()),
        this,
        role,
        peers: vec![],
    }
}

/// Starts the remote vehicles of coordinator process `c` on `bus`; `role` sets its
/// election status.
fn start_remotes(
    bus: &Arc<MemoryBus>,
    c: &Arc<Process>,
) -> (Arc<DdsCounters>, watch::Sender<ElectionStatus>) {
    let counters = Arc::new(DdsCounters::default());
    let remotes = Arc::new(Remotes::open(bus.as_ref(), &counters).unwrap());
    let (role, election) = watch::channel(status(CoordinatorRole::Standby));
    tokio::spawn(remote::run(remotes, election, c.clone()));
    (counters, role)
}

/// Waits for the next report of a remote vehicle.
async fn changed(reports: &mut watch::Receiver<skein_swarm::protocol::VehicleReport>) {
    tokio::time::timeout(Duration::from_millis(100), reports.changed())
        .await
        .expect("a new report")
        .unwrap();
}

async fn joined(calls: &mut Calls, within: Duration) -> Option<RemoteJoin> {
    calls
        .within(within, |c| match c {
            Call::Joined(j) => Some(j),
            _ => None,
        })
        .await
}

#[tokio::test(start_paused = true)]
async fn a_remote_vehicle_joins_with_its_first_report_goes_lost_when_its_reports_age_past_2_s_and_rejoins()
 {
    let bus = MemoryBus::new();
    // A coordinator without vehicles: it anchors at the first agent's origin.
    let (c, mut calls) = Process::new(None);
    let (counters, _role) = start_remotes(&bus, &c);
    let agent = Peer::open(&bus, &topics::swarm_report());
    let frame = NedFrame::new(origin_b());
    let p = Ned::new(5.0, 0.0, -10.0);
    // The agent's report of uav-1, made `age_s` ago by its wall clock.
    let report_of = |state, age_s: f64| ReportBody {
        report: skein_swarm::protocol::VehicleReport {
            stamp_us: wall_us() - (age_s * 1e6) as u64,
            ..report(state, p)
        },
        snapshot: snapshot("uav-1", state, p, frame),
    };
    agent.send("uav-1", "agent-a", 0, origin_b(), &"not a report");
    assert!(joined(&mut calls, Duration::from_secs(1)).await.is_none());
    assert_eq!(counters.malformed.load(Ordering::Relaxed), 1);

    agent.send(
        "uav-1",
        "agent-a",
        0,
        origin_b(),
        &report_of(VehicleState::Hovering, 0.0),
    );
    let join = joined(&mut calls, Duration::from_millis(100))
        .await
        .expect("uav-1 joins");
    assert_eq!(
        (join.id.as_str(), join.agent.as_str()),
        ("uav-1", "agent-a")
    );
    assert_eq!(c.frame(), Some(frame));
    let mut reports = join.reports.clone();
    let proxy = VehicleProxy::remote(join.port, join.snapshots, join.reports);
    assert_eq!(proxy.state(), VehicleState::Hovering);
    assert!((proxy.position().unwrap() - p).norm() < 0.01);

    // Its agent falls silent: what the coordinator holds is a report 2.5 s old (stamped
    // here, as the wall clock does not pause).
    agent.send(
        "uav-1",
        "agent-a",
        0,
        origin_b(),
        &report_of(VehicleState::Hovering, 2.5),
    );
    changed(&mut reports).await;
    assert_eq!(proxy.state(), VehicleState::Lost);
    assert!(!proxy.snapshot().link.connected);

    agent.send(
        "uav-1",
        "agent-a",
        0,
        origin_b(),
        &report_of(VehicleState::InFormation, 0.0),
    );
    changed(&mut reports).await;
    assert_eq!(proxy.state(), VehicleState::InFormation);
    assert!(proxy.snapshot().link.connected);
    let again = joined(&mut calls, Duration::from_secs(1)).await;
    assert!(again.is_none(), "{again:?}");
}

/// A coordinator (frame A, remote vehicles) and agent `agent-b` (frame B, uav-1) on one
/// bus, the agent hearing `gcs-a`'s lease; returns uav-1 as it joined the coordinator.
async fn coordinator_and_agent(
    bus: &Arc<MemoryBus>,
) -> (
    watch::Sender<ElectionStatus>,
    RemoteJoin,
    Calls,
    Arc<Process>,
    Calls,
) {
    let (c, mut c_calls) = Process::new(Some(origin_a()));
    let (_, role) = start_remotes(bus, &c);
    let (a, a_calls) = Process::new(Some(origin_b()));
    let a = a.with_vehicle("uav-1", VehicleState::Hovering, Ned::new(0.0, 0.0, -10.0));
    let counters = Arc::new(DdsCounters::default());
    let agent =
        Arc::new(Agent::open(bus.as_ref(), AgentConfig::new("agent-b".into()), &counters).unwrap());
    tokio::spawn(agent::run(agent, a.clone()));
    Peer::leases(bus).lease("gcs-a", 1, true);
    let join = joined(&mut c_calls, Duration::from_secs(1))
        .await
        .expect("uav-1 joins");
    (role, join, c_calls, a, a_calls)
}

#[tokio::test(start_paused = true)]
async fn only_the_active_coordinators_port_reaches_the_agent_in_its_own_frame() {
    let bus = MemoryBus::new();
    let (role, join, _, _, mut a_calls) = coordinator_and_agent(&bus).await;
    let p = Ned::new(5.0, 0.0, -10.0);
    let slot = ToVehicle::Slot {
        target: Some(SlotTarget {
            slot: 0,
            leader: true,
            position: p,
            goal: p,
            velocity: Ned::ZERO,
            yaw_rad: 0.0,
            stamp_us: 1,
        }),
    };
    let refused = join.port.send(slot.clone()).unwrap_err();
    assert!(refused.contains("standby"), "{refused}");

    role.send_replace(status(CoordinatorRole::Active));
    join.port.send(slot).unwrap();
    let (id, msg) = a_calls
        .next(Duration::from_millis(100), "the slot", |c| match c {
            Call::ToVehicle(id, msg) => Some((id, msg)),
            _ => None,
        })
        .await;
    let ToVehicle::Slot { target: Some(t) } = msg else {
        panic!("{msg:?}");
    };
    assert_eq!(id, "uav-1");
    // 5 m north of A's origin is 25 m south and 10 m west of B's.
    assert!(
        (t.position - Ned::new(-25.0, -10.0, -10.0)).norm() < 0.01,
        "{t:?}"
    );
}

#[tokio::test(start_paused = true)]
async fn an_agents_vehicle_answers_and_events_reach_the_coordinator() {
    let bus = MemoryBus::new();
    let (_role, _join, mut c_calls, a, _) = coordinator_and_agent(&bus).await;
    // Not a vehicle of the coordinator: dropped there.
    a.emit(SwarmEvent::LinkLost { id: "uav-7".into() });
    a.emit(SwarmEvent::LinkLost { id: "uav-1".into() });
    a.answer(FromVehicle::CommandAck {
        id: "uav-1".into(),
        command_id: 9,
        result: Ok(()),
    });
    let (mut ev, mut ack) = (None, None);
    while ev.is_none() || ack.is_none() {
        match c_calls
            .next(
                Duration::from_millis(100),
                "an event and an answer",
                |c| match c {
                    Call::Event(_) | Call::Answer(_) => Some(c),
                    _ => None,
                },
            )
            .await
        {
            Call::Event(e) => assert!(ev.replace(e).is_none(), "two events"),
            Call::Answer(a) => assert!(ack.replace(a).is_none(), "two answers"),
            _ => unreachable!(),
        }
    }
    assert!(
        matches!(&ev, Some(SwarmEvent::LinkLost { id }) if id == "uav-1"),
        "{ev:?}"
    );
    assert!(
        matches!(&ack, Some(FromVehicle::CommandAck { id, command_id: 9, .. }) if id == "uav-1"),
        "{ack:?}"
    );
    let more = c_calls.within(Duration::from_secs(1), Some).await;
    assert!(more.is_none(), "{more:?}");
}

#[tokio::test(start_paused = true)]
async fn under_dds_security_only_the_enclave_that_first_reported_a_vehicle_speaks_for_it() {
    let bus = MemoryBus::new();
    let (c, mut calls) = Process::new(Some(origin_a()));
    let (counters, _role) = start_remotes(&bus, &c);
    let (a1, a2) = (WriterIdentity([1; 6]), WriterIdentity([2; 6]));
    let owner = Peer::open_as(&bus, &topics::swarm_report(), a1);
    let forger = Peer::open_as(&bus, &topics::swarm_report(), a2);
    let frame = NedFrame::new(origin_a());
    let body = |p: Ned| ReportBody {
        report: report(VehicleState::Hovering, p),
        snapshot: snapshot("uav-1", VehicleState::Hovering, p, frame),
    };
    let p = Ned::new(5.0, 0.0, -10.0);
    owner.send("uav-1", "agent-1", 0, origin_a(), &body(p));
    let join = joined(&mut calls, Duration::from_millis(100))
        .await
        .expect("uav-1 joins");
    let proxy = VehicleProxy::remote(join.port, join.snapshots, join.reports.clone());

    // Another enrolled agent reports uav-1 somewhere else, then answers and emits for
    // it: none of it reaches the coordinator.
    forger.send(
        "uav-1",
        "agent-2",
        0,
        origin_a(),
        &body(Ned::new(50.0, 0.0, -10.0)),
    );
    Peer::open_as(&bus, &topics::swarm_events(), a2).send(
        "uav-1",
        "agent-2",
        0,
        origin_a(),
        &SwarmEvent::LinkLost { id: "uav-1".into() },
    );
    Peer::open_as(&bus, &topics::swarm_command_result(), a2).send(
        "uav-1",
        "agent-2",
        0,
        origin_a(),
        &FromVehicle::CommandAck {
            id: "uav-1".into(),
            command_id: 3,
            result: Ok(()),
        },
    );
    let heard = calls.within(Duration::from_secs(1), Some).await;
    assert!(heard.is_none(), "{heard:?}");
    assert!((proxy.position().unwrap() - p).norm() < 0.01);
    assert_eq!(counters.protocol_forged.load(Ordering::Relaxed), 3);

    // The owner's next report and event are read as before; a vehicle first reported
    // by the other agent is its own.
    let q = Ned::new(6.0, 0.0, -10.0);
    let mut reports = join.reports;
    owner.send("uav-1", "agent-1", 0, origin_a(), &body(q));
    changed(&mut reports).await;
    assert!((proxy.position().unwrap() - q).norm() < 0.01);
    forger.send(
        "uav-2",
        "agent-2",
        0,
        origin_a(),
        &ReportBody {
            report: report(VehicleState::Hovering, q),
            snapshot: snapshot("uav-2", VehicleState::Hovering, q, frame),
        },
    );
    let join2 = joined(&mut calls, Duration::from_millis(100))
        .await
        .expect("uav-2 joins");
    assert_eq!(join2.agent, "agent-2");
    assert_eq!(counters.protocol_forged.load(Ordering::Relaxed), 3);
}
