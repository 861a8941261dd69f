//! MAVLink framing for skein, shared by the PX4 link and the simulator.
//!
//! The `mavlink` crate provides the common dialect (message structs, CRC_EXTRA, payload
//! (de)serialisation). This crate adds what a swarm link needs on top of it:
//! - [`Decoder`]: finds MAVLink 1 and 2 frames in datagrams (UDP) or byte streams (TCP,
//!   serial), checks CRCs, and *counts* everything it drops (bad CRC, unknown message id,
//!   unparsable payload, truncated frames, garbage bytes) in shared [`DecodeStats`], so a
//!   malformed datagram is visible in the API instead of silently lost.
//! - [`Encoder`]: serialises MAVLink 2 frames with a per-sender sequence number.
//!
//! - [`command`]: the command protocol's `COMMAND_LONG` / `COMMAND_INT` frames, built in one
//!   place for the link, the simulator's clients and the plugins.
//! - [`param`]: parameter values in PX4's bytewise wire encoding.
//! - [`signing`]: MAVLink 2 message signing (keys, signing, replay protection).
//! - [`statustext`]: `STATUSTEXT` chunks as PX4 sends a long text.
//! - [`events`]: PX4's event ids and log levels (the events interface).
//! - [`ftp`]: MAVLink FTP's payload and PX4's metadata CRC32.
//!
//! Only the common dialect is compiled (one feature set for the whole workspace).
#![warn(missing_docs)]

pub mod command;
pub mod events;
pub mod ftp;
pub mod param;
pub mod signing;
pub mod statustext;

/// Per-message constants (`ID`, `EXTRA_CRC`) of the dialect's message structs.
pub use command::{CommandPosition, CommandTarget, command_int, command_long};
pub use mavlink::MessageData;
/// The largest MAVLink frame, bytes: v2 with a full payload and a signature (10 header +
/// 255 payload + 2 CRC + 13 signature).
pub use mavlink::consts::MAX_FRAME_SIZE;
pub use mavlink::dialects::common as dialect;
pub use mavlink::dialects::common::MavMessage;
use mavlink::{MAVLinkV2MessageRaw, MavHeader, Message, calculate_crc};
use signing::LinkSigning;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// MAVLink 1 start-of-frame marker.
pub const STX_V1: u8 = 0xFE;
/// MAVLink 2 start-of-frame marker.
pub const STX_V2: u8 = 0xFD;
/// `MAVLINK_IFLAG_SIGNED`: the frame carries a 13-byte signature after the CRC.
const IFLAG_SIGNED: u8 = 0x01;
const SIGNATURE_LEN: usize = 13;
const V2_HEADER_LEN: usize = 10; // STX .. msgid (3 bytes)
const V1_HEADER_LEN: usize = 6;
const CRC_LEN: usize = 2;

/// A decoded, CRC-valid frame.
#[derive(Debug, Clone)]
pub struct Frame {
    /// Sender system id.
    pub sysid: u8,
    /// Sender component id.
    pub compid: u8,
    /// Sender sequence number (for loss and reboot detection).
    pub seq: u8,
    /// 1 or 2.
    pub version: u8,
    /// The message.
    pub msg: MavMessage,
}

/// Counters of one decoder, shared with whoever reports them (atomics, relaxed).
#[derive(Debug, Default)]
pub struct DecodeStats {
    frames_ok: AtomicU64,
    mavlink1_frames: AtomicU64,
    bad_crc: AtomicU64,
    unknown_message: AtomicU64,
    parse_errors: AtomicU64,
    truncated: AtomicU64,
    bad_flags: AtomicU64,
    garbage_bytes: AtomicU64,
    datagrams: AtomicU64,
    rejected_datagrams: AtomicU64,
}

/// A plain copy of [`DecodeStats`] for reporting.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct DecodeCounts {
    /// Valid frames delivered.
    pub frames_ok: u64,
    /// Of which MAVLink 1.
    pub mavlink1_frames: u64,
    /// Frames of a known message whose CRC did not match.
    pub bad_crc: u64,
    /// Frames whose message id is not in the common dialect.
    pub unknown_message: u64,
    /// CRC-valid frames whose payload did not parse (bad enum value, oversize payload).
    pub parse_errors: u64,
    /// Frames cut short at the end of a datagram.
    pub truncated: u64,
    /// MAVLink 2 frames with incompatibility flags skein does not understand.
    pub bad_flags: u64,
    /// Bytes skipped while looking for a start-of-frame marker.
    pub garbage_bytes: u64,
    /// Datagrams (or stream reads) handled.
    pub datagrams: u64,
    /// Datagrams that contained no valid frame at all.
    pub rejected_datagrams: u64,
}

