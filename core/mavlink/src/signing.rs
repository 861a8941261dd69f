//! MAVLink 2 message signing (<https://mavlink.io/en/guide/message_signing.html>): a
//! 32-byte secret key shared by both ends of a link, and on every signed frame a 13-byte
//! trailer of link id, 48-bit timestamp (10 µs units since 2015-01-01 00:00 UTC) and the
//! first 6 bytes of `SHA-256(key ‖ header ‖ payload ‖ CRC ‖ link id ‖ timestamp)`.
//!
//! The signature itself is computed by the `mavlink` crate
//! (`MAVLinkV2MessageRaw::calculate_signature`, feature `mav2-message-signing`). Its
//! `SigningData::verify_signature` answers only yes or no, so the accept rules live here to
//! tell apart what [`SigningCounts`] counts: unsigned frames, bad signatures, replays
//! (a timestamp not newer than the last one of its stream; a stream is a
//! `(link id, sysid, compid)` triple), and new streams more than one minute behind our
//! clock (the spec's accept window).

use mavlink::MAVLinkV2MessageRaw;
use mavlink::consts::MAX_FRAME_SIZE;
use mavlink::consts::v2::SIGNATURE_VALUE_SIZE;
use std::collections::HashMap;
use std::path::Path;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::SystemTime;

/// Length of a signing key, bytes.
pub const KEY_LEN: usize = 32;
/// Unix time of the signing epoch, 2015-01-01 00:00:00 UTC, seconds.
pub const EPOCH_UNIX_S: u64 = 1_420_070_400;
/// The accept window for a new stream: one minute, in 10 µs units.
pub const NEW_STREAM_WINDOW: u64 = 60 * 100_000;
/// `MAVLINK_IFLAG_SIGNED`.
const IFLAG_SIGNED: u8 = 0x01;

/// A 32-byte MAVLink signing secret. Its `Debug` form does not show the key.
#[derive(Clone, PartialEq, Eq)]
pub struct SigningKey([u8; KEY_LEN]);

impl std::fmt::Debug for SigningKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("SigningKey(…)")
    }
}

/// Why a key could not be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct KeyError(pub String);

impl std::fmt::Display for KeyError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for KeyError {}

impl SigningKey {
    /// A key from its 32 bytes.
    pub fn from_bytes(bytes: [u8; KEY_LEN]) -> Self {
        SigningKey(bytes)
    }

    /// The key's bytes.
    pub fn as_bytes(&self) -> &[u8; KEY_LEN] {
        &self.0
    }

    /// All zeros: PX4's "no key" (a `SETUP_SIGNING` with a blank key and timestamp 0
    /// disables signing).
    pub fn is_blank(&self) -> bool {
        self.0.iter().all(|&b| b == 0)
    }

    /// The key as 64 lowercase hex characters (the key file format).
    pub fn to_hex(&self) -> String {
        self.0.iter().map(|b| format!("{b:02x}")).collect()
    }

    /// Parses a key file's text: exactly 64 hex characters (either case), surrounding
    /// whitespace ignored.
    ///
    /// # Errors
    /// Any other content, with what was found (never the text itself: it may be a key).
    pub fn parse_hex(text: &str) -> Result<Self, KeyError> {
        let t = text.trim();
        if t.len() != 2 * KEY_LEN {
            return Err(KeyError(format!(
                "a signing key is {} hex characters (32 bytes), found {} characters",
                2 * KEY_LEN,
                t.chars().count()
            )));
        }
        let mut key = [0u8; KEY_LEN];
        for (i, pair) in t.as_bytes().chunks(2).enumerate() {
            let hex = std::str::from_utf8(pair).ok();
            key[i] = hex
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| {
                    KeyError(format!(
                        "a signing key is 64 hex characters; character {} or {} is not hex",
                        2 * i + 1,
                        2 * i + 2
                    ))
                })?;
        }
        Ok(SigningKey(key))
    }

    /// Reads a key file (64 hex characters).
    ///
    /// # Errors
    /// The file cannot be read, or holds anything else than a key; the message names the
    /// file.
    pub fn load(path: &Path) -> Result<Self, KeyError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| KeyError(format!("{}: cannot read signing key: {e}", path.display())))?;
        Self::parse_hex(&text).map_err(|e| KeyError(format!("{}: {e}", path.display())))
    }
}

/// The current signing timestamp: 10 µs units since 2015-01-01 00:00 UTC (0 before it).
pub fn timestamp_now() -> u64 {
    let us = SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .map(|d| d.as_micros())
        .unwrap_or(0);
    (us.saturating_sub(u128::from(EPOCH_UNIX_S) * 1_000_000) / 10) as u64
}

