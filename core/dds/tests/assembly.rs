//! A swarm of dozens on one host: 24 DDS participants of this process on loopback, which
//! has no multicast, find and hear each other, and 16 under DDS Security.
//!
//! Both were out of reach on RustDDS 0.15.1 as published (`third_party/rustdds/PATCHES.md`):
//! on one host a participant probed only the first 12 participant slots by unicast SPDP, so
//! two participants past the twelfth never met; and under DDS Security every handshake
//! message went to every participant, whose stateless reader kept one message per read,
//! so handshakes past about a dozen participants starved (measured with RustDDS as
//! published: 12 of the open 24 and none of the secured 24 had heard every other after
//! 120 s; with the fixes, 0.2-1.5 s and 3.4-7.0 s). Each participant here writes and
//! reads `/skein/swarm/clock` (best-effort, as the agents' clock exchange is), and the
//! test waits until every one has heard every other.

use skein_dds::carrier::ros2::Ros2Carrier;
use skein_dds::carrier::{Carrier, Reader, Writer};
use skein_dds::envelope::Envelope;
use skein_dds::msgs::SwarmMessage;
use skein_dds::security::keystore::{Validity, create_enclave, create_keystore};
use skein_dds::security::{DdsSecurity, Role};
use skein_dds::topics;
use std::collections::BTreeSet;
use std::net::{IpAddr, Ipv4Addr};
use std::sync::Arc;
use std::time::{Duration, Instant};

const LOOPBACK: [IpAddr; 1] = [IpAddr::V4(Ipv4Addr::LOCALHOST)];

/// Participants of the open test: twice the slots RustDDS probed on one host.
const OPEN_PARTICIPANTS: usize = 24;

/// Participants of the secured test: past the dozen where the handshakes starved. At 24,
/// about one run in seven (5 of 36, 2026-11-27) leaves one pair authenticated with no
/// endpoint matched, a defect not found yet (`third_party/rustdds/PATCHES.md`, "Known");
/// at 16 it was not seen in 23 runs.
const SECURED_PARTICIPANTS: usize = 16;

/// How long the swarm may take to assemble. On this machine's debug build (RustDDS
/// unoptimised) the secured 24 assemble in seconds; the deadline is for a busy CI machine.
const DEADLINE: Duration = Duration::from_secs(120);

/// A domain of this test process alone, one per test (`k`): other tests' participants
/// may share the host.
fn domain(k: u32) -> u16 {
    u16::try_from(150 + (std::process::id() % 40) * 2 + k).unwrap()
}

/// One participant: its name, what it writes with and what it has heard.
struct Member {
    name: String,
    writer: Arc<dyn Writer<SwarmMessage>>,
    reader: Arc<dyn Reader<SwarmMessage>>,
    heard: BTreeSet<String>,
    /// Its participant: dropped with it.
    _carrier: Ros2Carrier,
}

impl Member {
    fn join(domain: u16, name: String, security: Option<&DdsSecurity>) -> Member {
        let carrier = Ros2Carrier::join(domain, &LOOPBACK, &name, security)
            .unwrap_or_else(|e| panic!("{name} joins: {e}"));
        let topic = topics::swarm_clock();
        Member {
            writer: carrier.writer(&topic).expect("writer"),
            reader: carrier.reader(&topic).expect("reader"),
            heard: BTreeSet::new(),
            _carrier: carrier,
            name,
        }
    }
}

/// Joins `participants` members at once (enrolled with `enrol(i)` when secured); every
/// 100 ms each writes one sample and takes what it heard, until each has heard every
/// other or [`DEADLINE`] passes. Panics naming who has not heard whom.
fn assemble(domain: u16, participants: usize, enrol: impl Fn(usize) -> Option<DdsSecurity>) {
    let members: Vec<(String, Option<DdsSecurity>)> = (0..participants)
        .map(|i| (format!("m{i}"), enrol(i)))
        .collect();
    let mut swarm: Vec<Member> = members
        .into_iter()
        .map(|(name, s)| Member::join(domain, name, s.as_ref()))
        .collect();
    let all: BTreeSet<String> = swarm.iter().map(|m| m.name.clone()).collect();
    let start = Instant::now();
    let mut n = 0;
    loop {
        n += 1;
        for m in &swarm {
            let sample = Envelope::message("uav-0", &m.name, n, None, &serde_json::json!({}));
            m.writer.write(sample.expect("sample")).expect("write");
        }
        std::thread::sleep(Duration::from_millis(100));
        for m in &mut swarm {
            // Only this test's members: another test's participants may share the domain.
            while let Ok(Some(s)) = m.reader.try_take() {
                if all.contains(&s.sender_id) {
                    m.heard.insert(s.sender_id);
                }
            }
        }
        let deaf: Vec<String> = swarm
            .iter()
            .filter(|m| m.heard.len() < all.len() - 1 || m.heard.contains(&m.name))
            .map(|m| {
                let missing: Vec<&String> = all
                    .iter()
                    .filter(|o| **o != m.name && !m.heard.contains(*o))
                    .collect();
                format!("{} has not heard {missing:?}", m.name)
            })
            .collect();
        if n % 50 == 0 {
            eprintln!(
                "{:.0} s: {} of {participants} have heard every other",
                start.elapsed().as_secs_f64(),
                participants - deaf.len()
            );
        }
        if deaf.is_empty() {
            eprintln!(
                "{participants} participants heard each other in {:.1} s",
                start.elapsed().as_secs_f64()
            );
            return;
        }
        if start.elapsed() > DEADLINE {
            // Not dropped: a participant stuck in discovery may never join its threads,
            // and the failure is reported, not hung.
            std::mem::forget(swarm);
            panic!(
                "after {DEADLINE:?}, {} of {participants} have not heard every other: {}",
                deaf.len(),
                deaf.join("; ")
            );
        }
    }
}

/// Runs `assembly` on a thread of its own and fails if it panics or has not returned a
/// minute past [`DEADLINE`]: a participant stuck in RustDDS (a lock held for ever) hangs
/// its creator, and the test reports that instead of hanging.
fn bounded(assembly: impl FnOnce() + Send + 'static) {
    let (done, finished) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        assembly();
        let _ = done.send(());
    });
    match finished.recv_timeout(DEADLINE + Duration::from_secs(60)) {
        Ok(()) => {}
        Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
            panic!("the assembly hung: not done a minute past its {DEADLINE:?}")
        }
        Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
            panic!("the assembly failed (its panic is above)")
        }
    }
}

#[test]
fn two_dozen_participants_on_one_hosts_loopback_hear_each_other() {
    bounded(|| assemble(domain(0), OPEN_PARTICIPANTS, |_| None));
}

#[test]
fn sixteen_secured_participants_on_one_hosts_loopback_hear_each_other() {
    bounded(|| {
        let keystore = tempfile::tempdir().unwrap();
        create_keystore(keystore.path(), Validity::days(1)).unwrap();
        assemble(domain(1), SECURED_PARTICIPANTS, |i| {
            let name = format!("/skein/agent/a{i}");
            create_enclave(keystore.path(), &name, Role::Agent, Validity::days(1)).unwrap();
            Some(DdsSecurity::new(keystore.path(), &name).unwrap())
        });
    });
}
