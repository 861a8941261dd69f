//! What DDS Security refused in this process, counted and said: every participant,
//! endpoint and message RustDDS's builtin plugins turn away.
//!
//! RustDDS 0.15 reports most refusals only as `log` records (a participant without a
//! certificate, or whose certificate is not from the keystore's CA, never reaches its
//! status events), so [`install`] makes a `log` logger of this module: it reads the
//! records of RustDDS's secure discovery and message receiver, classifies the refusals
//! among them by their text ([`Reason::of`]), counts them ([`counts`], in `/metrics` as
//! `skein_dds_security_refusals{reason="..."}`) and says each as one `warn` line of
//! skein's log, at most one a second per reason (a flood of forged messages is counted
//! whole, not logged whole). Every other `log` record is dropped, as it was before.
//!
//! The phrases are RustDDS 0.15.1's (`Cargo.lock` pins it): `core/dds/tests/security.rs`
//! checks that a participant without a certificate and one with a foreign CA's are
//! counted, so an upgrade that rewords them fails there.
//!
//! Counts are of refusals, not of participants: a participant without DDS Security is
//! refused once and each of its protected endpoints once more; a handshake is refused
//! once per attempt (RustDDS resends one up to 10 times). A handshake is refused by the
//! side that validates the other's certificate: a participant with a foreign CA's
//! certificate that sends the first request is counted (and said: "Replying to a
//! handshake request failed: … Certificate signature verification failure") by the
//! enrolled participant; when the enrolled one sends it, the foreign one refuses it and
//! the enrolled one's request goes unanswered, which RustDDS says only at `debug`.
//!
//! Not counted: messages RustDDS drops at `trace` level (a secured message whose keys
//! this participant does not hold, a receiver-specific MAC that does not verify), and
//! replays, which RTPS's sequence numbers drop silently inside RustDDS (a best-effort
//! reader takes no sample at or below the last it took; a reliable one no duplicate).

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, OnceLock, PoisonError};
use std::time::{Duration, Instant};

/// Why DDS Security refused something (the `reason` label of
/// `skein_dds_security_refusals`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reason {
    /// A participant without DDS Security, or with an incompatible configuration
    /// (governance `allow_unauthenticated_participants` false), or one of its
    /// endpoints on a protected topic.
    Unauthenticated,
    /// A participant whose identity did not validate: its certificate is not from the
    /// keystore's identity CA, or is malformed.
    Identity,
    /// A participant whose authentication handshake failed (a signature, a challenge or a
    /// Diffie-Hellman step that did not verify).
    Handshake,
    /// An authenticated participant whose permissions do not validate (not signed by the
    /// permissions CA, expired, another subject) or do not let it join the domain.
    Permissions,
    /// An authenticated participant's reader or writer on a topic its permissions do not
    /// grant (a viewer's command writer, an agent's target writer).
    AccessControl,
    /// A secured submessage that failed to decrypt or authenticate (AES-GCM / GMAC):
    /// altered, forged, or encrypted with keys this participant was never given.
    Undecodable,
}

impl Reason {
    /// Every reason, in the order of [`counts`].
    pub const ALL: [Reason; 6] = [
        Reason::Unauthenticated,
        Reason::Identity,
        Reason::Handshake,
        Reason::Permissions,
        Reason::AccessControl,
        Reason::Undecodable,
    ];

    /// The label (`unauthenticated`, `identity`, `handshake`, `permissions`,
    /// `access_control`, `undecodable`).
    pub fn name(self) -> &'static str {
        match self {
            Reason::Unauthenticated => "unauthenticated",
            Reason::Identity => "identity",
            Reason::Handshake => "handshake",
            Reason::Permissions => "permissions",
            Reason::AccessControl => "access_control",
            Reason::Undecodable => "undecodable",
        }
    }

    /// Whether RustDDS's records of `target` may say a refusal (its secure discovery and
    /// its message receiver): the only ones [`Reason::of`] reads, and formats.
    pub fn may_say(target: &str) -> bool {
        target.starts_with(SECURE_DISCOVERY) || target.starts_with(MESSAGE_RECEIVER)
    }

    /// The refusal a RustDDS `log` record of `target` says, if it says one.
    pub fn of(target: &str, text: &str) -> Option<Reason> {
        if target.starts_with(MESSAGE_RECEIVER) {
            return text
                .contains("decoding failed")
                .then_some(Reason::Undecodable);
        }
        if !target.starts_with(SECURE_DISCOVERY) {
            return None;
        }
        PHRASES
            .iter()
            .find(|(phrase, _)| text.contains(phrase))
            .map(|(_, r)| *r)
    }

    fn index(self) -> usize {
        Reason::ALL.iter().position(|r| *r == self).unwrap_or(0)
    }
}

/// The `log` targets of RustDDS's secure discovery and message receiver.
const SECURE_DISCOVERY: &str = "rustdds::discovery::secure_discovery";
const MESSAGE_RECEIVER: &str = "rustdds::rtps::message_receiver";

