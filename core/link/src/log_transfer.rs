//! MAVLink's log protocol, the ground station's side: listing a vehicle's flight logs
//! (`LOG_REQUEST_LIST` → `LOG_ENTRY`s) and downloading one (`LOG_REQUEST_DATA` →
//! `LOG_DATA` chunks of 90 bytes), as PX4 v1.16's `mavlink_log_handler` serves them: ids
//! from 0, no entry at all when there is no log, a listing needed before any data
//! request, a data request answered by a stream of whole chunks from its offset, nothing
//! at all for an offset past the end.
//!
//! A download keeps which 90-byte chunks arrived. Chunks lost on the way (UDP, a link
//! that fades or is cut) leave gaps: the first gap is requested again, for its own
//! length, as soon as the range asked for has ended (its last chunk arrived) or after
//! [`GAP_TIMEOUT`] without data, until every byte is there; the bytes are handed
//! over only then, so a file is never complete with a hole. A download that gains no byte
//! for [`STALL_TIMEOUT`] fails. The actor's side is `px4link/logs.rs`.

use serde::Serialize;
use skein_mavlink::dialect::{LOG_DATA_DATA, LOG_ENTRY_DATA};
use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// Bytes in one `LOG_DATA` (`data[90]`).
pub const CHUNK_BYTES: usize = 90;

/// A listing not complete after this is requested again (a vehicle answers within
/// milliseconds: its entries go out back to back).
pub const LIST_TIMEOUT: Duration = Duration::from_millis(500);

/// Listings a vehicle answers with nothing while it is heard (other messages arrive in
/// the [`LIST_TIMEOUT`] after the request) before it is taken to have no log: PX4 v1.16
/// answers a vehicle without logs with no `LOG_ENTRY` at all. A window in which nothing
/// at all is heard (a link cut) does not count.
pub const LIST_QUIET_ANSWERS: u32 = 2;

/// Transmissions of a listing before it fails (20 s at [`LIST_TIMEOUT`]: a link cut for
/// less is ridden out).
pub const LIST_ATTEMPTS: u32 = 40;

/// A download that received nothing for this long asks for its first gap again.
pub const GAP_TIMEOUT: Duration = Duration::from_millis(300);

/// A download that gained no byte for this long fails (a link cut for less resumes).
pub const STALL_TIMEOUT: Duration = Duration::from_secs(60);

/// One log on the vehicle (`LOG_ENTRY`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, utoipa::ToSchema)]
pub struct LogEntry {
    /// The vehicle's id of the log (PX4: 0 for the oldest).
    pub id: u16,
    /// Size, bytes.
    pub size_bytes: u32,
    /// When it was written, seconds since the Unix epoch (UTC; 0 when the vehicle does
    /// not know the time).
    pub time_utc: u32,
}

/// A listing in progress: the `LOG_ENTRY`s heard so far.
#[derive(Debug, Default)]
pub struct LogListing {
    entries: BTreeMap<u16, LogEntry>,
    /// `num_logs` as the vehicle said it.
    expected: Option<u16>,
}

impl LogListing {
    /// Takes one `LOG_ENTRY`; true once every log the vehicle has is listed.
    pub fn on_entry(&mut self, e: &LOG_ENTRY_DATA) -> bool {
        self.expected = Some(e.num_logs);
        if e.num_logs > 0 && e.id < e.num_logs {
            self.entries.insert(
                e.id,
                LogEntry {
                    id: e.id,
                    size_bytes: e.size,
                    time_utc: e.time_utc,
                },
            );
        }
        self.is_complete()
    }

    /// Every log listed (an older PX4 says "no log" with one entry of `num_logs` 0).
    pub fn is_complete(&self) -> bool {
        self.expected
            .is_some_and(|n| self.entries.len() >= usize::from(n))
    }

    /// No `LOG_ENTRY` arrived.
    pub fn is_empty(&self) -> bool {
        self.expected.is_none()
    }

