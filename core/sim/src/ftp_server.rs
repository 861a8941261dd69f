//! A MAVLink FTP server as PX4 v1.16's `MavlinkFTP` (`src/modules/mavlink/mavlink_ftp.cpp`)
//! serves files, read-only, without I/O: requests in ([`FtpServer::handle`]), replies
//! and burst data out ([`FtpServer::pump`]).
//!
//! What PX4 does and this server does too:
//! - one session (id 0): `OpenFileRO` while it is open is NAKed
//!   `NoSessionsAvailable`; a missing file `FileNotFound`; the ACK's data is the file
//!   size (u32); a session idle for [`SESSION_IDLE`] is closed;
//! - `ReadFile` sends up to 239 bytes from `offset`, NAK `Eof` at or past the end, NAK
//!   `InvalidSession` without the session;
//! - `BurstReadFile` answers with no ACK of its own: data ACKs (`req_opcode`
//!   BurstReadFile, consecutive sequence numbers from the request's + 1, `offset` of
//!   their data) until the end of the file, then a NAK `Eof`; after more than
//!   [`BURST_CHUNK_BYTES`] the burst stops with `burst_complete` set and the client asks
//!   again from where it stopped;
//! - `TerminateSession`, `ResetSessions`, `CalcFileCRC32`, `None`; any other opcode is
//!   NAKed `UnknownCommand` (the simulator has nothing to write or list);
//! - a request whose `seq_number + 1` is the last reply's gets that reply again (a lost
//!   ACK), kept for replies of at most 4 data bytes, as PX4 keeps them.

use skein_mavlink::ftp::{FtpPayload, MAX_DATA, NakError, Opcode, crc32};
use std::time::{Duration, Instant};

/// A session without a request for this long is closed (PX4: 10 s).
pub const SESSION_IDLE: Duration = Duration::from_secs(10);
/// Bytes after which a burst ends with `burst_complete` (PX4: "35K chunks").
pub const BURST_CHUNK_BYTES: usize = 35_000;

/// Where the server's files come from: the file at an FTP path (no leading `/`).
pub type FileSource = fn(&str) -> Option<&'static [u8]>;

struct Burst {
    offset: usize,
    seq: u16,
    sent: usize,
    to: (u8, u8),
}

struct Session {
    data: &'static [u8],
    burst: Option<Burst>,
}

/// The FTP server of one vehicle (see the module docs).
pub struct FtpServer {
    source: FileSource,
    session: Option<Session>,
    last_reply: Option<FtpPayload>,
    last_activity: Option<Instant>,
}

impl std::fmt::Debug for FtpServer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FtpServer")
            .field("session_open", &self.session.is_some())
            .finish_non_exhaustive()
    }
}

fn nak(req: &FtpPayload, e: NakError) -> FtpPayload {
    FtpPayload {
        seq: req.seq.wrapping_add(1),
        session: req.session,
        opcode: Opcode::Nak,
        req_opcode: req.opcode,
        burst_complete: false,
        offset: req.offset,
        data: vec![e.to_u8()],
    }
}

fn ack(req: &FtpPayload, data: Vec<u8>) -> FtpPayload {
    FtpPayload {
        seq: req.seq.wrapping_add(1),
        session: req.session,
        opcode: Opcode::Ack,
        req_opcode: req.opcode,
        burst_complete: false,
        offset: req.offset,
        data,
    }
}

fn path_of(req: &FtpPayload) -> String {
    let end = req
        .data
        .iter()
        .position(|&b| b == 0)
        .unwrap_or(req.data.len());
    String::from_utf8_lossy(&req.data[..end])
        .trim_start_matches('/')
        .to_string()
}

impl FtpServer {
    /// A server of the files `source` gives.
    pub fn new(source: FileSource) -> Self {
        FtpServer {
            source,
            session: None,
            last_reply: None,
            last_activity: None,
        }
    }