impl DecodeCounts {
    /// Every dropped frame or run of garbage, summed: the number a "malformed" alarm
    /// watches.
    pub fn errors(&self) -> u64 {
        self.bad_crc
            + self.unknown_message
            + self.parse_errors
            + self.truncated
            + self.bad_flags
            + self.rejected_datagrams
    }
}

impl DecodeStats {
    /// A copy of the counters.
    pub fn snapshot(&self) -> DecodeCounts {
        let l = |a: &AtomicU64| a.load(Ordering::Relaxed);
        DecodeCounts {
            frames_ok: l(&self.frames_ok),
            mavlink1_frames: l(&self.mavlink1_frames),
            bad_crc: l(&self.bad_crc),
            unknown_message: l(&self.unknown_message),
            parse_errors: l(&self.parse_errors),
            truncated: l(&self.truncated),
            bad_flags: l(&self.bad_flags),
            garbage_bytes: l(&self.garbage_bytes),
            datagrams: l(&self.datagrams),
            rejected_datagrams: l(&self.rejected_datagrams),
        }
    }

    fn bump(counter: &AtomicU64, by: u64) {
        counter.fetch_add(by, Ordering::Relaxed);
    }
}

/// What the decoder found at the front of its buffer.
// Returned by value once per frame on the receive path: boxing the frame would cost an
// allocation per message, which is what the lint's advice amounts to.
#[allow(clippy::large_enum_variant)]
enum Step {
    /// A frame of `len` bytes; `Some` when it decoded.
    Frame(usize, Option<Frame>),
    /// Skip this many bytes (garbage before a marker, or a marker that led nowhere).
    Skip(usize),
    /// Need more bytes.
    Incomplete,
}

/// Finds, validates and decodes MAVLink frames; counts what it drops.
///
/// Use [`Decoder::decode_datagram`] for UDP (each datagram holds whole frames) and
/// [`Decoder::push`] + [`Decoder::next_frame`] for byte streams.
#[derive(Debug)]
pub struct Decoder {
    buf: Vec<u8>,
    stats: Arc<DecodeStats>,
}

impl Default for Decoder {
    fn default() -> Self {
        Self::new(Arc::new(DecodeStats::default()))
    }
}

impl Decoder {
    /// A decoder that records into `stats`.
    pub fn new(stats: Arc<DecodeStats>) -> Self {
        Decoder {
            buf: Vec::with_capacity(2048),
            stats,
        }
    }

    /// The counters this decoder writes.
    pub fn stats(&self) -> &Arc<DecodeStats> {
        &self.stats
    }

    /// Decodes one UDP datagram and calls `on_frame` for every valid frame in it. Bytes
    /// left over at the end (a cut frame) are counted as truncated and discarded.
    pub fn decode_datagram(&mut self, datagram: &[u8], mut on_frame: impl FnMut(Frame)) {
        self.decode_datagram_raw(datagram, |f, _| on_frame(f));
    }

    /// [`Decoder::decode_datagram`], also handing over each frame's bytes as received
    /// (to check a signature, or forward the frame unchanged).
    pub fn decode_datagram_raw(&mut self, datagram: &[u8], mut on_frame: impl FnMut(Frame, &[u8])) {
        DecodeStats::bump(&self.stats.datagrams, 1);
        let mut pos = 0;
        let mut delivered = false;
        while pos < datagram.len() {
            match self.step(&datagram[pos..]) {
                Step::Frame(len, frame) => {
                    if let Some(f) = frame {
                        delivered = true;
                        on_frame(f, &datagram[pos..pos + len]);
                    }
                    pos += len;
                }
                Step::Skip(n) => pos += n,
                Step::Incomplete => {
                    DecodeStats::bump(&self.stats.truncated, 1);
                    break;
                }
            }
        }
        if !delivered {
            DecodeStats::bump(&self.stats.rejected_datagrams, 1);
        }
    }

    /// Appends stream bytes (TCP, serial); read frames with [`Decoder::next_frame`].
    pub fn push(&mut self, bytes: &[u8]) {
        DecodeStats::bump(&self.stats.datagrams, 1);
        self.buf.extend_from_slice(bytes);
    }

