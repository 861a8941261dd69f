//! What DDS Security refused in this process, counted and said: every participant,
//! endpoint and message RustDDS's builtin plugins turn away.
//!
//! RustDDS 0.15 reports most refusals only as `log` records (a participant without a
//! certificate, or whose certificate is not from the keystore's CA, never reaches its
//! status events), and its security plugins' traits are private to it (no wrapper can
//! count in their place), so [`install`] makes a `log` logger of this module: it reads
//! the records of RustDDS's secure discovery, message receiver and readers, classifies
//! the refusals among them by their text ([`Reason::of`]), counts them ([`counts`], in
//! `/metrics` as `skein_dds_security_refusals{reason="..."}`) and says each as one
//! `warn` line of skein's log, at most one a second per reason (a flood of forged
//! messages is counted whole, not logged whole). Every other `log` record is dropped, as
//! it was before. The message receiver and the readers say what this counts at `trace`,
//! so a secured process's `log` level is `trace`; a record of another target costs a
//! level and a prefix check, one of these three is formatted on the stack, cut at
//! 512 bytes, and a reader's record about anything but a DATA (a heartbeat, a gap) is
//! cut at its first bytes (no measurable CPU at one vehicle per agent, debug build).
//!
//! The phrases are RustDDS 0.15.1's (`Cargo.lock` pins it): `core/dds/tests/security.rs`
//! checks that a participant without a certificate and one with a foreign CA's are
//! counted, and `tests/e2e_dds_security.rs` that forged and replayed messages are, so an
//! upgrade that rewords them fails there.
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
//! A forged or altered message is counted once per message ([`Reason::Undecodable`]):
//! the message MAC (governance `rtps_protection_kind` SIGN) fails before any submessage
//! is read. A replayed message is authentic, so it passes the MACs: RTPS's sequence
//! numbers then drop each sample of a user topic (`rt/…`) in it that its reader had
//! already taken, and each such drop is counted ([`Reason::Replay`]) when the sample was
//! first taken over [`REPAIR_WINDOW`] ago; a later copy within the window is taken for a
//! reliable writer's repair that crossed its original, which loaded machines make every
//! few minutes ([`super::repeats`]), and is dropped uncounted. A replay into a reader
//! that never took the sample (one created after it was sent, as a restarted DDS link's
//! are) is not dropped by RTPS until the writer's first heartbeat moves the reader past
//! it, and is not counted.
//!
//! Not counted: a secured message or submessage protected with keys this participant
//! does not hold yet, or from a participant it has no keys for: RustDDS says these at
//! `trace` during every handshake (a peer's first secured messages outrun its keys: 16 to
//! 20 in each enrolled process's first seconds on loopback), so counting them would
//! count every enrolled peer; a message forged with a key id never used is among them.

use super::repeats::{Duplicate, REPAIR_WINDOW, Repeats};
use std::cell::RefCell;
use std::fmt;
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
    /// A secured message or submessage that failed to decrypt or authenticate
    /// (AES-GCM / GMAC, DDS Security's builtin crypto): altered or forged.
    Undecodable,
    /// An authentic message carrying a user-topic sample RTPS had already delivered (its
    /// writer's sequence number already taken), dropped by RTPS: a replay, or (rarely) a
    /// reliable writer's repair that crossed its original.
    Replay,
}

