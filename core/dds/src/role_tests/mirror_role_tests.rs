//! The formation mirror ([`crate::mirror`]) and the failover it serves, with the
//! election ([`crate::lease`]) of two candidates.

use super::{Call, Calls, Peer, Process, origin_a, origin_b, since};
use crate::carrier::memory::MemoryBus;
use crate::counters::DdsCounters;
use crate::lease::{Candidate, ElectionLink};
use crate::mirror::{self, Mirror};
use crate::topics;
use skein_model::formation::Shape;
use skein_model::geo::Ned;
use skein_swarm::election::{CoordinatorRole, ElectionConfig, ElectionStatus, Lease};
use skein_swarm::formation::{
    FormationFrame, FormationMirror, FormationSpec, LeaderMotion, Reference,
};
use skein_swarm::protocol::wall_us;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::watch;
use tokio::task::JoinSet;

/// A wedge of three behind the virtual leader, its reference at `north_m` (the sender's
/// frame) flying north at 5 m/s to 100 m further.
fn wedge(north_m: f64) -> FormationMirror {
    FormationMirror {
        spec: FormationSpec {
            shape: Shape::Wedge,
            spacing_m: 6.0,
            leader: Some("virtual".into()),
            heading_deg: 0.0,
            altitude_m: Some(12.0),
            frame: FormationFrame::World,
            offsets: vec![],
            standoff_m: None,
        },
        reference: Reference {
            position: Ned::new(north_m, 0.0, -12.0),
            velocity: Ned::new(5.0, 0.0, 0.0),
            heading_rad: 0.0,
            heading_rate_rad_s: 0.0,
            motion: LeaderMotion::GoTo {
                target: Ned::new(north_m + 100.0, 0.0, -12.0),
                speed_m_s: 5.0,
            },
        },
        leader: None,
        pattern_heading_rad: None,
        assignment: BTreeMap::from([
            ("uav-1".into(), 0),
            ("uav-2".into(), 1),
            ("uav-3".into(), 2),
        ]),
        stamp_us: wall_us(),
    }
}