    /// The next valid frame from the stream buffer, or `None` when more bytes are needed.
    pub fn next_frame(&mut self) -> Option<Frame> {
        self.next_frame_raw(|f, _| f)
    }

    /// [`Decoder::next_frame`], handing the frame and its bytes as received to `f`.
    pub fn next_frame_raw<R>(&mut self, f: impl FnOnce(Frame, &[u8]) -> R) -> Option<R> {
        let mut consumed = 0;
        let mut out = None;
        while consumed < self.buf.len() {
            // Split borrow: `step` only reads the counters.
            let step = Self::step_with(&self.stats, &self.buf[consumed..]);
            match step {
                Step::Frame(len, frame) => {
                    if let Some(frame) = frame {
                        out = Some(f(frame, &self.buf[consumed..consumed + len]));
                        consumed += len;
                        break;
                    }
                    consumed += len;
                }
                Step::Skip(n) => consumed += n,
                Step::Incomplete => break,
            }
        }
        self.buf.drain(..consumed);
        out
    }

    fn step(&self, bytes: &[u8]) -> Step {
        Self::step_with(&self.stats, bytes)
    }

    fn step_with(stats: &DecodeStats, bytes: &[u8]) -> Step {
        let Some(start) = bytes.iter().position(|&b| b == STX_V2 || b == STX_V1) else {
            DecodeStats::bump(&stats.garbage_bytes, bytes.len() as u64);
            return Step::Skip(bytes.len());
        };
        if start > 0 {
            DecodeStats::bump(&stats.garbage_bytes, start as u64);
            return Step::Skip(start);
        }
        let v2 = bytes[0] == STX_V2;
        let header_len = if v2 { V2_HEADER_LEN } else { V1_HEADER_LEN };
        if bytes.len() < header_len {
            return Step::Incomplete;
        }
        let payload_len = usize::from(bytes[1]);
        let incompat = if v2 { bytes[2] } else { 0 };
        if incompat & !IFLAG_SIGNED != 0 {
            DecodeStats::bump(&stats.bad_flags, 1);
            return Step::Skip(1);
        }
        let sig_len = if incompat & IFLAG_SIGNED != 0 {
            SIGNATURE_LEN
        } else {
            0
        };
        let frame_len = header_len + payload_len + CRC_LEN + sig_len;
        if bytes.len() < frame_len {
            return Step::Incomplete;
        }
        let (seq, sysid, compid, msgid) = if v2 {
            (
                bytes[4],
                bytes[5],
                bytes[6],
                u32::from_le_bytes([bytes[7], bytes[8], bytes[9], 0]),
            )
        } else {
            (bytes[2], bytes[3], bytes[4], u32::from(bytes[5]))
        };
        let crc_at = header_len + payload_len;
        let crc = u16::from_le_bytes([bytes[crc_at], bytes[crc_at + 1]]);
        let extra = MavMessage::extra_crc(msgid);
        if calculate_crc(&bytes[1..crc_at], extra) != crc {
            if MavMessage::default_message_from_id(msgid).is_none() {
                DecodeStats::bump(&stats.unknown_message, 1);
                // An unknown message cannot be CRC-checked: trust its length field.
                return Step::Frame(frame_len, None);
            }
            DecodeStats::bump(&stats.bad_crc, 1);
            // The marker may have been a payload byte: resynchronise one byte on.
            return Step::Skip(1);
        }
        let version = if v2 {
            mavlink::MavlinkVersion::V2
        } else {
            mavlink::MavlinkVersion::V1
        };
        let payload = &bytes[header_len..crc_at];
        match MavMessage::parse(version, msgid, payload) {
            Ok(msg) => {
                DecodeStats::bump(&stats.frames_ok, 1);
                if !v2 {
                    DecodeStats::bump(&stats.mavlink1_frames, 1);
                }
                Step::Frame(
                    frame_len,
                    Some(Frame {
                        sysid,
                        compid,
                        seq,
                        version: if v2 { 2 } else { 1 },
                        msg,
                    }),
                )
            }
            Err(mavlink::error::ParserError::UnknownMessage { .. }) => {
                DecodeStats::bump(&stats.unknown_message, 1);
                Step::Frame(frame_len, None)
            }
            Err(_) => {
                DecodeStats::bump(&stats.parse_errors, 1);
                Step::Frame(frame_len, None)
            }
        }
    }
}

/// Serialises MAVLink 2 frames for one sender (system id, component id), numbering them,
/// and signs them when given a [`LinkSigning`].
#[derive(Debug, Clone)]
pub struct Encoder {
    sysid: u8,
    compid: u8,
    seq: u8,
    signing: Option<Arc<LinkSigning>>,
}

