//! A MAVLink FTP client that reads one file (`mftp://` URIs of the Component Metadata
//! Protocol), without I/O: payloads in ([`FtpRead::on_reply`]), time in
//! ([`FtpRead::on_tick`]), payloads out ([`FtpRead::take_outgoing`]).
//!
//! How it reads, against PX4's `MavlinkFTP` (one session; see `skein_sim::ftp_server`):
//! `OpenFileRO` (its ACK gives the size), then `BurstReadFile` from offset 0: PX4 streams
//! the file in 239-byte ACKs and ends with a NAK `Eof`, or stops a long file after about
//! 35 kB with `burst_complete`. The client keeps which bytes arrived, by offset, so
//! reordered or duplicated messages do no harm. When a burst ends (its end seen, or no
//! data for [`BURST_IDLE`]: its tail lost) the first gap is asked for again: a long one
//! with a new burst from its start, a short one with `ReadFile`. Once every byte is
//! there the session is closed (`TerminateSession`, not waited for) and the bytes handed
//! over.
//!
//! A request without its reply after [`REQUEST_TIMEOUT`] is sent again with the same
//! sequence number (PX4 answers a repeated request with its last reply), at most
//! [`MAX_TRIES`] times; a burst that brings nothing [`MAX_TRIES`] times in a row fails.
//! NAKs: `NoSessionsAvailable` (a session another client left open) or
//! `InvalidSession` (PX4 closed an idle one) reset the sessions and open the file again;
//! `FileNotFound` and the rest fail with the error named. Replies whose sequence number
//! or request opcode are not the request's (late, duplicated) are ignored.

use skein_mavlink::ftp::{FtpPayload, MAX_DATA, NakError, Opcode};
use std::time::{Duration, Instant};

/// Wait for a reply before sending a request again.
pub const REQUEST_TIMEOUT: Duration = Duration::from_millis(500);
/// A burst without data for this long has ended (its end, or its tail, was lost).
pub const BURST_IDLE: Duration = Duration::from_millis(300);
/// Transmissions of one request, and bursts in a row without data, before failing.
pub const MAX_TRIES: u32 = 8;
/// Sessions reset (`ResetSessions`) before failing.
pub const MAX_RESETS: u32 = 3;
/// A gap longer than this many messages is read with a burst, a shorter one with
/// `ReadFile`.
const BURST_GAP_MESSAGES: usize = 4;

/// Why a read failed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FtpError {
    /// The file's FTP path.
    pub path: String,
    /// What went wrong (`"no such file (NAK FileNotFound to OpenFileRO)"`).
    pub reason: String,
}

impl std::fmt::Display for FtpError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "MAVLink FTP read of {}: {}", self.path, self.reason)
    }
}

/// What a read sent, for whoever reports it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FtpStats {
    /// Requests sent (first transmissions).
    pub requests: u32,
    /// Requests sent again after a timeout.
    pub retries: u32,
    /// Bursts asked for.
    pub bursts: u32,
    /// `ReadFile`s asked for (gaps).
    pub reads: u32,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    Opening,
    Resetting,
    Bursting { last_data: Instant, progress: bool },
    Reading,
    Done,
}

struct Pending {
    req: FtpPayload,
    sent_at: Instant,
    tries: u32,
}

/// One file being read (see the module docs).
pub struct FtpRead {
    path: String,
    seq: u16,
    state: State,
    session: u8,
    data: Vec<u8>,
    have: Vec<bool>,
    received: usize,
    pending: Option<Pending>,
    outgoing: Vec<FtpPayload>,
    resets: u32,
    idle_bursts: u32,
    stats: FtpStats,
}

