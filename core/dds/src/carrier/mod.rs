//! What carries the roles' samples: a [`Carrier`] opens a topic ([`TopicSpec`]) as a
//! [`Writer`] or a [`Reader`] of one message type. Two carriers implement it:
//!
//! - [`ros2::Ros2Carrier`]: a ROS 2 node on a DDS participant (ros2-client on RustDDS),
//!   what `skein up --dds`, `skein coordinator` and `skein agent` use;
//! - [`memory::MemoryBus`]: an in-memory bus, so that the roles of several "processes"
//!   (coordinator candidates, agents) run together in one unit test without DDS.
//!
//! A role never holds the raw writer or reader: it opens them counted
//! ([`TopicWriter`], [`TopicReader`]), so every write is counted as published or failed
//! and every unreadable sample as malformed, in the link's [`DdsCounters`]. A new
//! carrier (a secured participant, a lossy link for tests) is one module implementing
//! [`Carrier`], [`Writer`] and [`Reader`].

pub mod memory;
pub mod ros2;

use crate::counters::DdsCounters;
use crate::error::DdsError;
use crate::msgs::RosMessage;
use crate::topics::TopicSpec;
use serde::de::DeserializeOwned;
use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;

/// A message a carrier can carry: a ROS 2 message (CDR on DDS) that can be cloned (to
/// every reader of the in-memory bus).
pub trait Sample: RosMessage + DeserializeOwned + Clone + std::fmt::Debug + Send + Sync {}

impl<M: RosMessage + DeserializeOwned + Clone + std::fmt::Debug + Send + Sync> Sample for M {}

/// Why a sample could not be written or read; the text is the carrier's
/// (`"Deserialization { reason: ... }"`).
#[derive(Debug, Clone, PartialEq)]
pub struct CarrierError(pub String);

impl std::fmt::Display for CarrierError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

/// Writes samples of `M` on one topic.
pub trait Writer<M>: Send + Sync {
    /// Writes one sample.
    ///
    /// # Errors
    /// The carrier could not take it (a full reliable queue, a closed participant).
    fn write(&self, sample: M) -> Result<(), CarrierError>;
}

/// Who wrote a sample, as DDS Security proved it: the first 6 bytes of the writer's
/// participant GUID prefix, which DDS Security derives from the SHA-256 of the subject of
/// the participant's identity certificate and checks at authentication (DDS Security 1.1,
/// §9.3.1.1; RustDDS `guid_start_from_certificate`), so that one enclave always writes
/// with the same identity, across restarts, and no other enclave can ([`crate::security::identity_of`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct WriterIdentity(pub [u8; 6]);

impl std::fmt::Display for WriterIdentity {
    /// 12 hex digits.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.iter().try_for_each(|b| write!(f, "{b:02x}"))
    }
}

/// A sample and who wrote it: `None` on a participant without DDS Security, where any
/// participant may claim any GUID.
pub type Received<M> = (M, Option<WriterIdentity>);

/// The next sample of a [`Reader`], when it comes.
pub type NextSample<'a, M> =
    Pin<Box<dyn Future<Output = Result<Received<M>, CarrierError>> + Send + 'a>>;

/// Reads the samples of `M` on one topic: every writer's, its own process's too.
pub trait Reader<M>: Send + Sync {
    /// The oldest sample not taken yet, if any, without waiting.
    ///
    /// # Errors
    /// A sample could not be read (it is gone; the next call reads the next one).
    fn try_take(&self) -> Result<Option<M>, CarrierError>;

    /// The oldest sample not taken yet, and who wrote it, waiting for one.
    ///
    /// # Errors
    /// A sample could not be read (it is gone; the next call reads the next one).
    fn take_next(&self) -> NextSample<'_, M>;
}

/// Opens topics.
pub trait Carrier: Send + Sync + 'static {
    /// A writer on `topic`.
    ///
    /// # Errors
    /// The topic or the writer could not be created (names, sockets, another type on the
    /// same topic).
    fn writer<M: Sample>(&self, topic: &TopicSpec) -> Result<Arc<dyn Writer<M>>, DdsError>;

    /// A reader of `topic`; it gets the samples written from now on (and with
    /// transient-local durability the last ones before).
    ///
    /// # Errors
    /// As [`Carrier::writer`].
    fn reader<M: Sample>(&self, topic: &TopicSpec) -> Result<Arc<dyn Reader<M>>, DdsError>;
}

/// A counted writer of one topic (see the module docs).
pub struct TopicWriter<M> {
    writer: Arc<dyn Writer<M>>,
    counters: Arc<DdsCounters>,
}

impl<M: Sample> TopicWriter<M> {
    /// Opens `topic` on `carrier` for writing, counting in `counters`.
    ///
    /// # Errors
    /// As [`Carrier::writer`].
    pub fn open(
        carrier: &impl Carrier,
        topic: &TopicSpec,
        counters: &Arc<DdsCounters>,
    ) -> Result<Self, DdsError> {
        Ok(TopicWriter {
            writer: carrier.writer(topic)?,
            counters: counters.clone(),
        })
    }

    /// A counted writer around `writer`, counting in `counters`.
    pub fn from_writer(writer: Arc<dyn Writer<M>>, counters: &Arc<DdsCounters>) -> Self {
        TopicWriter {
            writer,
            counters: counters.clone(),
        }
    }

    /// Writes `sample`, counted as published or failed.
    ///
    /// # Errors
    /// The carrier's.
    pub fn publish(&self, sample: M) -> Result<(), CarrierError> {
        let r = self.writer.write(sample);
        DdsCounters::add(match r {
            Ok(()) => &self.counters.published,
            Err(_) => &self.counters.publish_errors,
        });
        r
    }
}

/// A counted reader of one topic: unreadable samples are counted as malformed, logged
/// (`dds: a <what> was dropped: ...`) and skipped.
pub struct TopicReader<M> {
    reader: Arc<dyn Reader<M>>,
    counters: Arc<DdsCounters>,
    what: String,
}

impl<M: Sample> TopicReader<M> {
    /// Opens `topic` on `carrier` for reading; `what` names its samples in the log
    /// (`"report sample"`).
    ///
    /// # Errors
    /// As [`Carrier::reader`].
    pub fn open(
        carrier: &impl Carrier,
        topic: &TopicSpec,
        counters: &Arc<DdsCounters>,
        what: impl Into<String>,
    ) -> Result<Self, DdsError> {
        Ok(TopicReader {
            reader: carrier.reader(topic)?,
            counters: counters.clone(),
            what: what.into(),
        })
    }

    fn dropped(&self, e: &CarrierError) {
        DdsCounters::add(&self.counters.malformed);
        tracing::warn!("dds: a {} was dropped: {e}", self.what);
    }

    /// The next readable sample, waiting for it.
    pub async fn next(&self) -> M {
        self.next_from().await.0
    }

    /// The next readable sample and who wrote it, waiting for it.
    pub async fn next_from(&self) -> Received<M> {
        loop {
            match self.reader.take_next().await {
                Ok(r) => return r,
                Err(e) => self.dropped(&e),
            }
        }
    }

    /// The next readable sample already here, if any.
    pub fn try_next(&self) -> Option<M> {
        loop {
            match self.reader.try_take() {
                Ok(m) => return m,
                Err(e) => self.dropped(&e),
            }
        }
    }
}
