//! The DDS link's sample counters, shared by its roles and exported to `/metrics` as
//! `skein_dds_samples{what="..."}` ([`DdsCounters::values`]).

use std::sync::atomic::{AtomicU64, Ordering};

/// Counters of the DDS link (in `/metrics` as `skein_dds_samples{what="published"}` …).
#[derive(Debug, Default)]
pub struct DdsCounters {
    /// Samples written.
    pub published: AtomicU64,
    /// Writes that failed (a full reliable queue, a closed participant).
    pub publish_errors: AtomicU64,
    /// Commands taken from the domain (`/skein/<vehicle>/command`).
    pub commands: AtomicU64,
    /// Samples that could not be read or did not parse (dropped).
    pub malformed: AtomicU64,
    /// An agent's targets and commands handed to a local vehicle.
    pub protocol_obeyed: AtomicU64,
    /// An agent's targets and commands for a local vehicle dropped: not from the active
    /// coordinator, or of an old epoch.
    pub protocol_refused: AtomicU64,
    /// Under DDS Security, reports, answers and events about a vehicle from another
    /// enclave than the one that first reported it, dropped ([`crate::remote`]).
    pub protocol_forged: AtomicU64,
}

impl DdsCounters {
    /// Adds one to `counter`.
    pub fn add(counter: &AtomicU64) {
        counter.fetch_add(1, Ordering::Relaxed);
    }

    /// Every counter with its `what` label, in the order of `/metrics`.
    pub fn values(&self) -> [(&'static str, u64); 7] {
        let v = |c: &AtomicU64| c.load(Ordering::Relaxed);
        [
            ("published", v(&self.published)),
            ("publish_errors", v(&self.publish_errors)),
            ("commands", v(&self.commands)),
            ("malformed", v(&self.malformed)),
            ("protocol_obeyed", v(&self.protocol_obeyed)),
            ("protocol_refused", v(&self.protocol_refused)),
            ("protocol_forged", v(&self.protocol_forged)),
        ]
    }
}