impl FtpRead {
    /// Starts reading `path` (an FTP path: `etc/extras/x.json.xz`) at `now`; its first
    /// request is in [`FtpRead::take_outgoing`].
    pub fn new(path: &str, now: Instant) -> Self {
        let mut r = FtpRead {
            path: path.to_string(),
            seq: 0,
            state: State::Opening,
            session: 0,
            data: Vec::new(),
            have: Vec::new(),
            received: 0,
            pending: None,
            outgoing: Vec::new(),
            resets: 0,
            idle_bursts: 0,
            stats: FtpStats::default(),
        };
        r.open(now);
        r
    }

    /// The payloads to send now (each once).
    pub fn take_outgoing(&mut self) -> Vec<FtpPayload> {
        std::mem::take(&mut self.outgoing)
    }

    /// What was sent so far.
    pub fn stats(&self) -> FtpStats {
        self.stats
    }

    /// The file's size once known, bytes.
    pub fn size(&self) -> Option<usize> {
        (self.state != State::Opening && self.state != State::Resetting).then_some(self.data.len())
    }

    fn fail(&self, reason: impl Into<String>) -> Option<Result<Vec<u8>, FtpError>> {
        Some(Err(FtpError {
            path: self.path.clone(),
            reason: reason.into(),
        }))
    }

    fn send(&mut self, opcode: Opcode, offset: u32, data: &[u8], now: Instant, awaited: bool) {
        self.seq = self.seq.wrapping_add(1);
        let req = FtpPayload::request(self.seq, self.session, opcode, offset, data);
        self.stats.requests += 1;
        self.outgoing.push(req.clone());
        self.pending = awaited.then_some(Pending {
            req,
            sent_at: now,
            tries: 1,
        });
    }

    fn open(&mut self, now: Instant) {
        self.state = State::Opening;
        let path = self.path.clone();
        self.send(Opcode::OpenFileRO, 0, path.as_bytes(), now, true);
    }

    fn burst(&mut self, offset: usize, now: Instant) {
        self.state = State::Bursting {
            last_data: now,
            progress: false,
        };
        self.stats.bursts += 1;
        self.send(Opcode::BurstReadFile, offset as u32, &[], now, false);
    }

    /// Takes the bytes of an ACK at `offset`; true when they were new.
    fn store(&mut self, offset: u32, bytes: &[u8]) -> bool {
        let start = offset as usize;
        let end = (start + bytes.len()).min(self.data.len());
        let mut new = false;
        for i in start..end {
            if !self.have[i] {
                self.have[i] = true;
                self.data[i] = bytes[i - start];
                self.received += 1;
                new = true;
            }
        }
        new
    }

    /// Asks for the first gap, or finishes.
    fn next_gap(&mut self, now: Instant) -> Option<Result<Vec<u8>, FtpError>> {
        let Some(start) = self.have.iter().position(|h| !h) else {
            return self.finish();
        };
        let run = self.have[start..].iter().take_while(|h| !**h).count();
        if run > BURST_GAP_MESSAGES * MAX_DATA {
            self.burst(start, now);
        } else {
            self.state = State::Reading;
            self.stats.reads += 1;
            self.send(Opcode::ReadFile, start as u32, &[], now, true);
        }
        None
    }

    fn finish(&mut self) -> Option<Result<Vec<u8>, FtpError>> {
        self.send(Opcode::TerminateSession, 0, &[], Instant::now(), false);
        self.state = State::Done;
        Some(Ok(std::mem::take(&mut self.data)))
    }

    fn reset(&mut self, why: NakError, now: Instant) -> Option<Result<Vec<u8>, FtpError>> {
        if self.resets >= MAX_RESETS {
            return self.fail(format!(
                "sessions still refused after {MAX_RESETS} resets ({why:?})"
            ));
        }
        self.resets += 1;
        self.state = State::Resetting;
        self.send(Opcode::ResetSessions, 0, &[], now, true);
        None
    }

