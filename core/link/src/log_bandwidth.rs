//! One byte-rate cap shared by every flight-log download of the process (`[logs]
//! max_bytes_s`): a crew bringing every aircraft's log home at once over one WLAN keeps
//! it for telemetry and setpoints. Without a cap a download asks PX4 for the whole log and
//! takes it at whatever rate the autopilot sends; with one, each download asks for one
//! window of the log per [`LOG_TICK`](crate::px4link::LOG_TICK), of the cap's share of the
//! downloads running now (`max_bytes_s × tick / downloads`), and the next window only when
//! the last one arrived, so the downloads together stay under the cap and share it evenly.

use crate::log_transfer::CHUNK_BYTES;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

#[derive(Debug, Default)]
struct Shared {
    cap_bytes_s: Option<f64>,
    running: AtomicUsize,
}

/// The cap shared by the downloads (see the module docs). Clones share it: every
/// vehicle's link gets a clone of the one in the swarm's link setup. Serialised as the cap
/// in bytes/s (`null`: none).
#[derive(Debug, Clone, Default)]
pub struct LogBandwidth {
    shared: Arc<Shared>,
}

impl LogBandwidth {
    /// A cap of `max_bytes_s` bytes a second over every download (`None`: none).
    pub fn new(max_bytes_s: Option<f64>) -> Self {
        LogBandwidth {
            shared: Arc::new(Shared {
                cap_bytes_s: max_bytes_s.filter(|c| c.is_finite() && *c > 0.0),
                running: AtomicUsize::new(0),
            }),
        }
    }

    /// The cap, bytes/s.
    pub fn cap_bytes_s(&self) -> Option<f64> {
        self.shared.cap_bytes_s
    }

    /// A download starts: it holds its share until the [`LogShare`] is dropped.
    pub fn join(&self) -> LogShare {
        self.shared.running.fetch_add(1, Ordering::Relaxed);
        LogShare {
            shared: self.shared.clone(),
        }
    }

    /// Downloads running now.
    pub fn running(&self) -> usize {
        self.shared.running.load(Ordering::Relaxed)
    }
}

impl PartialEq for LogBandwidth {
    fn eq(&self, other: &Self) -> bool {
        self.cap_bytes_s() == other.cap_bytes_s()
    }
}

impl Serialize for LogBandwidth {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.cap_bytes_s().serialize(s)
    }
}

impl<'de> Deserialize<'de> for LogBandwidth {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        Ok(LogBandwidth::new(Option::<f64>::deserialize(d)?))
    }
}

/// One download's part of the cap, for as long as it runs.
#[derive(Debug)]
pub struct LogShare {
    shared: Arc<Shared>,
}

impl LogShare {
    /// The bytes this download may ask for per `tick`: the cap's share of the downloads
    /// running now, whole chunks, at least one; `None` without a cap.
    pub fn window_bytes(&self, tick: Duration) -> Option<u32> {
        let cap = self.shared.cap_bytes_s?;
        let running = self.shared.running.load(Ordering::Relaxed).max(1);
        let share = cap * tick.as_secs_f64() / running as f64;
        let chunks = (share / CHUNK_BYTES as f64).floor().max(1.0);
        Some((chunks * CHUNK_BYTES as f64) as u32)
    }
}

impl Drop for LogShare {
    fn drop(&mut self) {
        self.shared.running.fetch_sub(1, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TICK: Duration = Duration::from_millis(100);

    #[test]
    fn the_cap_is_shared_evenly_by_the_running_downloads() {
        let bw = LogBandwidth::new(Some(27_000.0));
        let a = bw.join();
        // Alone: 2700 bytes a tick, 30 chunks.
        assert_eq!(a.window_bytes(TICK), Some(2700));
        let b = bw.clone().join();
        let c = bw.join();
        assert_eq!(bw.running(), 3);
        // Three: 900 bytes each, 10 chunks.
        assert_eq!(a.window_bytes(TICK), Some(900));
        assert_eq!(c.window_bytes(TICK), Some(900));
        drop((b, c));
        assert_eq!(a.window_bytes(TICK), Some(2700));
    }

    #[test]
    fn a_tiny_cap_still_moves_a_chunk_and_none_is_unlimited() {
        let bw = LogBandwidth::new(Some(10.0));
        assert_eq!(bw.join().window_bytes(TICK), Some(90));
        assert_eq!(LogBandwidth::default().join().window_bytes(TICK), None);
        assert_eq!(LogBandwidth::new(Some(0.0)).cap_bytes_s(), None);
    }

    #[test]
    fn it_serialises_as_its_cap() {
        let bw = LogBandwidth::new(Some(5000.0));
        assert_eq!(serde_json::to_string(&bw).unwrap(), "5000.0");
        let back: LogBandwidth = serde_json::from_str("5000.0").unwrap();
        assert_eq!(back, bw);
        let none: LogBandwidth = serde_json::from_str("null").unwrap();
        assert_eq!(none, LogBandwidth::default());
    }
}
