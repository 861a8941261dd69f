//! What the vehicle says (`STATUSTEXT`), and the reasons it gives for refusing a command.
//!
//! PX4 says why it refuses a command in `STATUSTEXT`s (arming checks: `"Preflight Fail:
//! …"`, then `"Arming denied: Resolve system health failures first"`), logged by the
//! commander as it acknowledges; the two reach the link in either order. So a refusing
//! `COMMAND_ACK` is answered [`REASON_GRACE`] later, with every warning or error text the
//! vehicle sent while the command was in flight ([`LinkError::Rejected`]'s
//! `statustexts`). PX4 sends `STATUSTEXT` only while it hears a ground station's
//! heartbeat (`px4.md`), which the link sends.
//!
//! PX4 ends a text it also sends as an event with a tab (`"Armed by external
//! command\t"`, `mavlink_log_info(…, "…\t")` beside `events::send`): the tab is
//! dropped, and once the vehicle's events are decoded ([`super::events`]) such a text is
//! not shown at all, its event is. A refused arm's error also names the checks that
//! prevent arming in PX4's last health and arming check report.

use super::{Px4LinkMsg, Px4LinkState};
use crate::command::{LinkCommand, LinkError};
use crate::statustext::{CHUNK_TIMEOUT, StatusText};
use ractor::ActorRef;
use skein_mavlink::dialect::{MavSeverity, STATUSTEXT_DATA};
use std::time::{Duration, Instant};

/// How long a refusal waits for the vehicle's reasons after its `COMMAND_ACK`.
pub const REASON_GRACE: Duration = Duration::from_millis(250);

impl Px4LinkState {
    /// One `STATUSTEXT` from the autopilot at `now`: each text it completes goes to the
    /// commands in flight (warnings and worse) and out as a [`super::LinkEvent`].
    pub(super) fn on_statustext(&mut self, m: &STATUSTEXT_DATA, now: Instant) {
        for t in self.statustexts.push(m, now) {
            self.heard_statustext(t);
        }
    }

    /// Ends a text that waited [`CHUNK_TIMEOUT`] for a chunk by `now`.
    pub(super) fn flush_statustext(&mut self, now: Instant) {
        if let Some(t) = self.statustexts.flush(now) {
            self.heard_statustext(t);
        }
    }

    fn heard_statustext(&mut self, t: StatusText) {
        let Some(text) = t.text.strip_suffix('\t') else {
            return self.heard_text(t);
        };
        if self.px4_events.has_metadata() {
            return; // its event says it
        }
        self.heard_text(StatusText {
            severity: t.severity,
            text: text.to_string(),
        });
    }

    /// A text of the vehicle (a `STATUSTEXT`, or an event's message): kept, told to
    /// the commands in flight (warnings and worse), sent on.
    pub(super) fn heard_text(&mut self, t: StatusText) {
        self.link.keep_message(t.severity, &t.text);
        if t.severity <= MavSeverity::MAV_SEVERITY_WARNING as u8 {
            for p in self.pending.values_mut() {
                p.statustexts.push(t.text.clone());
            }
        }
        (self.events)(super::LinkEvent::StatusText {
            severity: t.severity,
            text: t.text,
        });
    }

    /// [`REASON_GRACE`] after the refusal of command `id` (this `generation`): answers it
    /// with the texts heard.
    pub(super) fn on_reason_deadline(
        &mut self,
        myself: &ActorRef<Px4LinkMsg>,
        id: u32,
        generation: u64,
    ) {
        // A text still waiting for a chunk it will not get.
        self.flush_statustext(Instant::now() + CHUNK_TIMEOUT);
        let Some(p) = self.pending.get_mut(&id) else {
            return;
        };
        if p.generation != generation {
            return;
        }
        let Some(result) = p.refused.take() else {
            return;
        };
        let mut said = std::mem::take(&mut p.statustexts);
        if p.command == LinkCommand::Arm {
            // PX4's report names the checks that stop it: first, as PX4's own words.
            let checks = self.link.with_telemetry(|t| t.px4_arming_checks());
            let failing = checks
                .into_iter()
                .filter(|c| c.prevents_arming)
                .map(|c| c.message);
            let mut named: Vec<String> = failing.filter(|m| !said.contains(m)).collect();
            named.append(&mut said);
            said = named;
        }
        let err = LinkError::Rejected {
            command: p.command.describe(),
            result,
            statustexts: said,
        };
        self.finish(myself, id, Err(err));
    }
}
