//! The corrections relay ([`crate::rtcm`]): only the active coordinator of two with the
//! same source publishes, and the failover of the election ([`crate::lease`]) moves the
//! publishing; an agent's corrections service takes the samples as its source (frames,
//! bad CRCs, stalls), or ignores them while it has a source of its own.

use super::{Peer, Process};
use crate::carrier::memory::MemoryBus;
use crate::carrier::{Carrier, Reader};
use crate::counters::DdsCounters;
use crate::lease::{Candidate, ElectionLink};
use crate::msgs::{Header, RtcmMessage};
use crate::rtcm::{self, RtcmContext, RtcmPublisher, RtcmReceiver};
use crate::topics;
use ros2_client::builtin_interfaces::Time;
use ros2_client::qos::History;
use skein_model::geo::GeoPoint;
use skein_rtk::framer::{Frame, RtcmFramer};
use skein_rtk::testing::{frame_1005, frame_of};
use skein_rtk::{RelayRole, Relayed, RtkConfig, RtkService, SourceState};
use skein_swarm::election::ElectionConfig;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;
use tokio::sync::broadcast;
use tokio::task::JoinSet;

/// A coordinator's corrections source, as the relay sees it: the test hands it frames,
/// and it records what the relay told it.
struct Source {
    frames: broadcast::Sender<Frame>,
    /// Every `publishing(active)` the relay said, in order.
    roles: Mutex<Vec<bool>>,
    published: AtomicU64,
}

impl Source {
    fn new() -> Arc<Source> {
        Arc::new(Source {
            frames: broadcast::channel(64).0,
            roles: Mutex::new(Vec::new()),
            published: AtomicU64::new(0),
        })
    }

    fn roles(&self) -> Vec<bool> {
        self.roles
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }
}

impl RtcmContext for Source {
    fn source_frames(&self) -> broadcast::Receiver<Frame> {
        self.frames.subscribe()
    }

    fn publishing(&self, topic: &str, active: bool) {
        assert_eq!(topic, "/skein/rtcm");
        self.roles
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .push(active);
    }

    fn published(&self, frames: u64, failures: u64) {
        assert_eq!(failures, 0);
        self.published.fetch_add(frames, Ordering::Relaxed);
    }

    fn receiving(&self, _: &str) {
        panic!("a coordinator receives no corrections");
    }

    fn relayed(&self, _: &[u8]) -> Relayed {
        panic!("a coordinator receives no corrections");
    }
}

/// Candidate `id` of `priority` with `source`: its election and its relay, running.
fn candidate(bus: &Arc<MemoryBus>, id: &str, priority: u32, source: &Arc<Source>) -> JoinSet<()> {
    let counters = Arc::new(DdsCounters::default());
    let c = Candidate {
        coordinator_id: id.into(),
        priority,
        api_url: format!("http://{id}"),
        timing: ElectionConfig::default(),
    };
    let election = Arc::new(ElectionLink::open(bus.as_ref(), c, &counters).unwrap());
    let publisher = Arc::new(RtcmPublisher::open(bus.as_ref(), &counters).unwrap());
    let (process, _calls) = Process::new(None);
    let mut tasks = JoinSet::new();
    tasks.spawn(rtcm::publish(
        publisher,
        Some(election.subscribe()),
        source.clone(),
    ));
    tasks.spawn(election.run(process));
    tasks
}

/// The `n`-th frame of a base: a 1005 whose station id is `n` (every frame its own bytes).
fn nth_frame(n: u16) -> Frame {
    let bytes = frame_1005(n, GeoPoint::new(47.4, 8.55, 500.0));
    RtcmFramer::default().push(&bytes).remove(0)
}

/// Hands frames `from..to` to every source, one each 100 ms.
async fn stream(sources: &[&Arc<Source>], from: u16, to: u16) {
    let mut tick = tokio::time::interval(Duration::from_millis(100));
    for n in from..to {
        tick.tick().await;
        for s in sources {
            let _ = s.frames.send(nth_frame(n));
        }
    }
    // Let the relays publish the last one.
    tokio::time::sleep(Duration::from_millis(10)).await;
}