    /// The entries, by id.
    pub fn entries(&self) -> Vec<LogEntry> {
        self.entries.values().copied().collect()
    }
}

/// A download in progress (see the module docs).
#[derive(Debug)]
pub struct LogDownload {
    entry: LogEntry,
    data: Vec<u8>,
    /// Which chunks arrived, by `ofs / 90`.
    got: Vec<bool>,
    received: usize,
    /// Bytes received so far, for whoever watches (the API's progress).
    progress: Arc<AtomicU64>,
    last_data: Instant,
    last_progress: Instant,
    /// The chunk after the last one of the range asked for last.
    requested_end: usize,
}

impl LogDownload {
    /// A download of `entry` starting at `now`, counting its bytes into `progress`.
    pub fn new(entry: LogEntry, progress: Arc<AtomicU64>, now: Instant) -> Self {
        let size = entry.size_bytes as usize;
        progress.store(0, Ordering::Relaxed);
        LogDownload {
            entry,
            data: vec![0; size],
            got: vec![false; size.div_ceil(CHUNK_BYTES)],
            received: 0,
            progress,
            last_data: now,
            last_progress: now,
            requested_end: size.div_ceil(CHUNK_BYTES),
        }
    }

    /// The log being downloaded.
    pub fn entry(&self) -> LogEntry {
        self.entry
    }

    /// Takes one `LOG_DATA` heard at `now` (another log's, or one not on a chunk
    /// boundary or past the end, is ignored); true once every byte is there.
    pub fn on_data(&mut self, d: &LOG_DATA_DATA, now: Instant) -> bool {
        let ofs = d.ofs as usize;
        let count = usize::from(d.count).min(CHUNK_BYTES);
        if d.id != self.entry.id
            || !ofs.is_multiple_of(CHUNK_BYTES)
            || ofs + count > self.data.len()
        {
            return self.is_complete();
        }
        self.last_data = now;
        let chunk = ofs / CHUNK_BYTES;
        let expected = (self.data.len() - ofs).min(CHUNK_BYTES);
        if count == expected && !self.got[chunk] {
            self.data[ofs..ofs + count].copy_from_slice(&d.data[..count]);
            self.got[chunk] = true;
            self.received += count;
            self.last_progress = now;
            self.progress.store(self.received as u64, Ordering::Relaxed);
        }
        if chunk + 1 == self.requested_end {
            // The range asked for has ended: its gaps need not wait.
            self.last_data = now.checked_sub(GAP_TIMEOUT).unwrap_or(now);
        }
        self.is_complete()
    }

    /// Every byte arrived.
    pub fn is_complete(&self) -> bool {
        self.received == self.data.len()
    }

    /// The first gap at `now`, as `(ofs, count)` for `LOG_REQUEST_DATA`, once the range
    /// asked for ended or nothing arrived for [`GAP_TIMEOUT`]; `None` while data flows
    /// or nothing is missing.
    pub fn gap_to_request(&self, now: Instant) -> Option<(u32, u32)> {
        if self.is_complete() || now.saturating_duration_since(self.last_data) < GAP_TIMEOUT {
            return None;
        }
        let first = self.got.iter().position(|g| !g)?;
        let run = self.got[first..].iter().take_while(|g| !**g).count();
        let ofs = first * CHUNK_BYTES;
        let count = (run * CHUNK_BYTES).min(self.data.len() - ofs);
        Some((ofs as u32, count as u32))
    }

    /// Marks the request of `(ofs, count)` sent at `now` (the next one waits for its
    /// end or [`GAP_TIMEOUT`]).
    pub fn requested(&mut self, now: Instant, (ofs, count): (u32, u32)) {
        self.last_data = now;
        self.requested_end = (ofs as usize + count as usize).div_ceil(CHUNK_BYTES);
    }