/// The status of candidate `id` in `role` and `epoch`.
pub(super) fn status(id: &str, role: CoordinatorRole, epoch: u64) -> ElectionStatus {
    let this = Lease {
        coordinator_id: id.into(),
        priority: 1,
        epoch,
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

/// The next formation `process` was told to resume, and from whom.
async fn resumed(calls: &mut Calls, within: Duration) -> (FormationMirror, String) {
    calls
        .next(within, "resumed formation", |c| match c {
            Call::Resume(m, from) => Some((m, from)),
            _ => None,
        })
        .await
}

/// Asserts `m` is `wedge(north_m)` of A's frame, seen from B's (30 m north and 10 m east
/// of A's origin).
fn assert_in_b_frame(m: &FormationMirror, north_m: f64) {
    let expected = wedge(north_m);
    assert!(
        (m.reference.position - Ned::new(north_m - 30.0, -10.0, -12.0)).norm() < 0.01,
        "{:?}",
        m.reference
    );
    let LeaderMotion::GoTo { target, .. } = m.reference.motion else {
        panic!("{:?}", m.reference.motion);
    };
    assert!(
        (target - Ned::new(north_m + 70.0, -10.0, -12.0)).norm() < 0.01,
        "{target:?}"
    );
    assert_eq!(
        (&m.spec, &m.assignment),
        (&expected.spec, &expected.assignment)
    );
    assert_eq!(m.reference.velocity, expected.reference.velocity);
}

#[tokio::test(start_paused = true)]
async fn a_standby_resumes_the_latest_mirror_of_the_highest_epoch_in_its_own_frame_once_active() {
    let bus = MemoryBus::new();
    let (b, mut calls) = Process::new(Some(origin_b()));
    let mirror = Arc::new(
        Mirror::<FormationMirror>::open(bus.as_ref(), &Arc::new(DdsCounters::default())).unwrap(),
    );
    let (role, election) = watch::channel(status("gcs-b", CoordinatorRole::Standby, 1));
    let _b = tokio::spawn(mirror::run(mirror, election, b.clone()));
    let formation = Peer::open(&bus, &topics::formation());
    // Farther apart than the mirror's period: the standby reads each one (the topic keeps
    // one sample).
    let mut period = tokio::time::interval(Duration::from_millis(300));
    for (from, epoch, north_m) in [("gcs-a", 3, 0.0), ("gcs-a", 3, 5.0), ("gcs-x", 2, 50.0)] {
        period.tick().await;
        formation.send("", from, epoch, origin_a(), &Some(wedge(north_m)));
    }
    // A standby flies nothing it heard.
    assert!(calls.within(Duration::from_secs(1), Some).await.is_none());

    role.send_replace(status("gcs-b", CoordinatorRole::Active, 4));
    let (m, from) = resumed(&mut calls, Duration::from_millis(250)).await;
    assert_eq!(from, "gcs-a");
    assert_in_b_frame(&m, 5.0);
}

/// Candidate `id` of `priority` in `process`: its election and its mirror, running.
fn candidate(bus: &Arc<MemoryBus>, process: &Arc<Process>, id: &str, priority: u32) -> JoinSet<()> {
    let counters = Arc::new(DdsCounters::default());
    let c = Candidate {
        coordinator_id: id.into(),
        priority,
        api_url: format!("http://{id}"),
        timing: ElectionConfig::default(),
    };
    let election = Arc::new(ElectionLink::open(bus.as_ref(), c, &counters).unwrap());
    let mirror = Arc::new(Mirror::<FormationMirror>::open(bus.as_ref(), &counters).unwrap());
    let mut tasks = JoinSet::new();
    tasks.spawn(mirror::run(mirror, election.subscribe(), process.clone()));
    tasks.spawn(election.run(process.clone()));
    tasks
}

/// The epoch in which `process`'s candidate next takes the role.
async fn claimed(calls: &mut Calls, within: Duration) -> u64 {
    calls
        .next(within, "claim", |c| match c {
            Call::RoleChanged(r) if r.role == CoordinatorRole::Active => Some(r.epoch),
            Call::RoleChanged(r) => panic!("{r:?}"),
            _ => None,
        })
        .await
}

#[tokio::test(start_paused = true)]
async fn a_standby_takes_over_within_1_25_s_of_the_active_ones_silence_and_flies_its_formation_on()
{
    let bus = MemoryBus::new();
    let (a, mut a_calls) = Process::new(Some(origin_a()));
    let (b, mut b_calls) = Process::new(Some(origin_b()));
    a.flying(wedge(5.0));
    let mut gcs_a = candidate(&bus, &a, "gcs-a", 2);
    let _gcs_b = candidate(&bus, &b, "gcs-b", 1);
    assert_eq!(claimed(&mut a_calls, Duration::from_secs(2)).await, 1);
    // gcs-a flies for 2 s; gcs-b stays a standby and resumes nothing.
    let quiet = b_calls.within(Duration::from_secs(2), Some).await;
    assert!(quiet.is_none(), "{quiet:?}");

    let killed = tokio::time::Instant::now();
    gcs_a.abort_all();
    assert_eq!(claimed(&mut b_calls, Duration::from_secs(2)).await, 2);
    let at = since(killed);
    assert!(
        (0.8..1.25).contains(&at),
        "gcs-b active {at:.2} s after gcs-a fell silent"
    );
    let (m, from) = resumed(&mut b_calls, Duration::from_millis(250)).await;
    assert_eq!(from, "gcs-a");
    assert_in_b_frame(&m, 5.0);
}

/// A coordinator that hands the role over while the mirror asks it for its formation:
/// it flies `wedge(5.0)` for its first three answers; at the fourth the step-down has
/// landed first (the status says standby, the formation is let go: `null`).
struct HandingOver {
    process: Arc<Process>,
    role: watch::Sender<ElectionStatus>,
    asks: std::sync::atomic::AtomicUsize,
}

impl crate::reframe::FrameSource for HandingOver {
    async fn swarm_frame(&self) -> Option<Arc<dyn crate::reframe::SwarmFrame>> {
        self.process.swarm_frame().await
    }
}

impl mirror::MirrorContext<FormationMirror> for HandingOver {
    async fn current(&self) -> Option<Option<FormationMirror>> {
        if self.asks.fetch_add(1, std::sync::atomic::Ordering::SeqCst) < 3 {
            return Some(Some(wedge(5.0)));
        }
        self.role
            .send_replace(status("gcs-b", CoordinatorRole::Standby, 3));
        Some(None)
    }

    fn resume(&self, mirror: FormationMirror, from: String) {
        mirror::MirrorContext::resume(self.process.as_ref(), mirror, from);
    }
}

#[tokio::test(start_paused = true)]
async fn a_coordinator_that_steps_down_during_an_ask_publishes_no_null_mirror_for_its_successor() {
    let bus = MemoryBus::new();
    let counters = Arc::new(DdsCounters::default());
    let (b, _b_calls) = Process::new(Some(origin_a()));
    let (role, b_election) = watch::channel(status("gcs-b", CoordinatorRole::Active, 3));
    let handing_over = Arc::new(HandingOver {
        process: b,
        role,
        asks: Default::default(),
    });
    let b_mirror = Arc::new(Mirror::<FormationMirror>::open(bus.as_ref(), &counters).unwrap());
    let _b = tokio::spawn(mirror::run(b_mirror, b_election, handing_over.clone()));
    let (a, mut a_calls) = Process::new(Some(origin_b()));
    let a_mirror = Arc::new(Mirror::<FormationMirror>::open(bus.as_ref(), &counters).unwrap());
    let (a_role, a_election) = watch::channel(status("gcs-a", CoordinatorRole::Standby, 3));
    let _a = tokio::spawn(mirror::run(a_mirror, a_election, a));

    // gcs-b has stepped down (its fourth ask) and gcs-a has heard all there was to hear.
    tokio::time::sleep(Duration::from_secs(2)).await;
    assert!(handing_over.asks.load(std::sync::atomic::Ordering::SeqCst) >= 4);
    a_role.send_replace(status("gcs-a", CoordinatorRole::Active, 4));
    let (m, from) = resumed(&mut a_calls, Duration::from_millis(250)).await;
    assert_eq!(from, "gcs-b");
    assert_in_b_frame(&m, 5.0);
}

/// An election context that records whether the status already showed each change.
struct StatusFirst {
    status: std::sync::OnceLock<watch::Receiver<ElectionStatus>>,
    seen: std::sync::Mutex<Vec<(CoordinatorRole, CoordinatorRole)>>,
}

impl crate::lease::ElectionContext for StatusFirst {
    fn role_changed(&self, change: crate::lease::RoleChange) {
        let shown = self.status.get().expect("subscribed").borrow().role;
        self.seen.lock().unwrap().push((change.role, shown));
    }
}

#[tokio::test(start_paused = true)]
async fn the_election_status_shows_a_change_of_role_before_the_coordinator_hears_of_it() {
    let bus = MemoryBus::new();
    let c = Candidate {
        coordinator_id: "gcs-b".into(),
        priority: 1,
        api_url: String::new(),
        timing: ElectionConfig::default(),
    };
    let election =
        Arc::new(ElectionLink::open(bus.as_ref(), c, &Arc::new(DdsCounters::default())).unwrap());
    let ctx = Arc::new(StatusFirst {
        status: std::sync::OnceLock::new(),
        seen: Default::default(),
    });
    ctx.status.set(election.subscribe()).unwrap();
    let _run = tokio::spawn(election.run(ctx.clone()));
    // gcs-b claims the role alone, then gcs-x holds it in a higher epoch: it steps down.
    tokio::time::sleep(Duration::from_secs(3)).await;
    let leases = Peer::leases(&bus);
    let mut period = tokio::time::interval(Duration::from_millis(200));
    for _ in 0..5 {
        period.tick().await;
        leases.lease("gcs-x", 9, true);
    }
    let seen = ctx.seen.lock().unwrap().clone();
    assert_eq!(
        seen,
        vec![
            (CoordinatorRole::Active, CoordinatorRole::Active),
            (CoordinatorRole::Standby, CoordinatorRole::Standby)
        ]
    );
}
