//! The mission mirror ([`crate::mirror`] on `/skein/mission`): a standby keeps the
//! active coordinator's flying mission and, once it holds the role, flies it on in its
//! own frame and clock.

use super::mirror_role_tests::status;
use super::{Call, Calls, Peer, Process, origin_a, origin_b};
use crate::carrier::memory::MemoryBus;
use crate::counters::DdsCounters;
use crate::mirror::{self, Mirror};
use crate::topics;
use skein_mission::{MissionPlan, MissionRun};
use skein_swarm::coordinator::missions::MissionMirror;
use skein_swarm::election::CoordinatorRole;
use skein_swarm::protocol::wall_us;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::watch;

/// Mission `m-4` of A's frame: a survey of a 60 x 60 m square 20 m north of A's origin,
/// running.
fn survey() -> MissionMirror {
    let plan: MissionPlan = serde_json::from_value(serde_json::json!({
        "name": "square",
        "steps": [{"kind": "survey", "polygon": [[20, 0], [20, 60], [80, 60], [80, 0]],
                   "altitude_m": 15, "lane_spacing_m": 6}]
    }))
    .unwrap();
    let mut run = MissionRun::new(plan, vec![vec!["uav-1".into()]]);
    run.start();
    MissionMirror {
        id: "m-4".into(),
        run,
        stamp_us: wall_us(),
    }
}

/// The next mission `process` was told to resume, and from whom.
async fn resumed(calls: &mut Calls, within: Duration) -> (MissionMirror, String) {
    calls
        .next(within, "resumed mission", |c| match c {
            Call::ResumeMission(m, from) => Some((*m, from)),
            _ => None,
        })
        .await
}

#[tokio::test(start_paused = true)]
async fn a_standby_flies_the_mirrored_mission_on_in_its_own_frame_once_active() {
    let bus = MemoryBus::new();
    let counters = Arc::new(DdsCounters::default());
    let (b, mut calls) = Process::new(Some(origin_b()));
    let m = Arc::new(Mirror::<MissionMirror>::open(bus.as_ref(), &counters).unwrap());
    let (role, election) = watch::channel(status("gcs-b", CoordinatorRole::Standby, 1));
    let _b = tokio::spawn(mirror::run(m, election, b.clone()));
    // gcs-a flies the survey and mirrors it, active in epoch 3.
    let (a, _a_calls) = Process::new(Some(origin_a()));
    a.flying_mission(survey());
    let a_mirror = Arc::new(Mirror::<MissionMirror>::open(bus.as_ref(), &counters).unwrap());
    let (_a_role, a_election) = watch::channel(status("gcs-a", CoordinatorRole::Active, 3));
    let gcs_a = tokio::spawn(mirror::run(a_mirror, a_election, a));
    // A sample that is no mission is counted and dropped.
    let peer = Peer::open(&bus, &topics::mission());
    peer.send(
        "",
        "gcs-x",
        3,
        origin_a(),
        &serde_json::json!({"id": "m-4"}),
    );
    tokio::time::sleep(Duration::from_millis(1200)).await;
    assert!(
        counters
            .malformed
            .load(std::sync::atomic::Ordering::Relaxed)
            >= 1
    );
    // A standby flies nothing it heard.
    assert!(calls.within(Duration::from_secs(1), Some).await.is_none());

    gcs_a.abort();
    role.send_replace(status("gcs-b", CoordinatorRole::Active, 4));
    let (m, from) = resumed(&mut calls, Duration::from_millis(600)).await;
    assert_eq!((from.as_str(), m.id.as_str()), ("gcs-a", "m-4"));
    let skein_mission::plan::StepKind::Survey(s) = &m.run.plan().steps[0].kind else {
        panic!("a survey");
    };
    // B's origin is 30 m north and 10 m east of A's.
    let corner = s.polygon[0];
    assert!(
        (corner[0] + 10.0).abs() < 0.01 && (corner[1] + 10.0).abs() < 0.01,
        "{corner:?}"
    );
    assert_eq!(m.run.status().state, skein_mission::RunState::Running);
}
