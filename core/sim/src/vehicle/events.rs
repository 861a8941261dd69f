//! PX4's events interface, vehicle side (`src/modules/mavlink/mavlink_events.cpp`):
//! every event gets the next 16-bit sequence number and goes out as an `EVENT`
//! (broadcast: destination 0 / `MAV_COMP_ID_ALL`), kept in a buffer of the last
//! [`EVENT_BUFFER`] events; `CURRENT_EVENT_SEQUENCE` goes out every
//! [`CURRENT_SEQUENCE_PERIOD`] (with the reset flag while the buffer is empty, as after
//! a boot) and when a ground station connects; `REQUEST_EVENT {first, last}` is answered
//! with each event still held, and `RESPONSE_EVENT_ERROR` (reason `UNAVAILABLE`, the
//! oldest sequence still held) for each one no longer held, addressed to the requester.
//! The `EVENT` is the same whether or not a ground station is connected (unlike
//! `STATUSTEXT`).

use super::*;
use crate::px4_events::EventDef;
use skein_mavlink::events::log_levels;

/// Events PX4's buffer holds (`EventBuffer`'s default capacity).
pub const EVENT_BUFFER: usize = 20;
/// Period of `CURRENT_EVENT_SEQUENCE` (PX4: 3 s).
pub const CURRENT_SEQUENCE_PERIOD: Duration = Duration::from_secs(3);

/// The events sent so far and the sequence.
#[derive(Debug, Default)]
pub(crate) struct EventLog {
    buffer: VecDeque<EVENT_DATA>,
    pub(super) next_sequence: u16,
    last_current_sequence: Option<Instant>,
    /// Events sent (the stats).
    pub sent: u64,
}

impl EventLog {
    fn current_sequence(&self) -> MavMessage {
        let reset = self.buffer.is_empty();
        MavMessage::CURRENT_EVENT_SEQUENCE(CURRENT_EVENT_SEQUENCE_DATA {
            sequence: self.next_sequence.wrapping_sub(1),
            flags: if reset {
                MavEventCurrentSequenceFlags::MAV_EVENT_CURRENT_SEQUENCE_FLAGS_RESET
            } else {
                MavEventCurrentSequenceFlags::empty()
            },
        })
    }

    fn held(&self, sequence: u16) -> Option<&EVENT_DATA> {
        self.buffer.iter().find(|e| e.sequence == sequence)
    }

    /// The oldest sequence after `sequence` still held (PX4's
    /// `get_oldest_sequence_after`, wrap-around aware).
    fn oldest_after(&self, sequence: u16) -> u16 {
        self.buffer
            .iter()
            .map(|e| e.sequence)
            .filter(|&s| s != sequence)
            .min_by_key(|&s| s.wrapping_sub(sequence))
            .unwrap_or(self.next_sequence.wrapping_sub(1))
    }
}

/// The little-endian bytes of an event's arguments, packed as PX4 packs them.
pub(crate) fn args(parts: &[&[u8]]) -> [u8; 40] {
    let mut a = [0u8; 40];
    let mut at = 0;
    for p in parts {
        let n = p.len().min(40 - at);
        a[at..at + n].copy_from_slice(&p[..n]);
        at += n;
    }
    a
}

impl Vehicle {
    /// Sends event `def` with `arguments` (packed, [`args`]) at `now`.
    pub(crate) fn send_event(
        &mut self,
        now: Instant,
        def: &EventDef,
        arguments: [u8; 40],
        out: &mut Outbox,
    ) {
        let e = EVENT_DATA {
            id: def.id(),
            event_time_boot_ms: self.time_boot_ms(now),
            sequence: self.events.next_sequence,
            destination_component: 0,
            destination_system: 0,
            log_levels: log_levels(def.level, def.internal),
            arguments,
        };
        self.events.next_sequence = self.events.next_sequence.wrapping_add(1);
        if self.events.buffer.len() == EVENT_BUFFER {
            self.events.buffer.pop_front();
        }
        self.events.buffer.push_back(e.clone());
        self.events.sent += 1;
        if self.drop_next_events > 0 {
            self.drop_next_events -= 1; // lost on the way (a test's loss)
        } else {
            out.push(&MavMessage::EVENT(e));
        }
    }

    /// A text PX4 logs and also sends as an event: the `STATUSTEXT` with PX4's trailing
    /// tab (the mark that an event says the same), then the event.
    pub(crate) fn say(
        &mut self,
        now: Instant,
        severity: MavSeverity,
        def: &EventDef,
        text: &str,
        arguments: [u8; 40],
        out: &mut Outbox,
    ) {
        self.statustext(now, severity, &format!("{text}\t"), out);
        self.send_event(now, def, arguments, out);
    }

    /// Every step: `CURRENT_EVENT_SEQUENCE` when it is due.
    pub(crate) fn events_tick(&mut self, now: Instant, out: &mut Outbox) {
        let due = self
            .events
            .last_current_sequence
            .is_none_or(|t| now.saturating_duration_since(t) >= CURRENT_SEQUENCE_PERIOD);
        if due {
            self.send_current_sequence(now, out);
        }
    }

    /// `CURRENT_EVENT_SEQUENCE` now (also when a ground station connects).
    pub(crate) fn send_current_sequence(&mut self, now: Instant, out: &mut Outbox) {
        self.events.last_current_sequence = Some(now);
        out.push(&self.events.current_sequence());
    }

    /// `REQUEST_EVENT` from `from`: each event of the range still held, an error for
    /// each one not.
    pub(crate) fn on_request_event(
        &mut self,
        r: &REQUEST_EVENT_DATA,
        from: (u8, u8),
        out: &mut Outbox,
    ) {
        let end = r.last_sequence.wrapping_add(1);
        let mut sequence = r.first_sequence;
        let requested = end.wrapping_sub(sequence) as usize;
        if requested > EVENT_BUFFER {
            // Only the newest EVENT_BUFFER can be held: one error for the older part.
            self.event_unavailable(sequence, from, out);
            sequence = end.wrapping_sub(EVENT_BUFFER as u16);
        }
        while sequence != end {
            match self.events.held(sequence) {
                Some(e) => out.push(&MavMessage::EVENT(e.clone())),
                None => self.event_unavailable(sequence, from, out),
            }
            sequence = sequence.wrapping_add(1);
        }
    }

    fn event_unavailable(&self, sequence: u16, from: (u8, u8), out: &mut Outbox) {
        out.push(&MavMessage::RESPONSE_EVENT_ERROR(
            RESPONSE_EVENT_ERROR_DATA {
                sequence,
                sequence_oldest_available: self.events.oldest_after(sequence),
                target_system: from.0,
                target_component: from.1,
                reason: MavEventErrorReason::MAV_EVENT_ERROR_REASON_UNAVAILABLE,
            },
        ));
    }
}
