//! The `Px4Link` actor's side of PX4's events ([`crate::events`]): `EVENT`s put in
//! sequence order (gaps asked for with `REQUEST_EVENT`), held until the metadata is
//! loaded ([`HELD_BEFORE_METADATA`] at most), then decoded: the health and arming check
//! report goes to the telemetry, the other events of a user-facing level (info or
//! worse) become the vehicle's messages, as a `STATUSTEXT` would (kept, told to the
//! commands in flight, sent on as [`super::LinkEvent::StatusText`]).

use super::{Px4LinkState, StatusText};
use crate::events::{DecodedEvent, EventSequence, EventsMetadata, HealthReportBuilder, decode};
use skein_mavlink::MavMessage;
use skein_mavlink::dialect::{
    CURRENT_EVENT_SEQUENCE_DATA, EVENT_DATA, MavEventCurrentSequenceFlags, REQUEST_EVENT_DATA,
    RESPONSE_EVENT_ERROR_DATA,
};
use std::collections::{HashMap, VecDeque};
use std::sync::Arc;
use std::time::Instant;

/// Events kept while the metadata is being read.
pub const HELD_BEFORE_METADATA: usize = 100;
/// The most verbose log level shown as a message (info).
const SHOWN_LEVEL: u8 = 6;

/// The events of one vehicle.
#[derive(Default)]
pub(super) struct EventsState {
    meta: Option<Arc<EventsMetadata>>,
    mode_groups: Arc<HashMap<u32, u8>>,
    sequence: EventSequence,
    waiting: VecDeque<EVENT_DATA>,
    health: HealthReportBuilder,
}

impl EventsState {
    /// The metadata is loaded: the vehicle speaks events (its tab-marked
    /// `STATUSTEXT`s say the same again).
    pub(super) fn has_metadata(&self) -> bool {
        self.meta.is_some()
    }
}

impl Px4LinkState {
    /// An event-protocol message from the autopilot; false for any other message.
    pub(super) fn on_events_message(&mut self, msg: &MavMessage) -> bool {
        let now = Instant::now();
        match msg {
            MavMessage::EVENT(e) => {
                self.link.with_telemetry_mut(|t| t.px4_events.received += 1);
                let (ready, request) = self.px4_events.sequence.on_event(e.clone(), now);
                self.request_events(request);
                self.events_ready(ready);
            }
            MavMessage::CURRENT_EVENT_SEQUENCE(CURRENT_EVENT_SEQUENCE_DATA { sequence, flags }) => {
                let reset = flags
                    .contains(MavEventCurrentSequenceFlags::MAV_EVENT_CURRENT_SEQUENCE_FLAGS_RESET);
                let request = self.px4_events.sequence.on_current(*sequence, reset, now);
                self.request_events(request);
            }
            MavMessage::RESPONSE_EVENT_ERROR(RESPONSE_EVENT_ERROR_DATA {
                sequence,
                sequence_oldest_available,
                ..
            }) => {
                let ready = self
                    .px4_events
                    .sequence
                    .on_unavailable(*sequence, *sequence_oldest_available);
                self.events_ready(ready);
            }
            _ => return false,
        }
        true
    }

    /// Every tick: a gap asked for again, or given up.
    pub(super) fn events_tick(&mut self) {
        let (ready, request) = self.px4_events.sequence.on_tick(Instant::now());
        self.request_events(request);
        self.events_ready(ready);
    }

    /// The vehicle rebooted: its sequence starts over.
    pub(super) fn events_rebooted(&mut self) {
        self.px4_events.sequence.reset();
        self.px4_events.health = HealthReportBuilder::default();
    }

    fn request_events(&mut self, request: Option<(u16, u16)>) {
        let Some((first_sequence, last_sequence)) = request else {
            return;
        };
        let (target_system, target_component) = self.target();
        let msg = MavMessage::REQUEST_EVENT(REQUEST_EVENT_DATA {
            first_sequence,
            last_sequence,
            target_system,
            target_component,
        });
        let _ = self.link.endpoint.send(self.link.sysid, &msg);
        let (requested, lost) = (
            self.px4_events.sequence.requested,
            self.px4_events.sequence.lost,
        );
        self.link.with_telemetry_mut(|t| {
            t.px4_events.requested = requested;
            t.px4_events.lost = lost;
        });
    }

    /// The metadata is loaded: the events that waited for it are decoded.
    pub(super) fn set_events_metadata(&mut self, meta: Arc<EventsMetadata>) {
        self.px4_events.mode_groups = Arc::new(meta.mode_groups.clone());
        self.px4_events.meta = Some(meta);
        let waiting: Vec<EVENT_DATA> = self.px4_events.waiting.drain(..).collect();
        self.events_ready(waiting);
    }

    fn events_ready(&mut self, ready: Vec<EVENT_DATA>) {
        let lost = self.px4_events.sequence.lost;
        self.link.with_telemetry_mut(|t| t.px4_events.lost = lost);
        let Some(meta) = self.px4_events.meta.clone() else {
            for e in ready {
                if self.px4_events.waiting.len() == HELD_BEFORE_METADATA {
                    self.px4_events.waiting.pop_front();
                }
                self.px4_events.waiting.push_back(e);
            }
            return;
        };
        for e in ready {
            match decode(&meta, &e) {
                Some(d) => self.on_decoded(d),
                None => self.link.with_telemetry_mut(|t| t.px4_events.unknown += 1),
            }
        }
    }

    fn on_decoded(&mut self, d: DecodedEvent) {
        if d.group == "arming_check" || d.group == "health" {
            if let Some(report) = self
                .px4_events
                .health
                .on_event(&d, &self.px4_events.mode_groups)
            {
                self.link
                    .with_telemetry_mut(|t| t.arming_report = Some(report));
            }
            return;
        }
        if d.log_level <= SHOWN_LEVEL {
            self.heard_text(StatusText {
                severity: d.log_level,
                text: d.message,
            });
        }
    }
}