    /// No byte gained for [`STALL_TIMEOUT`] at `now`.
    pub fn stalled(&self, now: Instant) -> bool {
        now.saturating_duration_since(self.last_progress) >= STALL_TIMEOUT
    }

    /// The log's bytes (complete only when [`LogDownload::is_complete`]).
    pub fn into_bytes(self) -> Vec<u8> {
        self.data
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(id: u16, num_logs: u16, size: u32) -> LOG_ENTRY_DATA {
        LOG_ENTRY_DATA {
            time_utc: 1_790_000_000,
            size,
            id,
            num_logs,
            last_log_num: num_logs.saturating_sub(1),
        }
    }

    fn chunk(log: &[u8], id: u16, ofs: usize) -> LOG_DATA_DATA {
        let count = (log.len() - ofs).min(CHUNK_BYTES);
        let mut data = [0u8; CHUNK_BYTES];
        data[..count].copy_from_slice(&log[ofs..ofs + count]);
        LOG_DATA_DATA {
            ofs: ofs as u32,
            id,
            count: count as u8,
            data,
        }
    }

    #[test]
    fn a_listing_is_complete_with_every_entry_or_an_empty_vehicle() {
        let mut l = LogListing::default();
        assert!(!l.on_entry(&entry(0, 2, 100)));
        assert!(l.on_entry(&entry(1, 2, 200)));
        assert_eq!(
            l.entries().iter().map(|e| e.size_bytes).collect::<Vec<_>>(),
            [100, 200]
        );
        let mut empty = LogListing::default();
        assert!(empty.on_entry(&entry(0, 0, 0)));
        assert!(empty.entries().is_empty());
    }

    #[test]
    fn lost_chunks_are_asked_for_again_and_the_bytes_come_out_whole() {
        let log: Vec<u8> = (0..1000u32).map(|i| (i * 7 % 251) as u8).collect();
        let e = LogEntry {
            id: 3,
            size_bytes: log.len() as u32,
            time_utc: 0,
        };
        let progress = Arc::new(AtomicU64::new(0));
        let t0 = Instant::now();
        let mut d = LogDownload::new(e, progress.clone(), t0);
        // Chunks 2 and 3 (ofs 180, 270) and the last one are lost.
        for ofs in (0..log.len()).step_by(CHUNK_BYTES) {
            if ![180, 270, 990].contains(&ofs) {
                assert!(!d.on_data(&chunk(&log, 3, ofs), t0));
            }
        }
        assert_eq!(progress.load(Ordering::Relaxed), 1000 - 180 - 10);
        assert_eq!(
            d.gap_to_request(t0),
            None,
            "the range's last chunk was lost"
        );
        let later = t0 + GAP_TIMEOUT;
        assert_eq!(d.gap_to_request(later), Some((180, 180)));
        d.requested(later, (180, 180));
        assert_eq!(d.gap_to_request(later), None);
        assert!(!d.on_data(&chunk(&log, 3, 180), later));
        assert_eq!(d.gap_to_request(later), None, "ofs 270 is still to come");
        assert!(
            !d.on_data(&chunk(&log, 3, 180), later),
            "a duplicate changes nothing"
        );
        assert!(
            !d.on_data(&chunk(&log, 9, 270), later),
            "another log's chunk"
        );
        assert!(!d.on_data(&chunk(&log, 3, 270), later));
        // The range asked for ended: the next gap goes at once.
        assert_eq!(d.gap_to_request(later), Some((990, 10)));
        assert!(d.on_data(&chunk(&log, 3, 990), later));
        assert_eq!(d.into_bytes(), log);
    }

    #[test]
    fn a_download_without_progress_stalls() {
        let e = LogEntry {
            id: 0,
            size_bytes: 500,
            time_utc: 0,
        };
        let t0 = Instant::now();
        let d = LogDownload::new(e, Arc::default(), t0);
        assert!(!d.stalled(t0 + STALL_TIMEOUT / 2));
        assert!(d.stalled(t0 + STALL_TIMEOUT));
    }
}
