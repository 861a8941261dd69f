//! Simulated link quality of one vehicle: a loss fraction and a latency applied to every
//! datagram in both directions (what a thin telemetry radio does to MAVLink).
//!
//! Loss is drawn per datagram from the vehicle's own seeded generator, so a run with the
//! same seed and the same traffic drops the same datagrams. Latency queues datagrams
//! with their due time in two FIFO delay lines (one per direction) that the vehicle's
//! receive task drains when they fall due: no task or timer per datagram. A datagram is
//! never due before the one queued ahead of it in its direction, so lowering the latency
//! at run time never reorders traffic.

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use std::collections::VecDeque;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::Notify;

/// A datagram waiting in a delay line.
pub(crate) struct Delayed {
    /// When it may go.
    pub due: Instant,
    /// When it entered the line (for the effective latency).
    pub queued: Instant,
    /// Sender (inbound) or destination (outbound).
    pub addr: SocketAddr,
    pub bytes: Vec<u8>,
}

/// Counters of the impairment (since start or the last reset).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct ImpairmentCounters {
    /// Datagrams that went through the loss draw (both directions).
    pub considered: u64,
    /// Datagrams dropped by the loss draw (both directions).
    pub dropped: u64,
    /// Of those, datagrams to the vehicle.
    pub dropped_inbound: u64,
    /// Delayed datagrams delivered (both directions).
    pub delayed: u64,
    /// Sum of the actual delays of the delivered delayed datagrams, µs.
    pub delay_sum_us: u64,
}

/// Link quality and delay lines of one vehicle.
pub(crate) struct Impairment {
    loss_fraction: f64,
    latency: Duration,
    rng: SmallRng,
    inbound: VecDeque<Delayed>,
    outbound: VecDeque<Delayed>,
    /// Wakes the receive task when an outbound datagram enters an empty delay line (its
    /// due time is then the earliest).
    pub wake: Arc<Notify>,
    pub counters: ImpairmentCounters,
}

impl Impairment {
    /// A perfect link; `seed` feeds the loss draws.
    pub fn new(seed: u64) -> Self {
        Impairment {
            loss_fraction: 0.0,
            latency: Duration::ZERO,
            rng: SmallRng::seed_from_u64(seed),
            inbound: VecDeque::new(),
            outbound: VecDeque::new(),
            wake: Arc::new(Notify::new()),
            counters: ImpairmentCounters::default(),
        }
    }

    /// Sets the loss fraction (clamped to 0..=1; not a number = 0) and the one-way latency
    /// in ms (negative or not a number = 0).
    pub fn set(&mut self, loss_fraction: f64, latency_ms: f64) {
        self.loss_fraction = if loss_fraction.is_nan() {
            0.0
        } else {
            loss_fraction.clamp(0.0, 1.0)
        };
        self.latency = if latency_ms.is_finite() && latency_ms > 0.0 {
            Duration::from_secs_f64(latency_ms / 1e3)
        } else {
            Duration::ZERO
        };
    }

    /// Configured loss fraction (0..=1).
    pub fn loss_fraction(&self) -> f64 {
        self.loss_fraction
    }

    /// Configured one-way latency, ms.
    pub fn latency_ms(&self) -> f64 {
        self.latency.as_secs_f64() * 1e3
    }

    /// Measured loss fraction: dropped / considered (0 before any datagram).
    pub fn effective_loss(&self) -> f64 {
        let c = &self.counters;
        if c.considered == 0 {
            0.0
        } else {
            c.dropped as f64 / c.considered as f64
        }
    }

    /// Measured mean delay of the delayed datagrams delivered, ms (0 before any).
    pub fn effective_latency_ms(&self) -> f64 {
        let c = &self.counters;
        if c.delayed == 0 {
            0.0
        } else {
            c.delay_sum_us as f64 / c.delayed as f64 / 1e3
        }
    }

    /// Datagrams waiting in the delay lines.
    pub fn in_flight(&self) -> usize {
        self.inbound.len() + self.outbound.len()
    }

    /// Draws whether the next datagram (to the vehicle when `inbound`) is lost, and
    /// counts it.
    pub fn lose(&mut self, inbound: bool) -> bool {
        self.counters.considered += 1;
        let lost = self.loss_fraction > 0.0
            && (self.loss_fraction >= 1.0 || self.rng.random::<f64>() < self.loss_fraction);
        if lost {
            self.counters.dropped += 1;
            self.counters.dropped_inbound += u64::from(inbound);
        }
        lost
    }

    fn due(line: &VecDeque<Delayed>, now: Instant, latency: Duration) -> Instant {
        let due = now.checked_add(latency).unwrap_or(now);
        line.back().map_or(due, |last| due.max(last.due))
    }