/// What [`LinkSigning::verify`] decided about one frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Signed with our key, fresh: accept.
    Valid,
    /// No signature (or a MAVLink 1 frame).
    Unsigned,
    /// Signed, but not with our key (or altered on the way).
    BadSignature,
    /// Signed with our key, but its timestamp is not newer than the last frame of its
    /// stream: a replay.
    Replayed,
    /// Signed with our key, first of its stream, but more than a minute behind our clock.
    TooOld,
}

/// Counters of one signing link (atomics, relaxed).
#[derive(Debug, Default)]
struct SigningStats {
    signed_ok: AtomicU64,
    unsigned: AtomicU64,
    bad_signature: AtomicU64,
    replayed: AtomicU64,
    too_old: AtomicU64,
    frames_signed: AtomicU64,
}

/// A copy of a link's signing counters. Every counter but `signed_ok` and `frames_signed`
/// counts frames dropped.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct SigningCounts {
    /// Incoming frames with a valid, fresh signature.
    pub signed_ok: u64,
    /// Incoming unsigned frames dropped.
    pub unsigned: u64,
    /// Incoming frames dropped for a wrong signature.
    pub bad_signature: u64,
    /// Incoming frames dropped as replays.
    pub replayed: u64,
    /// Incoming frames dropped as a new stream older than the accept window.
    pub too_old: u64,
    /// Outgoing frames signed.
    pub frames_signed: u64,
}

impl SigningCounts {
    /// Incoming frames dropped, all reasons.
    pub fn dropped(&self) -> u64 {
        self.unsigned + self.bad_signature + self.replayed + self.too_old
    }

    /// Adds `other` into `self` (to total several links).
    pub fn add(&mut self, other: &SigningCounts) {
        self.signed_ok += other.signed_ok;
        self.unsigned += other.unsigned;
        self.bad_signature += other.bad_signature;
        self.replayed += other.replayed;
        self.too_old += other.too_old;
        self.frames_signed += other.frames_signed;
    }
}

#[derive(Debug, Default)]
struct State {
    /// Our clock: max(now, every accepted or sent timestamp), so it never goes back.
    timestamp: u64,
    /// Last accepted timestamp per `(link id, sysid, compid)`.
    streams: HashMap<(u8, u8, u8), u64>,
}

/// MAVLink 2 signing of one link: signs outgoing frames and checks incoming ones (see
/// the module docs). Shared as `Arc` between the encoder and the receive path.
#[derive(Debug)]
pub struct LinkSigning {
    key: SigningKey,
    link_id: u8,
    state: Mutex<State>,
    stats: SigningStats,
}

impl LinkSigning {
    /// Signing with `key`; outgoing frames carry `link_id` (MAVLink's per-link channel
    /// number, 0–255).
    pub fn new(key: SigningKey, link_id: u8) -> Self {
        LinkSigning {
            key,
            link_id,
            state: Mutex::new(State::default()),
            stats: SigningStats::default(),
        }
    }

    /// The secret key.
    pub fn key(&self) -> &SigningKey {
        &self.key
    }

    /// The link id outgoing frames carry.
    pub fn link_id(&self) -> u8 {
        self.link_id
    }