impl Encoder {
    /// An encoder that signs its frames as `sysid`/`compid` (e.g. 255/190 for a ground
    /// station, 1/1 for an autopilot).
    pub fn new(sysid: u8, compid: u8) -> Self {
        Encoder {
            sysid,
            compid,
            seq: 0,
            signing: None,
        }
    }

    /// Signs every frame from now on with `signing` (`None`: unsigned frames).
    pub fn set_signing(&mut self, signing: Option<Arc<LinkSigning>>) {
        self.signing = signing;
    }

    /// The signing in use, if any.
    pub fn signing(&self) -> Option<&Arc<LinkSigning>> {
        self.signing.as_ref()
    }

    /// The sender system id.
    pub fn sysid(&self) -> u8 {
        self.sysid
    }

    /// The sender component id.
    pub fn compid(&self) -> u8 {
        self.compid
    }

    /// Encodes `msg` as the next MAVLink 2 frame, signed if the encoder signs.
    pub fn encode(&mut self, msg: &MavMessage) -> EncodedFrame {
        let signing = self.signing.clone();
        self.encode_with(msg, signing.as_deref())
    }

    /// Encodes `msg` as the next frame, signed with `signing` when given (whatever the
    /// encoder's own setting: an endpoint shared by vehicles with their own keys).
    pub fn encode_with(&mut self, msg: &MavMessage, signing: Option<&LinkSigning>) -> EncodedFrame {
        let frame = encode_frame(self.sysid, self.compid, self.seq, msg, signing);
        self.seq = self.seq.wrapping_add(1);
        frame
    }

    /// Encodes `msg` and appends the frame bytes to `out` (to batch several frames into
    /// one datagram).
    pub fn encode_into(&mut self, msg: &MavMessage, out: &mut Vec<u8>) {
        out.extend_from_slice(self.encode(msg).as_bytes());
    }
}

/// Encodes `msg` as one MAVLink 2 frame from `sysid`/`compid` with sequence number `seq`,
/// signed with `signing` when given (to re-sign another system's frame on a signed link).
pub fn encode_frame(
    sysid: u8,
    compid: u8,
    seq: u8,
    msg: &MavMessage,
    signing: Option<&LinkSigning>,
) -> EncodedFrame {
    let mut raw = MAVLinkV2MessageRaw::new();
    let header = MavHeader {
        system_id: u32::from(sysid),
        component_id: compid,
        sequence: seq,
    };
    match signing {
        Some(s) => {
            raw.serialize_message_for_signing(header, msg);
            s.sign(&mut raw);
        }
        None => raw.serialize_message(header, msg),
    }
    EncodedFrame(raw)
}

/// One encoded frame.
pub struct EncodedFrame(MAVLinkV2MessageRaw);

impl EncodedFrame {
    /// The frame's bytes, ready for a socket.
    pub fn as_bytes(&self) -> &[u8] {
        self.0.raw_bytes()
    }
}

/// The name of a message (`"HEARTBEAT"`), for logs and counters.
pub fn message_name(msg: &MavMessage) -> &'static str {
    msg.message_name()
}

/// The `target_system` a message is addressed to (`None` for messages without one, such
/// as HEARTBEAT; `Some(0)` is a broadcast).
pub fn target_system(msg: &MavMessage) -> Option<u8> {
    msg.target_system_id()
}

/// The id of a message (0 for `HEARTBEAT`).
pub fn message_id(msg: &MavMessage) -> u32 {
    msg.message_id()
}

#[cfg(test)]
mod tests {
    use super::*;
    use dialect::*;

