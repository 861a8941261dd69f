//! DDS Security on real RustDDS participants over loopback: enclaves made by
//! `skein_dds::security::keystore` let a coordinator and an agent talk (targets, swarm
//! commands, reports; a lease from an unenrolled coordinator: `tests/e2e_dds_security.rs`); a participant
//! without a certificate, or with one from another keystore's CA, neither reaches them
//! nor reads them, and each is counted as refused; a viewer reads targets and poses; an expired enclave does
//! not join; a role's permissions refuse a writer its role does not grant (an agent's of
//! RTK corrections too, which it may read).

use ros2_client::builtin_interfaces::Time;
use skein_dds::carrier::ros2::Ros2Carrier;
use skein_dds::carrier::{Carrier, Reader, Writer};
use skein_dds::envelope::Envelope;
use skein_dds::msgs::{Header, Point, Pose, PoseStamped, Quaternion, RtcmMessage, SwarmMessage};
use skein_dds::security::keystore::{Validity, create_enclave, create_keystore};
use skein_dds::security::refusals::{self, Reason};
use skein_dds::security::{DdsSecurity, Role, identity_of};
use skein_dds::topics::{self, TopicSpec};
use std::net::{IpAddr, Ipv4Addr};
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

const LOOPBACK: [IpAddr; 1] = [IpAddr::V4(Ipv4Addr::LOCALHOST)];

/// A domain of this test process alone (other tests' participants may share the host).
fn domain() -> u16 {
    u16::try_from(150 + std::process::id() % 80).unwrap()
}

fn enclave(keystore: &Path, name: &str, role: Role, validity: Validity) -> DdsSecurity {
    create_enclave(keystore, name, role, validity).unwrap();
    DdsSecurity::new(keystore, name).unwrap()
}

fn join(name: &str, security: Option<&DdsSecurity>) -> Ros2Carrier {
    Ros2Carrier::join(domain(), &LOOPBACK, name, security)
        .unwrap_or_else(|e| panic!("{name} joins: {e}"))
}

/// A pose 10 m up, level.
fn a_pose() -> PoseStamped {
    PoseStamped {
        header: Header {
            stamp: Time::ZERO,
            frame_id: skein_dds::FRAME_ID.into(),
        },
        pose: Pose {
            position: Point {
                x: 1.0,
                y: 2.0,
                z: 10.0,
            },
            orientation: Quaternion {
                x: 0.0,
                y: 0.0,
                z: 0.0,
                w: 1.0,
            },
        },
    }
}

fn message(sender: &str, n: u64) -> SwarmMessage {
    Envelope::message("uav-1", sender, n, None, &serde_json::json!({ "n": n })).unwrap()
}

/// Senders of the samples `reader` holds now.
fn drain(reader: &Arc<dyn Reader<SwarmMessage>>, into: &mut Vec<String>) {
    while let Ok(Some(m)) = reader.try_take() {
        into.push(m.sender_id);
    }
}

struct Peer {
    name: &'static str,
    writer: Arc<dyn Writer<SwarmMessage>>,
}

/// Every `peers` writes on its topic each 50 ms until `done(heard)` holds for what
/// `reader` heard (its senders), or `limit` passes; returns what it heard.
fn exchange(
    peers: &[&Peer],
    reader: &Arc<dyn Reader<SwarmMessage>>,
    limit: Duration,
    done: impl Fn(&[String]) -> bool,
) -> Vec<String> {
    let start = Instant::now();
    let mut heard = Vec::new();
    let mut n = 0;
    while start.elapsed() < limit && !done(&heard) {
        n += 1;
        for p in peers {
            p.writer.write(message(p.name, n)).unwrap();
        }
        std::thread::sleep(Duration::from_millis(50));
        drain(reader, &mut heard);
    }
    heard
}

/// `enrolled` and `outsider` both write until `reader` has heard 20 samples of
/// `enrolled`'s, then for one more second; asserts that it heard none of `outsider`'s.
fn heard_only_enrolled(enrolled: &Peer, outsider: &Peer, reader: &Arc<dyn Reader<SwarmMessage>>) {
    let peers = [enrolled, outsider];
    let heard = exchange(&peers, reader, Duration::from_secs(30), |h| {
        count(h, enrolled.name) >= 20
    });
    assert!(
        count(&heard, enrolled.name) >= 20,
        "{} was heard: {heard:?}",
        enrolled.name
    );
    let more = exchange(&peers, reader, Duration::from_secs(1), |_| false);
    let heard = [heard, more].concat();
    assert_eq!(
        count(&heard, outsider.name),
        0,
        "{} was heard: {heard:?}",
        outsider.name
    );
}