    /// Starts our clock no earlier than `timestamp` (PX4: `SETUP_SIGNING.initial_timestamp`).
    pub fn advance_clock(&self, timestamp: u64) {
        let mut st = self.lock();
        st.timestamp = st.timestamp.max(timestamp);
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Signs a frame serialised with `serialize_message_for_signing` (signed flag set):
    /// fills link id, the next timestamp and the signature.
    pub fn sign(&self, raw: &mut MAVLinkV2MessageRaw) {
        let ts = {
            let mut st = self.lock();
            st.timestamp = st.timestamp.max(timestamp_now());
            let ts = st.timestamp;
            // Every frame gets its own timestamp, so a receiver never sees two equal ones.
            st.timestamp += 1;
            ts
        };
        raw.signature_timestamp_bytes_mut()
            .copy_from_slice(&ts.to_le_bytes()[..6]);
        *raw.signature_link_id_mut() = self.link_id;
        let mut sig = [0u8; SIGNATURE_VALUE_SIZE];
        raw.calculate_signature(self.key.as_bytes(), &mut sig);
        raw.signature_value_mut().copy_from_slice(&sig);
        self.stats.frames_signed.fetch_add(1, Ordering::Relaxed);
    }

    /// Checks one incoming frame (its bytes as received, CRC already checked) without
    /// counting it. A valid frame advances its stream's timestamp.
    pub fn verify(&self, frame: &[u8]) -> Verdict {
        if !is_signed(frame) {
            return Verdict::Unsigned;
        }
        if frame.len() > MAX_FRAME_SIZE {
            return Verdict::BadSignature;
        }
        let mut buf = [0u8; MAX_FRAME_SIZE];
        buf[..frame.len()].copy_from_slice(frame);
        let raw = MAVLinkV2MessageRaw::from_bytes_unparsed(buf);
        if raw.raw_bytes().len() != frame.len() {
            return Verdict::BadSignature;
        }
        let mut sig = [0u8; SIGNATURE_VALUE_SIZE];
        raw.calculate_signature(self.key.as_bytes(), &mut sig);
        if sig != raw.signature_value() {
            return Verdict::BadSignature;
        }
        let ts = raw.signature_timestamp();
        let stream = (raw.signature_link_id(), frame[5], frame[6]);
        let mut st = self.lock();
        st.timestamp = st.timestamp.max(timestamp_now());
        match st.streams.get(&stream) {
            Some(&last) if ts <= last => return Verdict::Replayed,
            None if ts + NEW_STREAM_WINDOW < st.timestamp => return Verdict::TooOld,
            _ => {}
        }
        st.streams.insert(stream, ts);
        st.timestamp = st.timestamp.max(ts);
        Verdict::Valid
    }

    /// [`LinkSigning::verify`] and count the verdict; true when the frame is to be
    /// accepted. Unsigned frames of `unsigned_ok` message ids are accepted (and not
    /// counted), as PX4 accepts RADIO_STATUS, ADSB_VEHICLE and COLLISION unsigned.
    pub fn accept(&self, frame: &[u8], unsigned_ok: &[u32]) -> bool {
        let verdict = self.verify(frame);
        let counter = match verdict {
            Verdict::Valid => &self.stats.signed_ok,
            Verdict::Unsigned => {
                if unsigned_ok.contains(&frame_msgid(frame)) {
                    return true;
                }
                &self.stats.unsigned
            }
            Verdict::BadSignature => &self.stats.bad_signature,
            Verdict::Replayed => &self.stats.replayed,
            Verdict::TooOld => &self.stats.too_old,
        };
        counter.fetch_add(1, Ordering::Relaxed);
        verdict == Verdict::Valid
    }

    /// A copy of the counters.
    pub fn counts(&self) -> SigningCounts {
        let l = |a: &AtomicU64| a.load(Ordering::Relaxed);
        let s = &self.stats;
        SigningCounts {
            signed_ok: l(&s.signed_ok),
            unsigned: l(&s.unsigned),
            bad_signature: l(&s.bad_signature),
            replayed: l(&s.replayed),
            too_old: l(&s.too_old),
            frames_signed: l(&s.frames_signed),
        }
    }
}

/// True when `frame` (one frame's bytes) is a MAVLink 2 frame with the signed flag.
pub fn is_signed(frame: &[u8]) -> bool {
    frame.len() > 2 && frame[0] == crate::STX_V2 && frame[2] & IFLAG_SIGNED != 0
}

/// The message id of a raw MAVLink 1 or 2 frame (0 when too short to tell).
pub fn frame_msgid(frame: &[u8]) -> u32 {
    match frame.first() {
        Some(&crate::STX_V2) if frame.len() >= 10 => {
            u32::from_le_bytes([frame[7], frame[8], frame[9], 0])
        }
        Some(&crate::STX_V1) if frame.len() >= 6 => u32::from(frame[5]),
        _ => 0,
    }
}

/// Message ids PX4 accepts unsigned on a link that requires signing
/// (`mavlink_sign_control.cpp`: RADIO_STATUS, ADSB_VEHICLE, COLLISION).
pub const PX4_UNSIGNED_OK: &[u32] = &[109, 246, 247];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Decoder, Encoder, MavMessage, dialect::*};
    use std::sync::Arc;

    fn key(b: u8) -> SigningKey {
        SigningKey::from_bytes([b; KEY_LEN])
    }

    fn ping() -> MavMessage {
        MavMessage::SYSTEM_TIME(SYSTEM_TIME_DATA {
            time_unix_usec: 1,
            time_boot_ms: 2,
        })
    }

    fn signed_frame(enc: &mut Encoder) -> Vec<u8> {
        enc.encode(&ping()).as_bytes().to_vec()
    }

    #[test]
    fn key_files_are_64_hex_characters_and_nothing_else() {
        let k = SigningKey::parse_hex(&format!("  {}\n", "aB".repeat(32))).unwrap();
        assert_eq!(k.as_bytes(), &[0xab; 32]);
        assert_eq!(k.to_hex(), "ab".repeat(32));
        let short = SigningKey::parse_hex("abcd").unwrap_err();
        assert!(short.0.contains("found 4 characters"), "{short}");
        let bad = SigningKey::parse_hex(&format!("zz{}", "00".repeat(31))).unwrap_err();
        assert!(bad.0.contains("not hex"), "{bad}");
        // Raw 32 bytes (a binary key file) are refused too.
        assert!(SigningKey::parse_hex(&"\u{1}".repeat(32)).is_err());
        assert!(!format!("{k:?}").contains("ab"));
    }

    #[test]
    fn a_signed_frame_verifies_and_decodes_with_the_same_key_only() {
        let signer = Arc::new(LinkSigning::new(key(7), 3));
        let mut enc = Encoder::new(1, 1);
        enc.set_signing(Some(signer.clone()));
        let bytes = signed_frame(&mut enc);
        assert_eq!(bytes[2] & IFLAG_SIGNED, IFLAG_SIGNED);
        assert_eq!(bytes.len(), 12 + usize::from(bytes[1]) + 13);
        assert_eq!(bytes[bytes.len() - 13], 3, "link id");
        // The decoder still reads signed frames.
        let mut got = 0;
        Decoder::default().decode_datagram(&bytes, |_| got += 1);
        assert_eq!(got, 1);
        let peer = LinkSigning::new(key(7), 0);
        assert_eq!(peer.verify(&bytes), Verdict::Valid);
        assert_eq!(
            LinkSigning::new(key(8), 0).verify(&bytes),
            Verdict::BadSignature
        );
        // One flipped payload bit (CRC recomputed by an attacker) breaks the signature.
        let mut forged = bytes.clone();
        forged[10] ^= 1;
        assert_eq!(
            LinkSigning::new(key(7), 0).verify(&forged),
            Verdict::BadSignature
        );
        assert_eq!(signer.counts().frames_signed, 1);
    }

    #[test]
    fn replays_and_stale_new_streams_are_refused_and_counted() {
        let signer = Arc::new(LinkSigning::new(key(1), 0));
        let mut enc = Encoder::new(2, 1);
        enc.set_signing(Some(signer));
        let first = signed_frame(&mut enc);
        let second = signed_frame(&mut enc);
        let rx = LinkSigning::new(key(1), 0);
        assert!(rx.accept(&first, &[]));
        assert!(rx.accept(&second, &[]));
        assert!(!rx.accept(&first, &[]), "older than the stream's last");
        assert!(!rx.accept(&second, &[]), "equal to the stream's last");
        // A new stream (another sysid) signed two minutes ago: outside the window.
        let old = LinkSigning::new(key(1), 0);
        old.advance_clock(0);
        let mut raw = MAVLinkV2MessageRaw::new();
        raw.serialize_message_for_signing(
            mavlink::MavHeader {
                system_id: 9,
                component_id: 1,
                sequence: 0,
            },
            &ping(),
        );
        *raw.signature_link_id_mut() = 0;
        let stale = timestamp_now() - 2 * NEW_STREAM_WINDOW;
        raw.signature_timestamp_bytes_mut()
            .copy_from_slice(&stale.to_le_bytes()[..6]);
        let mut sig = [0u8; SIGNATURE_VALUE_SIZE];
        raw.calculate_signature(key(1).as_bytes(), &mut sig);
        raw.signature_value_mut().copy_from_slice(&sig);
        assert!(!rx.accept(raw.raw_bytes(), &[]));
        // Unsigned: refused unless on the allow list.
        let plain = Encoder::new(2, 1).encode(&ping()).as_bytes().to_vec();
        assert!(!rx.accept(&plain, &[]));
        assert!(
            rx.accept(&plain, &[2]),
            "SYSTEM_TIME (2) allowed unsigned here"
        );
        assert!(!is_signed(&plain) && is_signed(&first));
        // A MAVLink 1 frame whose sequence byte (where v2 keeps its flags) is odd.
        let mut v1 = mavlink::MAVLinkV1MessageRaw::new();
        v1.serialize_message(
            mavlink::MavHeader {
                system_id: 2,
                component_id: 1,
                sequence: 1,
            },
            &ping(),
        );
        assert!(!is_signed(v1.raw_bytes()));
        let c = rx.counts();
        assert_eq!(
            (
                c.signed_ok,
                c.replayed,
                c.too_old,
                c.unsigned,
                c.bad_signature
            ),
            (2, 2, 1, 1, 0)
        );
        assert_eq!(c.dropped(), 4);
    }

    #[test]
    fn timestamps_are_strictly_increasing_and_near_now() {
        let s = LinkSigning::new(key(3), 0);
        let mut last = 0;
        for _ in 0..100 {
            let mut raw = MAVLinkV2MessageRaw::new();
            raw.serialize_message_for_signing(mavlink::MavHeader::default(), &ping());
            s.sign(&mut raw);
            let ts = raw.signature_timestamp();
            assert!(ts > last);
            last = ts;
        }
        let now = timestamp_now();
        // 10 µs units since 2015: within a second of now.
        assert!(last.abs_diff(now) < 100_000, "{last} vs {now}");
        assert!(now > 10 * 365 * 86_400 * 100_000, "after 2025");
    }
}
