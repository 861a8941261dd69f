//! The in-memory carrier: topics by name in one process, so that the roles of several
//! "processes" (coordinator candidates, agents) talk to each other in a unit test without
//! DDS. It keeps the QoS that shapes what a reader sees:
//!
//! - every reader gets every sample written after it was opened, its own process's too
//!   (as a DDS reader does);
//! - a reader keeps the last `depth` samples of a keep-last topic and loses the older
//!   ones (a reader that does not keep up misses samples, as on DDS);
//! - a transient-local topic hands a new reader the last `depth` samples written before
//!   it was opened (`/skein/formation` for a late standby).
//!
//! It never loses a sample otherwise, and its writes never fail: reliability, timing and
//! loss are DDS's business, tested end to end. A writer made by [`MemoryBus::writer_as`]
//! stamps its samples with a [`WriterIdentity`], as a secured DDS participant's are.

use super::{Carrier, CarrierError, NextSample, Reader, Received, Sample, Writer, WriterIdentity};
use crate::error::DdsError;
use crate::topics::TopicSpec;
use ros2_client::qos::{Durability, History};
use std::any::Any;
use std::collections::{BTreeMap, VecDeque};
use std::sync::{Arc, Mutex, PoisonError, Weak};
use tokio::sync::Notify;

/// Topics by ROS name; clone the `Arc` to hand it to every "process" of a test.
#[derive(Default)]
pub struct MemoryBus {
    topics: Mutex<BTreeMap<String, Arc<dyn Any + Send + Sync>>>,
}

/// One topic: its readers' queues and, transient-local, its last samples.
struct MemoryTopic<M> {
    depth: usize,
    transient_local: bool,
    state: Mutex<TopicState<M>>,
}

struct TopicState<M> {
    readers: Vec<Weak<Queue<M>>>,
    last: VecDeque<Received<M>>,
}

/// One reader's samples not taken yet.
struct Queue<M> {
    depth: usize,
    samples: Mutex<VecDeque<Received<M>>>,
    arrived: Notify,
}

impl<M> Queue<M> {
    fn push(&self, sample: Received<M>) {
        let mut q = self.samples.lock().unwrap_or_else(PoisonError::into_inner);
        if q.len() == self.depth {
            q.pop_front();
        }
        q.push_back(sample);
        drop(q);
        self.arrived.notify_one();
    }

    fn pop(&self) -> Option<Received<M>> {
        self.samples
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .pop_front()
    }
}

impl MemoryBus {
    /// An empty bus.
    pub fn new() -> Arc<Self> {
        Arc::new(MemoryBus::default())
    }

    fn topic<M: Sample>(&self, spec: &TopicSpec) -> Result<Arc<MemoryTopic<M>>, DdsError> {
        let mut topics = self.topics.lock().unwrap_or_else(PoisonError::into_inner);
        let any = topics
            .entry(spec.to_string())
            .or_insert_with(|| {
                Arc::new(MemoryTopic::<M> {
                    depth: match spec.qos.history {
                        History::KeepLast { depth } => depth.max(1),
                        History::KeepAll => usize::MAX,
                    },
                    transient_local: spec.qos.durability == Durability::TransientLocal,
                    state: Mutex::new(TopicState {
                        readers: Vec::new(),
                        last: VecDeque::new(),
                    }),
                })
            })
            .clone();
        any.downcast::<MemoryTopic<M>>()
            .map_err(|_| DdsError(format!("{spec}: the topic carries another type")))
    }
}

impl MemoryBus {
    /// A writer of `spec` whose samples say they come from `identity` (as a secured DDS
    /// participant's do).
    ///
    /// # Errors
    /// The topic carries another type.
    pub fn writer_as<M: Sample>(
        &self,
        spec: &TopicSpec,
        identity: WriterIdentity,
    ) -> Result<Arc<dyn Writer<M>>, DdsError> {
        Ok(Arc::new(MemoryWriter {
            topic: self.topic::<M>(spec)?,
            identity: Some(identity),
        }))
    }
}

impl Carrier for MemoryBus {
    fn writer<M: Sample>(&self, spec: &TopicSpec) -> Result<Arc<dyn Writer<M>>, DdsError> {
        Ok(Arc::new(MemoryWriter {
            topic: self.topic::<M>(spec)?,
            identity: None,
        }))
    }

    fn reader<M: Sample>(&self, spec: &TopicSpec) -> Result<Arc<dyn Reader<M>>, DdsError> {
        let topic = self.topic::<M>(spec)?;
        let queue = Arc::new(Queue {
            depth: topic.depth,
            samples: Mutex::new(VecDeque::new()),
            arrived: Notify::new(),
        });
        let mut state = topic.state.lock().unwrap_or_else(PoisonError::into_inner);
        for s in &state.last {
            queue.push(s.clone());
        }
        state.readers.push(Arc::downgrade(&queue));
        Ok(Arc::new(MemoryReader(queue)))
    }
}