fn count(heard: &[String], who: &str) -> usize {
    heard.iter().filter(|s| *s == who).count()
}

/// This process's refusals for `reason` (see `skein_dds::security::refusals`).
fn refusals_of(reason: Reason) -> u64 {
    refusals::counts()
        .iter()
        .find(|(r, _)| *r == reason)
        .map_or(0, |(_, n)| *n)
}

/// Waits (10 s at most) until DDS Security has refused something for one of `reasons`.
fn assert_refused(reasons: &[Reason], who: &str) {
    let deadline = Instant::now() + Duration::from_secs(10);
    while reasons.iter().all(|r| refusals_of(*r) == 0) {
        assert!(
            Instant::now() < deadline,
            "{who} was not counted as refused for {reasons:?}: {:?}",
            refusals::counts()
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn enrolled_participants_talk_and_nobody_else_reaches_or_reads_them() {
    let dir = tempfile::tempdir().unwrap();
    let ks = dir.path().join("keystore");
    create_keystore(&ks, Validity::days(30)).unwrap();
    let coordinator = enclave(
        &ks,
        "/skein/coordinator/c1",
        Role::Coordinator,
        Validity::days(30),
    );
    let agent = enclave(&ks, "/skein/agent/a1", Role::Agent, Validity::days(30));
    let viewer = enclave(&ks, "/skein/viewer/v1", Role::Viewer, Validity::days(30));
    // Another keystore's agent: a valid certificate from a CA this swarm does not trust.
    let foreign_ks = dir.path().join("foreign");
    create_keystore(&foreign_ks, Validity::days(30)).unwrap();
    let foreign = enclave(
        &foreign_ks,
        "/skein/agent/a9",
        Role::Agent,
        Validity::days(30),
    );

    let c = join("c1", Some(&coordinator));
    let a = join("a1", Some(&agent));
    let v = join("v1", Some(&viewer));
    let f = join("f9", Some(&foreign));
    let x = join("intruder", None);

    // Targets: the coordinator's reach the agent; the intruder's never do, and the
    // intruder reads none of the coordinator's.
    let target = topics::swarm_target();
    let agent_targets = a.reader::<SwarmMessage>(&target).unwrap();
    let viewer_targets = v.reader::<SwarmMessage>(&target).unwrap();
    let intruder_targets = x.reader::<SwarmMessage>(&target).unwrap();
    // One writer each for the whole test: RustDDS 0.15 did not always match a writer
    // made anew on a topic after one was dropped (the viewer heard none of a second
    // coordinator writer's targets in 30 s, in two runs of three).
    let c_targets = Peer {
        name: "c1",
        writer: c.writer(&target).unwrap(),
    };
    heard_only_enrolled(
        &c_targets,
        &Peer {
            name: "intruder",
            writer: x.writer(&target).unwrap(),
        },
        &agent_targets,
    );
    let mut read_by_intruder = Vec::new();
    drain(&intruder_targets, &mut read_by_intruder);
    assert!(
        !read_by_intruder.contains(&"c1".to_string()),
        "the intruder read the coordinator's targets: {read_by_intruder:?}"
    );
    // Refused, and counted as such: a participant without DDS Security.
    assert_refused(&[Reason::Unauthenticated], "the intruder");
    // The viewer reads what the coordinator writes (its own handshakes may end later
    // than the agent's: the coordinator writes on until it hears, 30 s at most).
    let read_by_viewer = exchange(
        &[&c_targets],
        &viewer_targets,
        Duration::from_secs(30),
        |h| count(h, "c1") > 0,
    );
    assert!(
        count(&read_by_viewer, "c1") > 0,
        "the viewer read no target: {read_by_viewer:?} (refusals {:?})",
        refusals::counts()
    );
    // And an agent's vehicle's poses.
    let pose = topics::pose("uav-1");
    let viewer_poses = v.reader::<PoseStamped>(&pose).unwrap();
    let agent_poses = a.writer::<PoseStamped>(&pose).unwrap();
    let start = Instant::now();
    let mut poses = 0;
    while poses == 0 && start.elapsed() < Duration::from_secs(30) {
        agent_poses.write(a_pose()).unwrap();
        std::thread::sleep(Duration::from_millis(50));
        while let Ok(Some(p)) = viewer_poses.try_take() {
            assert_eq!(p, a_pose());
            poses += 1;
        }
    }
    assert!(poses > 0, "the viewer read no pose in 30 s");
    // Swarm commands likewise: the coordinator's reach the agent, the intruder's never.
    let command = topics::swarm_command();
    let agent_commands = a.reader::<SwarmMessage>(&command).unwrap();
    heard_only_enrolled(
        &Peer {
            name: "c1",
            writer: c.writer(&command).unwrap(),
        },
        &Peer {
            name: "intruder",
            writer: x.writer(&command).unwrap(),
        },
        &agent_commands,
    );

    // Reports: the enrolled agent's reach the coordinator; a foreign-CA agent's do not.
    let report = topics::swarm_report();
    let coordinator_reports = c.reader::<SwarmMessage>(&report).unwrap();
    let agent_reports = Peer {
        name: "a1",
        writer: a.writer(&report).unwrap(),
    };
    heard_only_enrolled(
        &agent_reports,
        &Peer {
            name: "f9",
            writer: f.writer(&report).unwrap(),
        },
        &coordinator_reports,
    );
    // Its certificate does not verify against the swarm's identity CA (nor the swarm's
    // against its own): the handshake is refused.
    assert_refused(&[Reason::Handshake], "the foreign CA's agent");
    // Each sample names its writer's enclave, as the enclave's certificate proves it.
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    agent_reports.writer.write(message("a1", 0)).unwrap();
    let (m, from) = rt
        .block_on(async {
            tokio::time::timeout(Duration::from_secs(10), coordinator_reports.take_next()).await
        })
        .expect("a report")
        .unwrap();
    assert_eq!(m.sender_id, "a1");
    assert_eq!(from, Some(identity_of("/skein/agent/a1").unwrap()));
    assert_ne!(from, Some(identity_of("/skein/agent/a9").unwrap()));

    // Permissions by role, refused where the writer is made.
    let refused =
        |carrier: &Ros2Carrier, spec: &TopicSpec| match carrier.writer::<SwarmMessage>(spec) {
            Ok(_) => panic!("a writer on {spec} was allowed"),
            Err(e) => e.to_string(),
        };
    let e = refused(&a, &topics::swarm_target());
    assert!(e.contains("not allowed"), "agent writing targets: {e}");
    let e = refused(&v, &topics::swarm_command());
    assert!(e.contains("not allowed"), "viewer writing commands: {e}");
    assert!(
        v.reader::<SwarmMessage>(&topics::swarm_target()).is_ok(),
        "viewers read"
    );
    // RTK corrections: the coordinator writes them, an agent only reads them.
    let rtcm = topics::rtcm();
    match a.writer::<RtcmMessage>(&rtcm) {
        Ok(_) => panic!("an agent's writer of {rtcm} was allowed"),
        Err(e) => assert!(e.to_string().contains("not allowed"), "{e}"),
    }
    assert!(a.reader::<RtcmMessage>(&rtcm).is_ok(), "agents read {rtcm}");
    assert!(
        c.writer::<RtcmMessage>(&rtcm).is_ok(),
        "coordinators write {rtcm}"
    );
}

#[test]
fn an_expired_enclave_is_refused_with_its_dates() {
    let dir = tempfile::tempdir().unwrap();
    let ks = dir.path().join("keystore");
    create_keystore(&ks, Validity::days(30)).unwrap();
    let expired = Validity {
        from_days_ago: 10,
        days: -1,
    };
    create_enclave(&ks, "/skein/agent/old", Role::Agent, expired).unwrap();
    let e = DdsSecurity::new(&ks, "/skein/agent/old").unwrap_err();
    assert!(
        e.contains("/skein/agent/old") && e.contains("certificate expired on"),
        "{e}"
    );
    // Its permissions expired with it: a participant that skips the check above is
    // refused by DDS Security itself, which finds no grant valid now.
    let unchecked = DdsSecurity {
        keystore: ks.clone(),
        enclave: "/skein/agent/old".into(),
        dir: ks.join("enclaves/skein/agent/old"),
    };
    let e = match Ros2Carrier::join(domain(), &LOOPBACK, "old", Some(&unchecked)) {
        Ok(_) => panic!("an expired enclave joined"),
        Err(e) => e.to_string(),
    };
    assert!(e.contains("not found in the permissions document"), "{e}");
}
