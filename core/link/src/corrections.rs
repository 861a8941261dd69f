//! GNSS corrections to one vehicle: RTCM3 messages, already cut into MAVLink
//! `GPS_RTCM_DATA` fragments (`skein_rtk::fragment`), queued under a byte-rate cap and
//! sent paced, and what was sent counted for the vehicle's snapshot.
//!
//! PX4 hands every `GPS_RTCM_DATA` to its GPS driver as it arrives, through the uORB queue
//! `gps_inject_data` of 8 entries, which the driver empties at most every 50 ms
//! (`GPS_DRIVER_CYCLE`); a ninth fragment within that time overwrites the oldest, and the
//! RTCM message it belonged to is lost at the receiver (PX4 pull request 26042). An epoch
//! of a four-constellation MSM7 base is a dozen fragments at once, so the link sends at
//! most [`PACE_FRAGMENTS`] fragments per [`PACE_PERIOD`] to each vehicle
//! ([`CorrectionsLink::pump`]), the rest waiting in order.
//!
//! The cap ([`CorrectionsLink::offer`]) keeps corrections from crowding out telemetry and
//! setpoints on a thin link (a 57600-baud telemetry radio carries about 5.7 kB/s, a 50 Hz
//! setpoint stream about 3 kB/s of it): a message that does not fit in the vehicle's
//! budget is dropped whole and counted, never sent in part.

use skein_mavlink::MavMessage;
use skein_mavlink::dialect::GPS_RTCM_DATA_DATA;
use std::collections::VecDeque;
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// At most this many fragments go to one vehicle per [`PACE_PERIOD`]: half of PX4's
/// `gps_inject_data` queue (8), so one driver cycle never finds it overrun.
pub const PACE_FRAGMENTS: usize = 4;

/// PX4's GPS driver empties its inject queue at least this often (`GPS_DRIVER_CYCLE`).
pub const PACE_PERIOD: Duration = Duration::from_millis(50);

/// Bytes on the wire of one `GPS_RTCM_DATA` fragment carrying `len` bytes: MAVLink 2's
/// 10-byte header and 2-byte checksum, the 2 bytes of `flags` and `len`, the data (the
/// payload's trailing zeros truncated; a full 180-byte fragment carries all of them).
pub fn fragment_wire_bytes(len: usize) -> usize {
    12 + 2 + len.max(1)
}

/// What was sent to one vehicle, for its snapshot.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CorrectionsSent {
    /// When the last RTCM message went to the vehicle whole (Unix milliseconds); `None`
    /// before the first.
    pub last_unix_ms: Option<u64>,
    /// RTCM messages sent.
    pub messages: u64,
    /// RTCM bytes sent (the messages themselves, not the MAVLink framing).
    pub bytes: u64,
    /// Messages dropped because they did not fit the rate cap.
    pub dropped_over_cap: u64,
    /// Messages dropped because the endpoint refused a fragment (no address yet, full
    /// queue).
    pub dropped_send: u64,
}

/// One RTCM message waiting to go, and how far it went.
#[derive(Debug)]
struct Queued {
    fragments: Vec<GPS_RTCM_DATA_DATA>,
    next: usize,
    rtcm_len: usize,
    failed: bool,
}

#[derive(Debug, Default)]
struct State {
    tokens: f64,
    refilled: Option<Instant>,
    queue: VecDeque<Queued>,
    /// The start of the current pacing window and the fragments sent in it.
    window: Option<(Instant, usize)>,
    sent: CorrectionsSent,
}

/// Corrections to one vehicle: its rate budget, its paced queue and its counters (a field
/// of [`VehicleLink`](crate::VehicleLink), so a restarted link actor keeps them).
#[derive(Debug, Default)]
pub struct CorrectionsLink {
    state: Mutex<State>,
}

/// The longest burst a budget holds: one second of the cap, and never less than the
/// largest message (four full fragments), so a cap below one message a second still
/// lets messages through at its average rate.
fn burst_bytes(cap_bytes_s: f64) -> f64 {
    cap_bytes_s.max(fragment_wire_bytes(180) as f64 * 4.0)
}

impl CorrectionsLink {
    fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Queues one RTCM message's fragments if the vehicle's budget of `cap_bytes_s` bytes
    /// a second (MAVLink framing included) holds them all at `now`; otherwise drops the
    /// message whole. `rtcm_len` is the RTCM message's own length. Returns whether it was
    /// queued; [`CorrectionsLink::pump`] sends it.
    pub fn offer(
        &self,
        fragments: Vec<GPS_RTCM_DATA_DATA>,
        rtcm_len: usize,
        cap_bytes_s: f64,
        now: Instant,
    ) -> bool {
        let cost: usize = fragments
            .iter()
            .map(|f| fragment_wire_bytes(usize::from(f.len)))
            .sum();
        let mut s = self.lock();
        let burst = burst_bytes(cap_bytes_s);
        s.tokens = match s.refilled {
            // A fresh budget holds one burst.
            None => burst,
            Some(t) => {
                let elapsed = now.saturating_duration_since(t).as_secs_f64();
                (s.tokens + elapsed * cap_bytes_s).min(burst)
            }
        };
        s.refilled = Some(now);
        if (cost as f64) > s.tokens {
            s.sent.dropped_over_cap += 1;
            return false;
        }
        s.tokens -= cost as f64;
        s.queue.push_back(Queued {
            fragments,
            next: 0,
            rtcm_len,
            failed: false,
        });
        true
    }