    /// One reply from the vehicle at `now`: `Some` once the read is over (the bytes,
    /// or why not).
    pub fn on_reply(&mut self, p: &FtpPayload, now: Instant) -> Option<Result<Vec<u8>, FtpError>> {
        if self.state == State::Done {
            return None;
        }
        if p.req_opcode == Opcode::BurstReadFile {
            return self.on_burst(p, now);
        }
        let Some(pending) = &self.pending else {
            return None;
        };
        if p.seq != pending.req.seq.wrapping_add(1) || p.req_opcode != pending.req.opcode {
            return None; // late or repeated: not the answer to what we asked
        }
        let asked = pending.req.opcode;
        self.pending = None;
        match (p.nak_error(), asked) {
            (Some(e @ (NakError::NoSessionsAvailable | NakError::InvalidSession)), _) => {
                self.reset(e, now)
            }
            (Some(NakError::FileNotFound), _) => {
                self.fail(format!("no such file (NAK FileNotFound to {asked:?})"))
            }
            (Some(e), _) => self.fail(format!("NAK {e:?} to {asked:?}")),
            (None, Opcode::ResetSessions) => {
                self.open(now);
                None
            }
            (None, Opcode::OpenFileRO) => {
                let size = p
                    .data
                    .get(..4)
                    .map_or(0, |b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]));
                self.session = p.session;
                self.data = vec![0; size as usize];
                self.have = vec![false; size as usize];
                self.received = 0;
                if size == 0 {
                    self.finish()
                } else {
                    self.burst(0, now);
                    None
                }
            }
            (None, Opcode::ReadFile) => {
                if p.data.is_empty() {
                    return self.fail(format!(
                        "empty read at offset {} of {} bytes",
                        p.offset,
                        self.data.len()
                    ));
                }
                self.store(p.offset, &p.data);
                self.next_gap(now)
            }
            _ => None,
        }
    }

    fn on_burst(&mut self, p: &FtpPayload, now: Instant) -> Option<Result<Vec<u8>, FtpError>> {
        if self.have.is_empty() {
            return None; // not open yet: a burst of an earlier read
        }
        match p.nak_error() {
            Some(NakError::Eof) => {}
            Some(e @ NakError::InvalidSession) => return self.reset(e, now),
            Some(e) => return self.fail(format!("NAK {e:?} to BurstReadFile")),
            None => {
                let new = self.store(p.offset, &p.data);
                if let State::Bursting {
                    last_data,
                    progress,
                } = &mut self.state
                {
                    *last_data = now;
                    *progress |= new;
                }
                if self.received == self.data.len() {
                    return self.finish();
                }
                if !p.burst_complete {
                    return None;
                }
            }
        }
        // The burst ended (its end, or its 35 kB chunk): what is still missing next.
        if matches!(self.state, State::Bursting { .. }) {
            self.idle_bursts = 0;
            return self.next_gap(now);
        }
        None
    }

    /// Time passes (call every 100 ms or so): requests sent again, a burst's lost end
    /// noticed; `Some` once the read is over.
    pub fn on_tick(&mut self, now: Instant) -> Option<Result<Vec<u8>, FtpError>> {
        if let State::Bursting {
            last_data,
            progress,
        } = self.state
        {
            if now.saturating_duration_since(last_data) < BURST_IDLE {
                return None;
            }
            self.idle_bursts = if progress { 0 } else { self.idle_bursts + 1 };
            if self.idle_bursts >= MAX_TRIES {
                return self.fail(format!(
                    "no data in {MAX_TRIES} bursts ({} of {} bytes)",
                    self.received,
                    self.data.len()
                ));
            }
            return self.next_gap(now);
        }
        let p = self.pending.as_mut()?;
        if now.saturating_duration_since(p.sent_at) < REQUEST_TIMEOUT {
            return None;
        }
        if p.tries >= MAX_TRIES {
            let op = p.req.opcode;
            return self.fail(format!("no answer to {op:?} after {MAX_TRIES} tries"));
        }
        p.tries += 1;
        p.sent_at = now;
        self.stats.retries += 1;
        self.outgoing.push(p.req.clone());
        None
    }
}

#[cfg(test)]
mod tests;
