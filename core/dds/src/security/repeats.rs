//! A replay told from RTPS's own repeat, for [`super::refusals`].
//!
//! RustDDS's reader drops a DATA whose sequence number it already took and says only
//! "already have this seq" (at `trace`). Two things make such a DATA: an attacker's
//! replay of a recorded message, and a reliable writer's repair that crossed its original
//! (a NACK answered twice, a sample that arrived late after its repair). A repair is of
//! a sample still unacknowledged, so it follows the first copy within a few heartbeat
//! periods (RustDDS: 100 ms while unacknowledged, 1 s after); a replay follows it by as
//! long as the attacker likes. [`Repeats`] remembers, per writer, when each sample of
//! the last [`REPAIR_WINDOW`] was first taken: a copy of one taken within the window is
//! a repeat, a copy of an older one a replay. Measured on loopback, a secured wedge of
//! three agents orbiting at 5 m/s with the machine short of CPU (two compilers beside
//! it): counting every copy made eight "replays" in 17 minutes; with the window, none in
//! 26 minutes. A replay within the window of its original is dropped all the same, only
//! not counted.

use std::collections::{BTreeMap, HashMap};
use std::time::{Duration, Instant};

/// How long after a sample's first copy another is taken as RTPS's repair: ten of
/// RustDDS's slow heartbeat periods.
pub const REPAIR_WINDOW: Duration = Duration::from_secs(10);

/// What a DATA already taken was.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Duplicate {
    /// A copy of a sample first taken within [`REPAIR_WINDOW`]: RTPS's repair.
    Repeat,
    /// A copy of a sample first taken longer ago (or that this reader skipped): a replay.
    Replay,
}

/// The samples a process's readers took lately, per writer; fed by the reader's records
/// in the order RustDDS's event loop says them.
#[derive(Debug, Default)]
pub struct Repeats {
    /// Per writer (its GUID as RustDDS prints it), when each recent sequence number was
    /// first taken.
    writers: HashMap<String, BTreeMap<i64, Instant>>,
    /// The DATA being handled (sequence number, when), of [`Repeats::pending_writer`]:
    /// taken unless the reader's next record says it already had it.
    pending: Option<(i64, Instant)>,
    /// Its writer: one buffer, rewritten for every DATA (nothing allocated per sample
    /// but a new writer's entry).
    pending_writer: String,
}

impl Repeats {
    /// A reader handles DATA `seq` of `writer` at `now` (a user topic's).
    pub fn data(&mut self, writer: &str, seq: i64, now: Instant) {
        self.settle();
        self.pending_writer.clear();
        self.pending_writer.push_str(writer);
        self.pending = Some((seq, now));
    }

    /// A reader handles a DATA this ledger does not follow (a discovery topic's): the one
    /// before it, if any, was taken.
    pub fn other_data(&mut self) {
        self.settle();
    }

    /// The reader dropped DATA `seq` as already taken, at `now`: what it was, if it is the
    /// DATA [`Repeats::data`] announced.
    pub fn already_taken(&mut self, seq: i64, now: Instant) -> Option<Duplicate> {
        let (pending_seq, _) = self.pending.take()?;
        if pending_seq != seq {
            return None;
        }
        let first = self
            .writers
            .get(self.pending_writer.as_str())
            .and_then(|w| w.get(&seq));
        Some(match first {
            Some(t) if now.duration_since(*t) < REPAIR_WINDOW => Duplicate::Repeat,
            _ => Duplicate::Replay,
        })
    }

    /// The pending DATA was taken: remember when (its first copy), and forget what is
    /// older than the window.
    fn settle(&mut self) {
        let Some((seq, at)) = self.pending.take() else {
            return;
        };
        let writer = self.pending_writer.as_str();
        if !self.writers.contains_key(writer) {
            self.writers.insert(writer.to_string(), BTreeMap::new());
        }
        let taken = self.writers.get_mut(writer).expect("inserted above");
        taken.entry(seq).or_insert(at);
        // Most samples come in order: the oldest first. A repaired one out of order stays
        // until the oldest are gone, at most a window more.
        while let Some(e) = taken.first_entry() {
            if at.duration_since(*e.get()) < REPAIR_WINDOW {
                break;
            }
            e.remove();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const W: &str = "GUID {01.02 EntityId {[0, 0, 1] User/WriterNoKey}}";

    #[test]
    fn a_copy_within_the_window_is_a_repeat_and_an_older_one_a_replay() {
        let t0 = Instant::now();
        let mut r = Repeats::default();
        for seq in 1..=100 {
            r.data(
                W,
                seq,
                t0 + Duration::from_millis(200) * u32::try_from(seq).unwrap(),
            );
        }
        // 20.2 s: sample 100 (taken at 20.0 s) again, then sample 3 (taken at 0.6 s).
        let now = t0 + Duration::from_millis(20_200);
        r.data(W, 100, now);
        assert_eq!(r.already_taken(100, now), Some(Duplicate::Repeat));
        r.data(W, 3, now);
        assert_eq!(r.already_taken(3, now), Some(Duplicate::Replay));
        // 40 s on, even sample 100 is long taken.
        let later = now + REPAIR_WINDOW * 2;
        r.data(W, 100, later);
        assert_eq!(r.already_taken(100, later), Some(Duplicate::Replay));
    }

    #[test]
    fn only_the_announced_data_is_judged_and_another_writers_samples_are_theirs() {
        let t0 = Instant::now();
        let mut r = Repeats::default();
        r.data(W, 7, t0);
        assert_eq!(r.already_taken(8, t0), None, "not the DATA announced");
        assert_eq!(r.already_taken(7, t0), None, "nothing announced any more");
        r.data(W, 7, t0);
        r.other_data();
        r.data("GUID {other}", 7, t0);
        assert_eq!(
            r.already_taken(7, t0),
            Some(Duplicate::Replay),
            "the other writer never sent 7 before"
        );
        r.data(W, 7, t0 + Duration::from_secs(1));
        assert_eq!(
            r.already_taken(7, t0 + Duration::from_secs(1)),
            Some(Duplicate::Repeat)
        );
    }

    #[test]
    fn the_ledger_keeps_only_a_window_of_samples() {
        let t0 = Instant::now();
        let mut r = Repeats::default();
        for seq in 0..10_000 {
            r.data(
                W,
                seq,
                t0 + Duration::from_millis(20) * u32::try_from(seq).unwrap(),
            );
        }
        r.other_data();
        let kept = r.writers[W].len();
        // 50 samples a second for the 10 s window.
        assert!((500..=501).contains(&kept), "{kept} kept");
    }
}