    /// One request from `from` (sysid, compid) at `now`: the reply, or none (a burst's
    /// data follows from [`FtpServer::pump`]).
    pub fn handle(&mut self, req: &FtpPayload, from: (u8, u8), now: Instant) -> Option<FtpPayload> {
        self.last_activity = Some(now);
        if let Some(last) = &self.last_reply
            && req.seq.wrapping_add(1) == last.seq
        {
            return Some(last.clone());
        }
        self.last_reply = None;
        let reply = match req.opcode {
            Opcode::None => ack(req, vec![]),
            Opcode::TerminateSession | Opcode::ResetSessions => {
                let valid = req.opcode == Opcode::ResetSessions
                    || (req.session == 0 && self.session.is_some());
                self.session = None;
                if valid {
                    ack(req, vec![])
                } else {
                    nak(req, NakError::InvalidSession)
                }
            }
            Opcode::OpenFileRO => self.open(req),
            Opcode::ReadFile => self.read(req),
            Opcode::BurstReadFile => match self.session.as_mut() {
                Some(s) if req.session == 0 => {
                    s.burst = Some(Burst {
                        offset: req.offset as usize,
                        seq: req.seq.wrapping_add(1),
                        sent: 0,
                        to: from,
                    });
                    return None;
                }
                _ => nak(req, NakError::InvalidSession),
            },
            Opcode::CalcFileCrc32 => match (self.source)(&path_of(req)) {
                Some(data) => ack(req, crc32(data).to_le_bytes().to_vec()),
                None => nak(req, NakError::FileNotFound),
            },
            _ => nak(req, NakError::UnknownCommand),
        };
        if reply.data.len() <= 4 {
            self.last_reply = Some(reply.clone());
        }
        Some(reply)
    }

    fn open(&mut self, req: &FtpPayload) -> FtpPayload {
        if self.session.is_some() {
            return nak(req, NakError::NoSessionsAvailable);
        }
        let Some(data) = (self.source)(&path_of(req)) else {
            return nak(req, NakError::FileNotFound);
        };
        self.session = Some(Session { data, burst: None });
        let mut a = ack(req, (data.len() as u32).to_le_bytes().to_vec());
        a.session = 0;
        a
    }

    fn read(&mut self, req: &FtpPayload) -> FtpPayload {
        let Some(s) = self.session.as_ref().filter(|_| req.session == 0) else {
            return nak(req, NakError::InvalidSession);
        };
        let offset = req.offset as usize;
        if offset >= s.data.len() {
            return nak(req, NakError::Eof);
        }
        let end = (offset + MAX_DATA).min(s.data.len());
        ack(req, s.data[offset..end].to_vec())
    }

    /// The burst in progress at `now`, at most `max` messages of it, each with the
    /// (sysid, compid) it goes to; closes a session idle for [`SESSION_IDLE`].
    pub fn pump(&mut self, now: Instant, max: usize) -> Vec<((u8, u8), FtpPayload)> {
        if self
            .last_activity
            .is_some_and(|t| now.saturating_duration_since(t) > SESSION_IDLE)
        {
            self.session = None;
            self.last_reply = None;
            self.last_activity = None;
        }
        let mut out = Vec::new();
        let Some(s) = self.session.as_mut() else {
            return out;
        };
        while out.len() < max {
            let Some(b) = s.burst.as_mut() else { break };
            let mut p = FtpPayload {
                seq: b.seq,
                session: 0,
                opcode: Opcode::Ack,
                req_opcode: Opcode::BurstReadFile,
                burst_complete: false,
                offset: b.offset as u32,
                data: vec![],
            };
            b.seq = b.seq.wrapping_add(1);
            let to = b.to;
            if b.offset >= s.data.len() {
                p.opcode = Opcode::Nak;
                p.data = vec![NakError::Eof.to_u8()];
                s.burst = None;
            } else {
                let end = (b.offset + MAX_DATA).min(s.data.len());
                p.data = s.data[b.offset..end].to_vec();
                b.sent += end - b.offset;
                b.offset = end;
                if b.sent > BURST_CHUNK_BYTES {
                    p.burst_complete = true;
                    s.burst = None;
                }
            }
            out.push((to, p));
        }
        out
    }
}