    /// Sends what the pacing allows at `now` through `send` (each fragment as a
    /// `GPS_RTCM_DATA`; false: refused). Returns whether fragments are still waiting.
    pub fn pump(&self, now: Instant, mut send: impl FnMut(&MavMessage) -> bool) -> bool {
        let mut s = self.lock();
        let (start, used) = match s.window {
            Some((start, used)) if now.saturating_duration_since(start) < PACE_PERIOD => {
                (start, used)
            }
            _ => (now, 0),
        };
        let mut used = used;
        while used < PACE_FRAGMENTS {
            let Some(q) = s.queue.front_mut() else {
                break;
            };
            let f = q.fragments[q.next].clone();
            q.failed |= !send(&MavMessage::GPS_RTCM_DATA(f));
            q.next += 1;
            used += 1;
            if q.next == q.fragments.len() {
                let done = s.queue.pop_front().expect("the front message");
                s.finished(&done);
            }
        }
        s.window = Some((start, used));
        !s.queue.is_empty()
    }

    /// What was sent so far.
    pub fn sent(&self) -> CorrectionsSent {
        self.lock().sent
    }
}

impl State {
    fn finished(&mut self, q: &Queued) {
        if q.failed {
            self.sent.dropped_send += 1;
            return;
        }
        self.sent.messages += 1;
        self.sent.bytes += q.rtcm_len as u64;
        self.sent.last_unix_ms = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .ok()
            .map(|d| d.as_millis() as u64);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fragment(len: u8) -> GPS_RTCM_DATA_DATA {
        GPS_RTCM_DATA_DATA {
            flags: 0,
            len,
            data: [0; 180],
        }
    }

    fn full() -> Vec<GPS_RTCM_DATA_DATA> {
        vec![fragment(180); 4]
    }

    #[test]
    fn a_message_over_the_budget_is_dropped_whole_and_counted() {
        let link = CorrectionsLink::default();
        let t0 = Instant::now();
        // A fresh budget holds one burst (four full fragments at least).
        assert!(link.offer(full(), 720, 100.0, t0));
        // Empty now: the next message is dropped, none of its fragments queued.
        assert!(!link.offer(full(), 720, 100.0, t0));
        let mut sent = 0;
        assert!(!link.pump(t0, |_| {
            sent += 1;
            true
        }));
        assert_eq!(sent, 4);
        let s = link.sent();
        assert_eq!((s.messages, s.bytes, s.dropped_over_cap), (1, 720, 1));
        assert!(s.last_unix_ms.is_some());
    }

    #[test]
    fn the_budget_refills_at_the_cap() {
        let link = CorrectionsLink::default();
        let t0 = Instant::now();
        let cost = fragment_wire_bytes(100) as f64;
        let cap = 1000.0;
        let mut n = 0;
        while link.offer(vec![fragment(100)], 100, cap, t0) {
            n += 1;
        }
        assert_eq!(n, (burst_bytes(cap) / cost) as usize);
        // One second later, one second of the cap is back.
        let later = t0 + Duration::from_secs(1);
        let mut m = 0;
        while link.offer(vec![fragment(100)], 100, cap, later) {
            m += 1;
        }
        assert_eq!(m, (cap / cost) as usize);
    }

    #[test]
    fn fragments_are_paced_to_four_per_driver_cycle_in_order() {
        let link = CorrectionsLink::default();
        let t0 = Instant::now();
        // An epoch of three messages: 4 + 4 + 2 fragments.
        for (i, n) in [4u8, 4, 2].into_iter().enumerate() {
            let frags = (0..n)
                .map(|k| GPS_RTCM_DATA_DATA {
                    flags: (i as u8) << 3 | k << 1 | 1,
                    ..fragment(180)
                })
                .collect();
            assert!(link.offer(frags, 180 * usize::from(n), 1e6, t0));
        }
        let mut order = Vec::new();
        let pump = |at: Instant, order: &mut Vec<u8>| {
            link.pump(at, |m| {
                if let MavMessage::GPS_RTCM_DATA(d) = m {
                    order.push(d.flags);
                }
                true
            })
        };
        assert!(pump(t0, &mut order));
        assert!(pump(t0 + Duration::from_millis(30), &mut order));
        assert_eq!(order.len(), 4, "one window: four fragments");
        assert!(pump(t0 + PACE_PERIOD, &mut order));
        assert!(!pump(t0 + PACE_PERIOD * 2, &mut order));
        assert_eq!(order.len(), 10);
        let mut sorted = order.clone();
        sorted.sort();
        assert_eq!(order, sorted, "in order");
        assert_eq!(link.sent().messages, 3);
    }

    #[test]
    fn a_refused_fragment_counts_the_message_as_not_sent() {
        let link = CorrectionsLink::default();
        let t0 = Instant::now();
        assert!(link.offer(vec![fragment(10)], 10, 1e6, t0));
        link.pump(t0, |_| false);
        let s = link.sent();
        assert_eq!((s.messages, s.dropped_send), (0, 1));
        assert_eq!(s.last_unix_ms, None);
    }
}