impl Reason {
    /// Every reason, in the order of [`counts`].
    pub const ALL: [Reason; 7] = [
        Reason::Unauthenticated,
        Reason::Identity,
        Reason::Handshake,
        Reason::Permissions,
        Reason::AccessControl,
        Reason::Undecodable,
        Reason::Replay,
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
            Reason::Replay => "replay",
        }
    }

    /// Whether a RustDDS `log` record of `target` at `level` may say a refusal: its
    /// secure discovery's (`info` and above), its message receiver's (every level: it
    /// says a message that failed to authenticate at `trace`) and its readers' (the
    /// sample already taken, at `trace`). The only ones [`Reason::of`] reads, and formats.
    pub fn may_say(target: &str, level: log::Level) -> bool {
        target.starts_with(MESSAGE_RECEIVER)
            || target.starts_with(READER)
            || (level <= log::Level::Info && target.starts_with(SECURE_DISCOVERY))
    }

    /// The refusal a RustDDS `log` record of `target` says, if it says one (a reader's
    /// records say a replay only in their sequence: `reader_record`).
    pub fn of(target: &str, text: &str) -> Option<Reason> {
        if target.starts_with(MESSAGE_RECEIVER) {
            return RECEIVER_PHRASES
                .iter()
                .any(|p| text.contains(p))
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

/// The `log` targets of RustDDS's secure discovery, message receiver and readers.
const SECURE_DISCOVERY: &str = "rustdds::discovery::secure_discovery";
const MESSAGE_RECEIVER: &str = "rustdds::rtps::message_receiver";
const READER: &str = "rustdds::rtps::reader";

/// RustDDS 0.15.1's message receiver phrases of a secured message or submessage that did
/// not authenticate: a submessage (`error`); a whole message whose MAC failed, or a
/// payload (`error`, the plugin's `SecurityError` as is: ring says only "Unspecified");
/// a message whose receiver-specific MAC failed (`trace`; checked before its common
/// MAC, so a forgery may end there).
/// (Not "No matching message decode keys found" nor "No participant crypto handle
/// found": every handshake makes some, see the module's documentation. Nor "No endpoints
/// passed the receiver-specific MAC validation for the submessage": RustDDS says it only
/// after the submessage's common MAC verified (or it decrypted), so the submessage is
/// authentic, addressed to readers or writers of another participant at this address.
/// A peer restarted on its port gets one a second from every peer's heartbeats to its
/// previous incarnation until that one's lease runs out: counted, it was a "refusal" a
/// second after every coordinator failover.)
const RECEIVER_PHRASES: [&str; 3] = [
    "Submessage decoding failed",
    "SecurityError",
    "Failed to validate the receiver-specif MAC for the rtps message",
];

/// RustDDS 0.15.1's reader phrases: the DATA it handles (with its topic), and a DATA
/// whose sequence number it had already taken (dropped).
const HANDLING_DATA: &str = "handle_data_msg from ";
const ALREADY_TAKEN: &str = "handle_data_msg already have this seq";
/// What both begin with.
const DATA_RECORDS: &str = "handle_data_msg ";

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
    counts: [AtomicU64; REASONS],
    said: Mutex<[Option<Instant>; REASONS]>,
}

/// How many reasons there are.
const REASONS: usize = Reason::ALL.len();

static REFUSALS: Refusals = Refusals {
    counts: [const { AtomicU64::new(0) }; REASONS],
    said: Mutex::new([None; REASONS]),
};

/// Refusals since the process started, by reason, in [`Reason::ALL`]'s order (every
/// reason, zeros included). Zeros until [`install`] ran.
pub fn counts() -> [(Reason, u64); REASONS] {
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

thread_local! {
    /// The user-topic samples RustDDS's readers took lately on this thread (its event
    /// loop's), to tell a replay from RTPS's repeat ([`Repeats`]).
    static REPEATS: RefCell<Repeats> = RefCell::new(Repeats::default());
}

impl log::Log for Listener {
    fn enabled(&self, metadata: &log::Metadata<'_>) -> bool {
        Reason::may_say(metadata.target(), metadata.level())
    }

    /// Formats only the records of the three targets that may say a refusal, and only
    /// their first [`Capped::LEN`] bytes, on the stack: every other record (RustDDS's
    /// per-message ones elsewhere, other crates') costs a level and a prefix check.
    fn log(&self, record: &log::Record<'_>) {
        let target = record.target();
        if !Reason::may_say(target, record.level()) {
            return;
        }
        let reader = target.starts_with(READER);
        // A reader says a record for every submessage it handles (heartbeats, gaps,
        // acknacks …): only those about a DATA are read, and the others' formatting stops
        // at their first bytes.
        let mut text = Capped {
            expect: if reader { DATA_RECORDS } else { "" },
            ..Capped::default()
        };
        // An `Err` only says the text was cut: at `Capped::LEN`, or where it left `expect`.
        let _ = fmt::write(&mut text, *record.args());
        if text.diverged {
            return;
        }
        let text = text.as_str();
        if reader {
            if let Some(reason) = reader_record(text, Instant::now()) {
                refused(
                    reason,
                    &format!(
                        "an authentic message repeated a sample its reader took over {} s \
                         ago, a replay ({text})",
                        REPAIR_WINDOW.as_secs()
                    ),
                );
            }
            return;
        }
        if let Some(reason) = Reason::of(target, text) {
            refused(reason, text);
        }
    }

    fn flush(&self) {}
}

/// What a RustDDS reader's record `text`, said at `now`, makes of the DATA it handles:
/// its "handle_data_msg from GUID {…} seq=SequenceNumber(N) topic=\"…\"" announces one
/// (followed in [`Repeats`] when its topic is a user topic, `rt/…`), its "handle_data_msg
/// already have this seq=SequenceNumber(N)" drops it: a replay when it is one
/// ([`Repeats::already_taken`]).
fn reader_record(text: &str, now: Instant) -> Option<Reason> {
    if let Some(rest) = text.strip_prefix(HANDLING_DATA) {
        let (writer, rest) = rest.split_once(" seq=SequenceNumber(")?;
        let seq = rest.split_once(')')?.0.parse().ok();
        REPEATS.with_borrow_mut(|r| match seq {
            Some(seq) if rest.contains("topic=\"rt/") => r.data(writer, seq, now),
            _ => r.other_data(),
        });
        return None;
    }
    let seq = text
        .strip_prefix(ALREADY_TAKEN)?
        .strip_prefix("=SequenceNumber(")?
        .split_once(')')?
        .0
        .parse()
        .ok()?;
    let copy = REPEATS.with_borrow_mut(|r| r.already_taken(seq, now))?;
    (copy == Duplicate::Replay).then_some(Reason::Replay)
}

/// A record's text, cut at [`Capped::LEN`] bytes (on a character boundary), or as soon
/// as it leaves the prefix it must begin with.
struct Capped {
    bytes: [u8; Capped::LEN],
    len: usize,
    /// What the text must begin with (`""`: anything).
    expect: &'static str,
    /// Set when the text did not begin with `expect`: formatting stopped there.
    diverged: bool,
}

impl Capped {
    /// Enough for every phrase [`Reason::of`] looks for, and for the topic of a reader's
    /// "handle_data_msg from" record (after the writer's GUID and sequence number).
    const LEN: usize = 512;

    fn as_str(&self) -> &str {
        std::str::from_utf8(&self.bytes[..self.len]).unwrap_or_default()
    }
}

impl Default for Capped {
    fn default() -> Self {
        Capped {
            bytes: [0; Capped::LEN],
            len: 0,
            expect: "",
            diverged: false,
        }
    }
}

impl fmt::Write for Capped {
    /// Takes what fits; `Err` once full, or once the text left `expect`, which ends the
    /// formatting.
    fn write_str(&mut self, s: &str) -> fmt::Result {
        let room = Capped::LEN - self.len;
        let mut n = s.len().min(room);
        while !s.is_char_boundary(n) {
            n -= 1;
        }
        self.bytes[self.len..self.len + n].copy_from_slice(&s.as_bytes()[..n]);
        self.len += n;
        let checked = self.len.min(self.expect.len());
        if self.bytes[..checked] != self.expect.as_bytes()[..checked] {
            self.diverged = true;
            return Err(fmt::Error);
        }
        if n < s.len() { Err(fmt::Error) } else { Ok(()) }
    }
}

static LISTENER: Listener = Listener;
static INSTALLED: OnceLock<bool> = OnceLock::new();

/// Makes this module the process's `log` logger, once (a secured participant's join calls
/// it). Returns whether it is: `false` when another `log` logger was set first, and then
/// nothing is counted (said once as a warning).
pub fn install() -> bool {
    *INSTALLED.get_or_init(|| match log::set_logger(&LISTENER) {
        Ok(()) => {
            // The message receiver says a message that failed to authenticate, and a
            // reader a sample already taken, at `trace`.
            log::set_max_level(log::LevelFilter::Trace);
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
    use log::Log;

    const SD: &str = "rustdds::discovery::secure_discovery";
    const MR: &str = "rustdds::rtps::message_receiver";
    const RD: &str = "rustdds::rtps::reader::Reader";

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
                "rustdds::discovery::discovery",
                "Failed to validate the identity"
            ),
            None,
            "only the secure discovery's records"
        );
    }

    #[test]
    fn a_message_or_submessage_that_fails_to_authenticate_is_undecodable_not_missing_keys() {
        let cases = [
            (
                "Submessage decoding failed: SecurityError { msg: \"x\" }",
                true,
            ),
            (
                "SecurityError { msg: \"The ring crypto library gives 'Unspecified' error.\" }",
                true,
            ),
            (
                "Failed to validate the receiver-specif MAC for the rtps message.",
                true,
            ),
            // Authentic (its common MAC verified first), for another participant's
            // endpoints at this address: not counted.
            (
                "No endpoints passed the receiver-specific MAC validation for the submessage.",
                false,
            ),
            // Every handshake makes these: not counted.
            (
                "No matching message decode keys found for the key id K for the remote \
                 participant G",
                false,
            ),
            (
                "No participant crypto handle found for the participant G for rtps message \
                 decoding.",
                false,
            ),
            ("Message is not for this participant. Dropping.", false),
        ];
        for (text, undecodable) in cases {
            let want = undecodable.then_some(Reason::Undecodable);
            assert_eq!(Reason::of(MR, text), want, "{text}");
        }
    }

    #[test]
    fn only_the_reader_and_receiver_records_are_read_at_trace() {
        assert!(Reason::may_say(RD, log::Level::Trace));
        assert!(Reason::may_say(MR, log::Level::Trace));
        assert!(!Reason::may_say(SD, log::Level::Debug));
        assert!(!Reason::may_say("rustdds::rtps::writer", log::Level::Error));
    }

    /// A record of `target` at `level` saying `text`, through the listener.
    fn say(target: &str, level: log::Level, text: &str) {
        LISTENER.log(
            &log::Record::builder()
                .target(target)
                .level(level)
                .args(format_args!("{text}"))
                .build(),
        );
    }

    fn replays() -> u64 {
        counts()[Reason::Replay.index()].1
    }

    /// RustDDS's reader records of a DATA `seq` of topic `topic` from writer `w`.
    fn data(w: &str, seq: i64, topic: &str) -> String {
        format!(
            "handle_data_msg from GUID {{{w} EntityId {{[0, 0, 3] User/WriterNoKey}}}} \
             seq=SequenceNumber({seq}) topic=\"{topic}\" reliability=Reliable stateless=false"
        )
    }

    fn taken(seq: i64) -> String {
        format!("handle_data_msg already have this seq=SequenceNumber({seq})")
    }

    #[test]
    fn the_listener_counts_a_replay_of_a_user_topic_sample_not_of_discovery() {
        // Each test runs on a thread of its own: the listener's ledger is this thread's,
        // and a copy judged at once is a repeat; a copy of a sample this ledger never saw
        // taken (taken before it, or skipped) is a replay.
        let before = replays();
        let w = "0a.0b.0c";
        say(RD, log::Level::Trace, &data(w, 7, "rt/skein/swarm/command"));
        say(RD, log::Level::Trace, &data(w, 7, "rt/skein/swarm/command"));
        say(RD, log::Level::Trace, &taken(7));
        assert_eq!(replays(), before, "a copy at once is RTPS's repeat");
        say(RD, log::Level::Trace, &data(w, 3, "rt/skein/swarm/command"));
        say(RD, log::Level::Trace, &taken(3));
        assert_eq!(
            replays(),
            before + 1,
            "a sample taken before the ledger knew"
        );
        say(RD, log::Level::Trace, &data(w, 2, "DCPSParticipant"));
        say(RD, log::Level::Trace, &taken(2));
        assert_eq!(replays(), before + 1, "a discovery repeat is no replay");
        // A record cut at its cap still reads when its topic is within it.
        let long_writer = "x".repeat(300);
        say(
            RD,
            log::Level::Trace,
            &data(&long_writer, 1, "rt/skein/formation"),
        );
        say(RD, log::Level::Trace, &taken(1));
        assert_eq!(replays(), before + 2);
    }

    #[test]
    fn a_capped_text_is_cut_on_a_character_boundary() {
        let mut c = Capped::default();
        let text = format!("{}é{}", "a".repeat(Capped::LEN - 1), "b".repeat(10));
        assert!(fmt::write(&mut c, format_args!("{text}")).is_err());
        assert_eq!(c.as_str(), "a".repeat(Capped::LEN - 1));
        let mut c = Capped::default();
        assert!(fmt::write(&mut c, format_args!("short {}", 1)).is_ok());
        assert_eq!(c.as_str(), "short 1");
    }

    #[test]
    fn a_capped_text_stops_where_it_leaves_its_prefix() {
        let expecting = || Capped {
            expect: DATA_RECORDS,
            ..Capped::default()
        };
        let mut c = expecting();
        let heartbeat = format_args!("handle_heartbeat_msg {}", "x".repeat(400));
        assert!(fmt::write(&mut c, heartbeat).is_err());
        assert!(c.diverged);
        assert!(c.len < 30, "formatting went on to {} bytes", c.len);
        let mut c = expecting();
        assert!(fmt::write(&mut c, format_args!("{}", taken(4))).is_ok());
        assert!(!c.diverged);
        assert_eq!(c.as_str(), taken(4));
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
