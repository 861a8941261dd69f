//! The clock exchange on `/skein/swarm/clock`: every coordinator and agent estimates its
//! peers' clocks ([`PeerClocks`], the NTP exchange over the swarm's own link), so that the
//! roles convert the stamps of targets, reports and mirrors from another host into this
//! process's clock before aging them.
//!
//! Each process publishes a [`ClockSample`] every [`CLOCK_PERIOD`]: when it sent it, and
//! for each peer heard lately when that peer sent its last sample and when it arrived
//! here. A sample that echoes this process's own send time completes an exchange. Arrival
//! times are taken when the sample is read off the topic (a task waits on it), not on a
//! tick.

use crate::carrier::{Carrier, TopicReader, TopicWriter};
use crate::counters::DdsCounters;
use crate::envelope::{Envelope, body_or_drop};
use crate::error::DdsError;
use crate::msgs::SwarmMessage;
use crate::topics;
use serde::{Deserialize, Serialize};
use skein_swarm::clocks::PeerClocks;
use skein_swarm::protocol::wall_us;
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

/// How often each process publishes its clock sample.
pub const CLOCK_PERIOD: Duration = Duration::from_millis(500);

/// A peer not heard for this long is no longer echoed.
const ECHO_FOR: Duration = Duration::from_secs(5);

/// One process's clock sample (the body of a `/skein/swarm/clock` message).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClockSample {
    /// When it was sent, the sender's wall clock, µs.
    pub sent_us: u64,
    /// The peers it heard lately.
    pub echoes: Vec<Echo>,
}

/// What a process last heard of one peer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Echo {
    /// The peer's id.
    pub peer: String,
    /// When the peer sent its last sample, the peer's clock, µs.
    pub peer_sent_us: u64,
    /// When it arrived, the echoing process's clock, µs.
    pub received_us: u64,
}

/// The clock role of one process.
pub struct Clocks {
    me: String,
    counters: Arc<DdsCounters>,
    writer: TopicWriter<SwarmMessage>,
    reader: TopicReader<SwarmMessage>,
    clocks: Arc<PeerClocks>,
    /// Each peer's last sample: (its send time, its clock; arrival, this clock).
    heard: Mutex<BTreeMap<String, (u64, u64)>>,
}

impl Clocks {
    /// Opens `/skein/swarm/clock` for process `me` (its id on the protocol topics),
    /// estimating into `clocks`.
    ///
    /// # Errors
    /// The topic, reader or writer could not be created.
    pub fn open(
        carrier: &impl Carrier,
        me: String,
        clocks: Arc<PeerClocks>,
        counters: &Arc<DdsCounters>,
    ) -> Result<Self, DdsError> {
        let topic = topics::swarm_clock();
        Ok(Clocks {
            writer: TopicWriter::open(carrier, &topic, counters)?,
            reader: TopicReader::open(carrier, &topic, counters, "clock sample")?,
            me,
            counters: counters.clone(),
            clocks,
            heard: Mutex::new(BTreeMap::new()),
        })
    }

    /// A sample arrived at `received_us` (this clock).
    fn on_sample(&self, env: Envelope, received_us: u64) {
        if env.sender_id == self.me {
            return;
        }
        let Some(sample) = body_or_drop::<ClockSample>(&self.counters, &env, "clock sample") else {
            return;
        };
        if let Some(e) = sample.echoes.iter().find(|e| e.peer == self.me) {
            self.clocks.exchange(
                &env.sender_id,
                e.peer_sent_us,
                e.received_us,
                sample.sent_us,
                received_us,
            );
        }
        self.heard
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .insert(env.sender_id, (sample.sent_us, received_us));
    }

    /// This process's sample now.
    fn sample(&self, now_us: u64) -> ClockSample {
        let mut heard = self.heard.lock().unwrap_or_else(PoisonError::into_inner);
        let horizon = ECHO_FOR.as_micros() as u64;
        heard.retain(|_, (_, at)| now_us.saturating_sub(*at) < horizon);
        ClockSample {
            sent_us: now_us,
            echoes: heard
                .iter()
                .map(|(peer, (sent, at))| Echo {
                    peer: peer.clone(),
                    peer_sent_us: *sent,
                    received_us: *at,
                })
                .collect(),
        }
    }
}

/// Runs the clock exchange until the task is aborted (see the module docs).
pub async fn run(clocks: Arc<Clocks>) {
    let c = clocks.clone();
    let listen = tokio::spawn(async move {
        loop {
            let m = c.reader.next().await;
            c.on_sample(Envelope::from_msg(m), wall_us());
        }
    });
    let _listen = AbortOnDrop(listen);
    let mut tick = tokio::time::interval(CLOCK_PERIOD);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        tick.tick().await;
        let sample = clocks.sample(wall_us());
        if let Ok(m) = Envelope::message("", &clocks.me, 0, None, &sample) {
            let _ = clocks.writer.publish(m);
        }
    }
}

struct AbortOnDrop(tokio::task::JoinHandle<()>);

impl Drop for AbortOnDrop {
    fn drop(&mut self) {
        self.0.abort();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::carrier::memory::MemoryBus;

    #[test]
    fn two_processes_learn_each_others_offset_from_their_samples() {
        let bus = MemoryBus::new();
        let counters = Arc::new(DdsCounters::default());
        let (ca, cb) = (
            Arc::new(PeerClocks::default()),
            Arc::new(PeerClocks::default()),
        );
        let a = Clocks::open(bus.as_ref(), "gcs-a".into(), ca.clone(), &counters).unwrap();
        let b = Clocks::open(bus.as_ref(), "agent-2".into(), cb.clone(), &counters).unwrap();
        // agent-2's clock is 300 ms ahead; each leg takes 1 ms.
        let skew = 300_000u64;
        let to_env = |s: &Clocks, sample: &ClockSample| {
            Envelope::from_msg(Envelope::message("", &s.me, 0, None, sample).unwrap())
        };
        let mut t = 1_000_000_000u64; // a's clock
        for _ in 0..3 {
            let sa = a.sample(t);
            b.on_sample(to_env(&a, &sa), t + 1_000 + skew);
            t += 250_000;
            let sb = b.sample(t + skew);
            a.on_sample(to_env(&b, &sb), t + 1_000);
            t += 250_000;
        }
        let oa = ca.offset_us("agent-2").unwrap();
        assert_eq!(oa, 300_000, "a sees agent-2 300 ms ahead");
        let ob = cb.offset_us("gcs-a").unwrap();
        assert_eq!(ob, -300_000, "agent-2 sees gcs-a 300 ms behind");
        assert_eq!(ca.snapshot(t)["agent-2"].uncertainty_ms, 1.0);
        // Its own samples and malformed ones teach nothing.
        let own = a.sample(t);
        a.on_sample(to_env(&a, &own), t);
        assert!(!ca.snapshot(t).contains_key("gcs-a"));
        let bad = Envelope::from_msg(Envelope::message("", "x", 0, None, &"no").unwrap());
        a.on_sample(bad, t);
        assert!(
            counters
                .malformed
                .load(std::sync::atomic::Ordering::Relaxed)
                >= 1
        );
    }
}