/// A writer of the bus, and the identity its samples carry.
struct MemoryWriter<M> {
    topic: Arc<MemoryTopic<M>>,
    identity: Option<WriterIdentity>,
}

impl<M: Sample> Writer<M> for MemoryWriter<M> {
    fn write(&self, sample: M) -> Result<(), CarrierError> {
        let topic = &self.topic;
        let mut state = topic.state.lock().unwrap_or_else(PoisonError::into_inner);
        state.readers.retain(|r| r.strong_count() > 0);
        for r in state.readers.iter().filter_map(Weak::upgrade) {
            r.push((sample.clone(), self.identity));
        }
        if topic.transient_local {
            if state.last.len() == topic.depth {
                state.last.pop_front();
            }
            state.last.push_back((sample, self.identity));
        }
        Ok(())
    }
}

/// A reader of the bus.
struct MemoryReader<M>(Arc<Queue<M>>);

impl<M: Sample> Reader<M> for MemoryReader<M> {
    fn try_take(&self) -> Result<Option<M>, CarrierError> {
        Ok(self.0.pop().map(|(m, _)| m))
    }

    fn take_next(&self) -> NextSample<'_, M> {
        Box::pin(async move {
            loop {
                if let Some(m) = self.0.pop() {
                    return Ok(m);
                }
                // A sample pushed since the pop left a permit: this returns at once.
                self.0.arrived.notified().await;
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msgs::{CoordinatorLease, Header, SwarmMessage};
    use crate::topics;
    use ros2_client::builtin_interfaces::Time;

    fn lease(epoch: u64) -> CoordinatorLease {
        CoordinatorLease {
            header: Header {
                stamp: Time::ZERO,
                frame_id: String::new(),
            },
            coordinator_id: "gcs-a".into(),
            priority: 1,
            epoch,
            active: true,
            api_url: String::new(),
        }
    }

    #[tokio::test]
    async fn every_reader_gets_every_sample_in_order_its_writers_own_too() {
        let bus = MemoryBus::new();
        let w = bus
            .writer::<CoordinatorLease>(&topics::coordinator())
            .unwrap();
        let a = bus
            .reader::<CoordinatorLease>(&topics::coordinator())
            .unwrap();
        let b = bus
            .reader::<CoordinatorLease>(&topics::coordinator())
            .unwrap();
        for e in 1..=3 {
            w.write(lease(e)).unwrap();
        }
        for r in [&a, &b] {
            for e in 1..=3 {
                assert_eq!(r.take_next().await.unwrap().0.epoch, e);
            }
            assert_eq!(r.try_take().unwrap(), None);
        }
    }

    #[tokio::test]
    async fn a_slow_reader_keeps_the_last_depth_samples_of_a_keep_last_topic() {
        let bus = MemoryBus::new();
        // Keep-last 32.
        let w = bus
            .writer::<CoordinatorLease>(&topics::coordinator())
            .unwrap();
        let r = bus
            .reader::<CoordinatorLease>(&topics::coordinator())
            .unwrap();
        for e in 1..=40 {
            w.write(lease(e)).unwrap();
        }
        let mut got = Vec::new();
        while let Some(l) = r.try_take().unwrap() {
            got.push(l.epoch);
        }
        assert_eq!(got, (9..=40).collect::<Vec<_>>());
    }

    #[tokio::test]
    async fn a_late_reader_of_a_transient_local_topic_gets_the_last_sample_only_there() {
        let bus = MemoryBus::new();
        let formation = bus.writer::<SwarmMessage>(&topics::formation()).unwrap();
        let report = bus.writer::<SwarmMessage>(&topics::swarm_report()).unwrap();
        let m = |epoch| {
            let mut m = crate::envelope::Envelope::message("", "gcs-a", epoch, None, &()).unwrap();
            m.header.stamp = Time::ZERO;
            m
        };
        for e in 1..=2 {
            formation.write(m(e)).unwrap();
            report.write(m(e)).unwrap();
        }
        let late = bus.reader::<SwarmMessage>(&topics::formation()).unwrap();
        assert_eq!(late.try_take().unwrap().map(|m| m.epoch), Some(2));
        assert_eq!(late.try_take().unwrap(), None);
        let late = bus.reader::<SwarmMessage>(&topics::swarm_report()).unwrap();
        assert_eq!(late.try_take().unwrap(), None);
    }

    #[test]
    fn a_topic_opened_with_another_type_is_refused_naming_it() {
        let bus = MemoryBus::new();
        bus.writer::<CoordinatorLease>(&topics::coordinator())
            .unwrap();
        let e = bus
            .reader::<SwarmMessage>(&topics::coordinator())
            .err()
            .unwrap();
        assert!(e.0.contains("/skein/coordinator"), "{e}");
    }
}
