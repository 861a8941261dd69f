//! Events of the last few seconds (frames decoded, frames published): how many per
//! second, when the last one was, and what they carried.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// The events of the last `window`, oldest first, each with a value (`()` for none).
#[derive(Debug, Clone)]
pub struct Recent<T> {
    window: Duration,
    events: VecDeque<(Instant, T)>,
}

impl<T> Recent<T> {
    /// No events yet; those older than `window` behind the newest are forgotten.
    pub fn new(window: Duration) -> Self {
        Recent {
            window,
            events: VecDeque::new(),
        }
    }

    /// Adds an event at `at` (not before the last one) carrying `value`.
    pub fn push(&mut self, at: Instant, value: T) {
        self.events.push_back((at, value));
        while self
            .events
            .front()
            .is_some_and(|(t, _)| at.duration_since(*t) > self.window)
        {
            self.events.pop_front();
        }
    }

    /// Events per second over the span they cover; `None` with fewer than two, or all at
    /// one instant.
    pub fn rate_hz(&self) -> Option<f64> {
        let ((first, _), (last, _)) = (self.events.front()?, self.events.back()?);
        (last > first)
            .then(|| (self.events.len() - 1) as f64 / last.duration_since(*first).as_secs_f64())
    }

    /// When the newest event was.
    pub fn last_at(&self) -> Option<Instant> {
        self.events.back().map(|(t, _)| *t)
    }

    /// The events' values, oldest first.
    pub fn values(&self) -> impl ExactSizeIterator<Item = &T> {
        self.events.iter().map(|(_, v)| v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_the_rate_over_the_window_and_forgets_older_events() {
        let t0 = Instant::now();
        let mut r = Recent::new(Duration::from_secs(3));
        assert_eq!((r.rate_hz(), r.last_at()), (None, None));
        r.push(t0, 10);
        assert_eq!(r.rate_hz(), None);
        for i in 1..=40 {
            r.push(t0 + Duration::from_millis(100 * i), 10 + i);
        }
        // 4 s of events at 10 Hz: the last 3 s (31 events) kept.
        assert_eq!(r.values().len(), 31);
        assert!((r.rate_hz().unwrap() - 10.0).abs() < 1e-9);
        assert_eq!(r.last_at(), Some(t0 + Duration::from_millis(4000)));
        assert_eq!(r.values().next(), Some(&20));
    }
}
