//! The events' sequence, receiving side (libevents' `protocol/receive`): events are
//! handed on in sequence order, once each; a gap is asked for (`REQUEST_EVENT`) and the
//! events after it held until it is filled, the vehicle says its events are no longer
//! held (`RESPONSE_EVENT_ERROR`), or [`GAP_GIVE_UP`] passes. `CURRENT_EVENT_SEQUENCE`
//! shows events missed at the end (asked for), or a restarted sequence (its reset flag:
//! the vehicle rebooted). Sequence numbers are 16 bits and wrap.

use skein_mavlink::dialect::EVENT_DATA;
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// A gap not filled after this is skipped (its events are lost).
pub const GAP_GIVE_UP: Duration = Duration::from_secs(2);
/// A gap's request is sent again after this.
pub const REQUEST_RETRY: Duration = Duration::from_millis(500);
/// Events held behind a gap at most (the vehicle keeps 20).
const HELD_MAX: usize = 64;

/// What the sequence asks for: `REQUEST_EVENT {first, last}`.
pub type Request = (u16, u16);

fn ahead(a: u16, b: u16) -> i16 {
    a.wrapping_sub(b) as i16
}

/// The receiving side of one vehicle's events.
#[derive(Debug, Default)]
pub struct EventSequence {
    expected: Option<u16>,
    held: BTreeMap<u16, EVENT_DATA>,
    gap_since: Option<Instant>,
    requested_at: Option<Instant>,
    /// Events skipped as lost.
    pub lost: u64,
    /// Events requested again.
    pub requested: u64,
}

impl EventSequence {
    /// Starts over (the vehicle rebooted).
    pub fn reset(&mut self) {
        *self = EventSequence {
            lost: self.lost,
            requested: self.requested,
            ..Default::default()
        };
    }

    fn key(&self, seq: u16) -> u16 {
        seq.wrapping_sub(self.expected.unwrap_or(seq))
    }

    fn release(&mut self, ready: &mut Vec<EVENT_DATA>) {
        while let Some(e) = self.held.remove(&0) {
            self.expected = Some(e.sequence.wrapping_add(1));
            // Keys are relative to `expected`: shift them by one.
            self.held = std::mem::take(&mut self.held)
                .into_iter()
                .map(|(k, v)| (k.wrapping_sub(1), v))
                .collect();
            ready.push(e);
        }
        if self.held.is_empty() {
            self.gap_since = None;
            self.requested_at = None;
        }
    }

    fn gap_request(&mut self, now: Instant) -> Option<Request> {
        let exp = self.expected?;
        let (&first_held, _) = self.held.iter().next()?;
        self.gap_since.get_or_insert(now);
        if self
            .requested_at
            .is_some_and(|t| now.saturating_duration_since(t) < REQUEST_RETRY)
        {
            return None;
        }
        self.requested_at = Some(now);
        self.requested += u64::from(first_held);
        Some((exp, exp.wrapping_add(first_held).wrapping_sub(1)))
    }

    /// One `EVENT` at `now`: the events now ready (in order), and a request for a gap.
    pub fn on_event(&mut self, e: EVENT_DATA, now: Instant) -> (Vec<EVENT_DATA>, Option<Request>) {
        let mut ready = Vec::new();
        let Some(exp) = self.expected else {
            self.expected = Some(e.sequence.wrapping_add(1));
            ready.push(e);
            return (ready, None);
        };
        if ahead(e.sequence, exp) < 0 || self.held.len() >= HELD_MAX {
            return (ready, None); // a repeat, or too far behind a gap
        }
        let key = self.key(e.sequence);
        self.held.insert(key, e);
        self.release(&mut ready);
        (ready, self.gap_request(now))
    }

    /// `CURRENT_EVENT_SEQUENCE` (the vehicle's latest sequence; `reset` its flag).
    pub fn on_current(&mut self, latest: u16, reset: bool, now: Instant) -> Option<Request> {
        let Some(exp) = self.expected else {
            self.expected = Some(latest.wrapping_add(1));
            return None;
        };
        if reset && ahead(latest.wrapping_add(1), exp) != 0 {
            self.reset();
            self.expected = Some(latest.wrapping_add(1));
            return None;
        }
        if ahead(latest, exp) < 0 || !self.held.is_empty() {
            return None;
        }
        if self
            .requested_at
            .is_some_and(|t| now.saturating_duration_since(t) < REQUEST_RETRY)
        {
            return None;
        }
        self.requested_at = Some(now);
        self.requested += u64::from(latest.wrapping_sub(exp)) + 1;
        Some((exp, latest))
    }

    /// `RESPONSE_EVENT_ERROR`: `sequence` is not held any more, nor anything before
    /// `oldest_available`; the events now ready.
    pub fn on_unavailable(&mut self, sequence: u16, oldest_available: u16) -> Vec<EVENT_DATA> {
        let mut ready = Vec::new();
        let Some(exp) = self.expected else {
            return ready;
        };
        if ahead(sequence, exp) > 0 {
            return ready;
        }
        let skip_to = if ahead(oldest_available, exp) > 0 {
            oldest_available
        } else {
            exp.wrapping_add(1)
        };
        self.skip_to(skip_to, &mut ready);
        ready
    }

    fn skip_to(&mut self, to: u16, ready: &mut Vec<EVENT_DATA>) {
        let Some(exp) = self.expected else { return };
        let by = to.wrapping_sub(exp);
        let upto = self.held.keys().next().copied().map_or(by, |k| k.min(by));
        self.lost += u64::from(upto);
        self.expected = Some(exp.wrapping_add(upto));
        self.held = std::mem::take(&mut self.held)
            .into_iter()
            .map(|(k, v)| (k - upto, v))
            .collect();
        self.release(ready);
    }

    /// Time passes: a gap asked for again, or given up (the events after it ready).
    pub fn on_tick(&mut self, now: Instant) -> (Vec<EVENT_DATA>, Option<Request>) {
        let mut ready = Vec::new();
        let Some(since) = self.gap_since else {
            return (ready, None);
        };
        if now.saturating_duration_since(since) >= GAP_GIVE_UP {
            let first = self.held.keys().next().copied().unwrap_or(0);
            let to = self.expected.unwrap_or(0).wrapping_add(first);
            self.skip_to(to, &mut ready);
            return (ready, None);
        }
        (ready, self.gap_request(now))
    }
}