/// How many times each frame (by station id) was read on the topic.
fn read_counts(reader: &Arc<dyn Reader<RtcmMessage>>) -> BTreeMap<u16, usize> {
    let mut counts = BTreeMap::new();
    let mut framer = RtcmFramer::default();
    while let Some(m) = reader.try_take().unwrap() {
        let f = framer.push(&m.message).remove(0);
        *counts.entry(f.base.unwrap().station_id).or_default() += 1;
    }
    counts
}

#[tokio::test(start_paused = true)]
async fn only_the_active_coordinator_publishes_and_a_failover_moves_the_publishing() {
    let bus = MemoryBus::new();
    // Deep enough for the whole test: every sample is kept.
    let reader: Arc<dyn Reader<RtcmMessage>> = bus
        .reader(&topics::TopicSpec {
            qos: topics::corrections().history(History::KeepLast { depth: 1000 }),
            ..topics::rtcm()
        })
        .unwrap();
    let (a, b) = (Source::new(), Source::new());
    let mut gcs_a = candidate(&bus, "gcs-a", 2, &a);
    let _gcs_b = candidate(&bus, "gcs-b", 1, &b);
    // Both connected to the same caster: the same frames, from before the election.
    stream(&[&a, &b], 0, 15).await;
    stream(&[&a, &b], 15, 35).await;
    assert_eq!(a.roles(), [false, true], "gcs-a: standby, then publishing");
    assert_eq!(b.roles(), [false], "gcs-b stays a standby");
    assert_eq!(b.published.load(Ordering::Relaxed), 0);
    let before = read_counts(&reader);
    assert!(
        before.values().all(|n| *n == 1),
        "each frame once: {before:?}"
    );
    // gcs-a active from its first second (after its first listen) on.
    let first = *before.keys().next().unwrap();
    assert!((9..=11).contains(&first), "first frame published: {first}");
    assert_eq!(before.keys().last(), Some(&34));
    assert_eq!(a.published.load(Ordering::Relaxed), before.len() as u64);

    // gcs-a dies: gcs-b claims after the lease timeout and publishes from then on.
    gcs_a.abort_all();
    stream(&[&b], 35, 65).await;
    assert_eq!(b.roles(), [false, true], "gcs-b took over");
    let after = read_counts(&reader);
    assert!(
        after.values().all(|n| *n == 1),
        "each frame once: {after:?}"
    );
    let resumed = *after.keys().next().unwrap();
    assert!(
        (43..=48).contains(&resumed),
        "gcs-b published from frame {resumed} (gcs-a died at 35)"
    );
    assert_eq!(after.keys().last(), Some(&64));
    assert_eq!(b.published.load(Ordering::Relaxed), after.len() as u64);
}

/// An agent's relay and corrections service (no vehicles), running; its DDS counters.
async fn agent(bus: &Arc<MemoryBus>) -> (Arc<RtkService>, Arc<DdsCounters>, JoinSet<()>) {
    let counters = Arc::new(DdsCounters::default());
    let receiver = Arc::new(RtcmReceiver::open(bus.as_ref(), &counters).unwrap());
    let rtk = Arc::new(RtkService::start(Arc::new(Vec::new)));
    let mut tasks = JoinSet::new();
    tasks.spawn(rtcm::receive(receiver, rtk.clone()));
    tokio::time::sleep(Duration::from_millis(1)).await;
    (rtk, counters, tasks)
}

/// An `rtcm_msgs/Message` carrying `bytes`.
fn sample(bytes: &[u8]) -> RtcmMessage {
    RtcmMessage {
        header: Header {
            stamp: Time::now(),
            frame_id: String::new(),
        },
        message: bytes.to_vec(),
    }
}