/// RustDDS 0.15.1's secure discovery phrases, and the refusal each says (first match).
const PHRASES: [(&str, Reason); 11] = [
    (
        "incompatible Security, not matching",
        Reason::Unauthenticated,
    ),
    ("Unauthenticated participant", Reason::Unauthenticated),
    ("non-secure DCPS", Reason::Unauthenticated),
    ("Failed to validate the identity", Reason::Identity),
    ("missing the Identity token", Reason::Identity),
    (
        "Validating handshake reply message failed",
        Reason::Handshake,
    ),
    (
        "Validating final handshake message failed",
        Reason::Handshake,
    ),
    ("Replying to a handshake request failed", Reason::Handshake),
    (
        "Validating permissions for remote failed",
        Reason::Permissions,
    ),
    ("not allowed to join the domain", Reason::Permissions),
    ("Access control check did not pass", Reason::AccessControl),
];

/// How often one reason is said in skein's log, at most.
const SAY_EVERY: Duration = Duration::from_secs(1);

/// The process's refusals: counts by [`Reason`] and when each was last said.
struct Refusals {
    counts: [AtomicU64; 6],
    said: Mutex<[Option<Instant>; 6]>,
}

static REFUSALS: Refusals = Refusals {
    counts: [const { AtomicU64::new(0) }; 6],
    said: Mutex::new([None; 6]),
};

/// Refusals since the process started, by reason, in [`Reason::ALL`]'s order (every
/// reason, zeros included). Zeros until [`install`] ran.
pub fn counts() -> [(Reason, u64); 6] {
    Reason::ALL.map(|r| (r, REFUSALS.counts[r.index()].load(Ordering::Relaxed)))
}

/// Counts `reason` and says `text` in skein's log, unless this reason was said less
/// than a second ago.
pub fn refused(reason: Reason, text: &str) {
    let i = reason.index();
    REFUSALS.counts[i].fetch_add(1, Ordering::Relaxed);
    let now = Instant::now();
    let mut said = REFUSALS.said.lock().unwrap_or_else(PoisonError::into_inner);
    if said[i].is_some_and(|t| now.duration_since(t) < SAY_EVERY) {
        return;
    }
    said[i] = Some(now);
    drop(said);
    tracing::warn!(
        reason = reason.name(),
        "DDS Security refused: {text} (counted in skein_dds_security_refusals)"
    );
}

/// The `log` logger reading RustDDS's records.
struct Listener;

impl log::Log for Listener {
    fn enabled(&self, metadata: &log::Metadata<'_>) -> bool {
        metadata.level() <= log::Level::Info && Reason::may_say(metadata.target())
    }

    /// Formats only the records of the two targets that may say a refusal: every other
    /// record (RustDDS's per-message ones included) costs a level and a prefix check.
    fn log(&self, record: &log::Record<'_>) {
        if !self.enabled(record.metadata()) {
            return;
        }
        let text = record.args().to_string();
        if let Some(reason) = Reason::of(record.target(), &text) {
            refused(reason, &text);
        }
    }

    fn flush(&self) {}
}

static LISTENER: Listener = Listener;
static INSTALLED: OnceLock<bool> = OnceLock::new();

/// Makes this module the process's `log` logger, once (a secured participant's join calls
/// it). Returns whether it is: `false` when another `log` logger was set first, and then
/// nothing is counted (said once as a warning).
pub fn install() -> bool {
    *INSTALLED.get_or_init(|| match log::set_logger(&LISTENER) {
        Ok(()) => {
            log::set_max_level(log::LevelFilter::Info);
            true
        }
        Err(_) => {
            tracing::warn!(
                "another `log` logger is set: DDS Security's refusals are not counted \
                 (skein_dds_security_refusals stays 0)"
            );
            false
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const SD: &str = "rustdds::discovery::secure_discovery";

    #[test]
    fn rustdds_phrases_are_classified_and_other_records_are_not() {
        let cases = [
            (
                "Remote participant has incompatible Security, not matching with it. Remote guid: G",
                Some(Reason::Unauthenticated),
            ),
            (
                "Failed to validate the identity of the remote participant G. Info: x",
                Some(Reason::Identity),
            ),
            (
                "Validating permissions for remote failed: e. Rejecting the remote. Guid prefix: G",
                Some(Reason::Permissions),
            ),
            (
                "Access control check did not pass for authenticated participant G to publish \
                 to topic rt/skein/swarm/target. Rejecting.",
                Some(Reason::AccessControl),
            ),
            ("Authenticated successfully Participant G", None),
            (
                "Remote participant has incompatible Security, but matching with it anyways",
                None,
            ),
        ];
        for (text, want) in cases {
            assert_eq!(Reason::of(SD, text), want, "{text}");
        }
        assert_eq!(
            Reason::of(
                "rustdds::rtps::message_receiver",
                "Submessage decoding failed: x"
            ),
            Some(Reason::Undecodable)
        );
        assert_eq!(
            Reason::of(
                "rustdds::discovery::discovery",
                "Failed to validate the identity"
            ),
            None,
            "only the secure discovery's records"
        );
    }

    #[test]
    fn every_refusal_is_counted_even_when_not_said() {
        let before = counts()[Reason::Handshake.index()].1;
        for _ in 0..5 {
            refused(Reason::Handshake, "test");
        }
        assert_eq!(counts()[Reason::Handshake.index()].1, before + 5);
    }
}