    /// True when an inbound datagram must go through the delay line (latency set, or
    /// earlier ones still waiting: order is kept).
    pub fn delays_inbound(&self) -> bool {
        !self.latency.is_zero() || !self.inbound.is_empty()
    }

    /// True when an outbound datagram must go through the delay line.
    pub fn delays_outbound(&self) -> bool {
        !self.latency.is_zero() || !self.outbound.is_empty()
    }

    /// Queues a received datagram.
    pub fn push_inbound(&mut self, now: Instant, addr: SocketAddr, bytes: &[u8]) {
        let due = Self::due(&self.inbound, now, self.latency);
        self.inbound.push_back(Delayed {
            due,
            queued: now,
            addr,
            bytes: bytes.to_vec(),
        });
    }

    /// Queues a datagram to send; wakes the receive task if the line was empty.
    pub fn push_outbound(&mut self, now: Instant, addr: SocketAddr, bytes: &[u8]) {
        let due = Self::due(&self.outbound, now, self.latency);
        let was_empty = self.outbound.is_empty();
        self.outbound.push_back(Delayed {
            due,
            queued: now,
            addr,
            bytes: bytes.to_vec(),
        });
        if was_empty {
            self.wake.notify_one();
        }
    }

    fn pop_due(line: &mut VecDeque<Delayed>, now: Instant) -> Option<Delayed> {
        if line.front().is_some_and(|d| d.due <= now) {
            line.pop_front()
        } else {
            None
        }
    }

    fn delivered(&mut self, d: &Delayed, now: Instant) {
        self.counters.delayed += 1;
        self.counters.delay_sum_us += now.saturating_duration_since(d.queued).as_micros() as u64;
    }

    /// The next inbound datagram due at `now`, if any.
    pub fn pop_inbound(&mut self, now: Instant) -> Option<Delayed> {
        let d = Self::pop_due(&mut self.inbound, now)?;
        self.delivered(&d, now);
        Some(d)
    }

    /// The next outbound datagram due at `now`, if any.
    pub fn pop_outbound(&mut self, now: Instant) -> Option<Delayed> {
        let d = Self::pop_due(&mut self.outbound, now)?;
        self.delivered(&d, now);
        Some(d)
    }

    /// The earliest due time in either line.
    pub fn next_due(&self) -> Option<Instant> {
        let a = self.inbound.front().map(|d| d.due);
        let b = self.outbound.front().map(|d| d.due);
        match (a, b) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn addr() -> SocketAddr {
        "127.0.0.1:1".parse().expect("addr")
    }

    #[test]
    fn loss_is_seeded_and_near_the_fraction() {
        let draws = |seed| {
            let mut i = Impairment::new(seed);
            i.set(0.5, 0.0);
            (0..10_000).map(|_| i.lose(false)).collect::<Vec<_>>()
        };
        let a = draws(7);
        assert_eq!(a, draws(7), "same seed, same drops");
        assert_ne!(a, draws(8));
        let lost = a.iter().filter(|l| **l).count();
        assert!((4_800..=5_200).contains(&lost), "{lost}");
        let mut i = Impairment::new(1);
        i.set(f64::NAN, -3.0);
        assert!(!i.lose(true));
        assert_eq!((i.loss_fraction(), i.latency_ms()), (0.0, 0.0));
        i.set(2.0, f64::INFINITY);
        assert!(i.lose(true));
        assert_eq!(i.effective_loss(), 0.5);
        assert_eq!(i.counters.dropped_inbound, 1);
    }

    #[test]
    fn delay_lines_keep_order_when_the_latency_drops() {
        let t0 = Instant::now();
        let mut i = Impairment::new(0);
        i.set(0.0, 200.0);
        i.push_outbound(t0, addr(), b"first");
        i.set(0.0, 0.0);
        assert!(i.delays_outbound(), "queue not empty: keep order");
        i.push_outbound(t0, addr(), b"second");
        assert_eq!(i.next_due(), Some(t0 + Duration::from_millis(200)));
        assert!(i.pop_outbound(t0 + Duration::from_millis(199)).is_none());
        let t1 = t0 + Duration::from_millis(200);
        assert_eq!(i.pop_outbound(t1).expect("due").bytes, b"first");
        assert_eq!(i.pop_outbound(t1).expect("due").bytes, b"second");
        assert!(!i.delays_outbound());
        assert!((i.effective_latency_ms() - 200.0).abs() < 1e-6);
        i.set(0.0, 50.0);
        i.push_inbound(t1, addr(), b"in");
        assert_eq!(i.in_flight(), 1);
        assert_eq!(i.next_due(), Some(t1 + Duration::from_millis(50)));
    }
}