#[tokio::test(start_paused = true)]
async fn an_agent_takes_the_relayed_frames_as_its_source_counts_bad_ones_and_stalls_without() {
    let bus = MemoryBus::new();
    let (rtk, counters, _agent) = agent(&bus).await;
    let s = rtk.status();
    assert_eq!(s.source.as_deref(), Some("dds:/skein/rtcm"));
    assert_eq!(s.state, SourceState::Connecting);
    assert_eq!(s.relay.unwrap().role, RelayRole::Receiving);

    let coordinator = Peer::open(&bus, &topics::rtcm());
    let good = frame_of(1074, 200);
    let mut corrupt = good.clone();
    corrupt[100] ^= 0x01;
    for bytes in [
        frame_1005(7, GeoPoint::new(47.4, 8.55, 500.0)),
        good.clone(),
        corrupt,
        b"$GPGGA,not RTCM".to_vec(),
    ] {
        coordinator.writer.publish(sample(&bytes)).unwrap();
    }
    tokio::time::sleep(Duration::from_millis(10)).await;
    let s = rtk.status();
    assert_eq!(s.state, SourceState::Streaming, "{s:?}");
    assert_eq!((s.frames, s.crc_failures), (2, 1), "{s:?}");
    assert_eq!(s.message_types.keys().collect::<Vec<_>>(), ["1005", "1074"]);
    assert_eq!(s.base.unwrap().station_id, 7);
    let relay = s.relay.unwrap();
    assert_eq!((relay.received, relay.malformed), (4, 2), "{relay:?}");
    assert_eq!(counters.malformed.load(Ordering::Relaxed), 2);

    // No frame for the stall timeout (10 s): stalled, saying on which topic.
    tokio::time::sleep(Duration::from_millis(9900)).await;
    assert_eq!(rtk.status().state, SourceState::Streaming);
    tokio::time::sleep(Duration::from_millis(200)).await;
    let s = rtk.status();
    assert_eq!(s.state, SourceState::Stalled, "{s:?}");
    assert_eq!(
        s.error.as_deref(),
        Some("no RTCM frame on /skein/rtcm for 10 s")
    );
    coordinator.writer.publish(sample(&good)).unwrap();
    tokio::time::sleep(Duration::from_millis(10)).await;
    let s = rtk.status();
    assert_eq!((s.state, s.error), (SourceState::Streaming, None));
    assert_eq!(s.frames, 3);
}

#[tokio::test(start_paused = true)]
async fn an_agent_with_a_source_of_its_own_ignores_the_topic_until_it_has_none() {
    let bus = MemoryBus::new();
    let (rtk, counters, _agent) = agent(&bus).await;
    let own = RtkConfig {
        source: "tcp://127.0.0.1:1".into(),
        max_bytes_s: 2000.0,
        stall_timeout_s: 10.0,
        send_gga: false,
    };
    rtk.configure(Some(&own)).unwrap();
    let coordinator = Peer::open(&bus, &topics::rtcm());
    coordinator
        .writer
        .publish(sample(&frame_of(1074, 200)))
        .unwrap();
    tokio::time::sleep(Duration::from_millis(10)).await;
    let s = rtk.status();
    assert_eq!(s.source.as_deref(), Some("tcp://127.0.0.1:1"));
    assert_eq!(s.frames, 0);
    let relay = s.relay.unwrap();
    assert_eq!(relay.role, RelayRole::Ignoring);
    assert_eq!((relay.received, relay.ignored), (1, 1));
    assert_eq!(counters.malformed.load(Ordering::Relaxed), 0);

    // Its own source removed (`DELETE /api/v1/rtk`): the topic is its source again.
    rtk.configure(None).unwrap();
    coordinator
        .writer
        .publish(sample(&frame_of(1074, 200)))
        .unwrap();
    tokio::time::sleep(Duration::from_millis(10)).await;
    let s = rtk.status();
    assert_eq!(s.source.as_deref(), Some("dds:/skein/rtcm"));
    assert_eq!((s.state, s.frames), (SourceState::Streaming, 1));
    assert_eq!(s.relay.unwrap().role, RelayRole::Receiving);
}