    fn heartbeat() -> MavMessage {
        MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: 50_593_792,
            mavtype: MavType::MAV_TYPE_QUADROTOR,
            autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
            base_mode: MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
            system_status: MavState::MAV_STATE_STANDBY,
            mavlink_version: 3,
        })
    }

    fn ack() -> MavMessage {
        MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            result: MavResult::MAV_RESULT_ACCEPTED,
            progress: 0,
            result_param2: 0,
            target_system: 255,
            target_component: 190,
        })
    }

    #[test]
    fn round_trip_several_frames_in_one_datagram() {
        let mut enc = Encoder::new(3, 1);
        let mut dgram = Vec::new();
        enc.encode_into(&heartbeat(), &mut dgram);
        enc.encode_into(&ack(), &mut dgram);
        let mut dec = Decoder::default();
        let mut got = Vec::new();
        dec.decode_datagram(&dgram, |f| got.push(f));
        assert_eq!(got.len(), 2);
        assert_eq!((got[0].sysid, got[0].compid, got[0].seq), (3, 1, 0));
        assert_eq!(got[1].seq, 1);
        assert!(matches!(got[1].msg, MavMessage::COMMAND_ACK(ref a) if a.target_system == 255));
        let c = dec.stats().snapshot();
        assert_eq!((c.frames_ok, c.errors()), (2, 0));
    }

    #[test]
    fn bad_crc_is_counted_and_dropped() {
        let mut enc = Encoder::new(1, 1);
        let mut bytes = enc.encode(&heartbeat()).as_bytes().to_vec();
        let n = bytes.len();
        bytes[n - 1] ^= 0xff;
        let mut dec = Decoder::default();
        let mut got = 0;
        dec.decode_datagram(&bytes, |_| got += 1);
        assert_eq!(got, 0);
        let c = dec.stats().snapshot();
        assert_eq!(c.bad_crc, 1);
        assert_eq!(c.rejected_datagrams, 1);
    }

    #[test]
    fn unknown_message_id_is_counted() {
        // A syntactically fine MAVLink 2 frame with message id 0xABCDEF.
        let payload = [1u8, 2, 3];
        let mut f = vec![STX_V2, payload.len() as u8, 0, 0, 7, 1, 1, 0xEF, 0xCD, 0xAB];
        f.extend_from_slice(&payload);
        let crc = calculate_crc(&f[1..], 0);
        f.extend_from_slice(&crc.to_le_bytes());
        let mut dec = Decoder::default();
        dec.decode_datagram(&f, |_| panic!("must not decode"));
        assert_eq!(dec.stats().snapshot().unknown_message, 1);
    }

    #[test]
    fn garbage_and_truncation_are_counted_and_good_frames_still_found() {
        let mut enc = Encoder::new(1, 1);
        let good = enc.encode(&heartbeat()).as_bytes().to_vec();
        let mut dgram = b"hello world".to_vec();
        dgram.extend_from_slice(&good);
        dgram.extend_from_slice(&good[..good.len() - 3]);
        let mut dec = Decoder::default();
        let mut got = 0;
        dec.decode_datagram(&dgram, |_| got += 1);
        assert_eq!(got, 1);
        let c = dec.stats().snapshot();
        assert_eq!(c.garbage_bytes, 11);
        assert_eq!(c.truncated, 1);
        assert_eq!(c.rejected_datagrams, 0);
    }

    #[test]
    fn stream_decoding_across_arbitrary_splits() {
        let mut enc = Encoder::new(9, 1);
        let mut bytes = Vec::new();
        for _ in 0..20 {
            enc.encode_into(&heartbeat(), &mut bytes);
            enc.encode_into(&ack(), &mut bytes);
        }
        for chunk in [1usize, 3, 7, 64, 1000] {
            let mut dec = Decoder::default();
            let mut got = 0;
            for piece in bytes.chunks(chunk) {
                dec.push(piece);
                while dec.next_frame().is_some() {
                    got += 1;
                }
            }
            assert_eq!(got, 40, "chunk {chunk}");
            assert_eq!(dec.stats().snapshot().errors(), 0);
        }
    }

    #[test]
    fn mavlink1_frames_are_accepted_and_counted() {
        let mut raw = mavlink::MAVLinkV1MessageRaw::new();
        raw.serialize_message(
            MavHeader {
                system_id: 4,
                component_id: 1,
                sequence: 9,
            },
            &heartbeat(),
        );
        let mut dec = Decoder::default();
        let mut got = Vec::new();
        dec.decode_datagram(raw.raw_bytes(), |f| got.push(f));
        assert_eq!(got.len(), 1);
        assert_eq!((got[0].version, got[0].sysid, got[0].seq), (1, 4, 9));
        assert_eq!(dec.stats().snapshot().mavlink1_frames, 1);
    }

    proptest::proptest! {
        #[test]
        fn random_bytes_never_panic_and_are_accounted(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..600)) {
            let mut dec = Decoder::default();
            let mut n = 0u64;
            dec.decode_datagram(&bytes, |_| n += 1);
            let c = dec.stats().snapshot();
            proptest::prop_assert_eq!(c.frames_ok, n);
            if n == 0 { proptest::prop_assert_eq!(c.rejected_datagrams, 1); }
        }
    }
}
