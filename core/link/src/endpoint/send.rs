//! The endpoint's send path, shared by the link actors, the heartbeat, the ground-station
//! forward and the setpoint streams: encoding with our identity (sequence, signing), the
//! destination of each vehicle, and the socket, one frame at a time or many in one system
//! call (`sendmmsg(2)`: the setpoint clock sends every stream of one endpoint at once when
//! vehicles share a port, as PX4's instances from the 10th on, a telemetry radio or
//! mavlink-router do). Never blocks: a datagram the socket cannot take right now is
//! dropped and counted.

use super::{Endpoint, Peer, Transport, stream};
use nix::sys::socket::{MsgFlags, MultiHeaders, SockaddrStorage, sendmmsg};
use skein_mavlink::{EncodedFrame, Frame, MavMessage};
use std::io;
use std::io::IoSlice;
use std::net::SocketAddr;
use std::os::fd::AsRawFd;
use std::sync::atomic::Ordering;

/// Counters of the send path.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct SendCounts {
    /// Frames handed to the socket.
    pub frames_sent: u64,
    /// Frames dropped because the socket would block or failed.
    pub send_errors: u64,
    /// Frames dropped because the vehicle's address is not known yet.
    pub no_route: u64,
}

/// Why a frame could not be sent.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SendError {
    /// A `udpin` endpoint has not heard from this sysid yet, so it has no address.
    NoAddress(u8),
    /// The socket refused the datagram.
    Io(String),
}

impl std::fmt::Display for SendError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SendError::NoAddress(s) => write!(f, "no address known yet for sysid {s}"),
            SendError::Io(e) => write!(f, "send failed: {e}"),
        }
    }
}

impl std::error::Error for SendError {}

/// A frame encoded for one vehicle and where it goes (`None` on a byte stream), made by
/// [`Endpoint::prepare`].
pub(crate) struct Outgoing {
    dest: Option<SocketAddr>,
    frame: EncodedFrame,
}

/// Most datagrams in one `sendmmsg` call: the call's arrays live on the stack (some
/// 9 KiB), and a shared port's slice of a tick is some 60 vehicles (250 to a port).
const MAX_BATCH: usize = 64;

thread_local! {
    /// The message headers of `sendmmsg`, made once per thread that sends batches (the
    /// setpoint thread) and reused by every call.
    static SEND_HEADERS: std::cell::RefCell<MultiHeaders<SockaddrStorage>> =
        std::cell::RefCell::new(MultiHeaders::preallocate(MAX_BATCH, None));
}

/// Why [`Endpoint::write_counted`] could not send (described only by [`Endpoint::write`]).
enum WriteError {
    /// The socket refused the datagram.
    Io(std::io::Error),
    /// The byte stream's writer is gone.
    Closed,
    /// A UDP endpoint with no destination for the frame.
    NoDestination,
}

impl Endpoint {
    /// Send-path counters.
    pub fn send_counts(&self) -> SendCounts {
        SendCounts {
            frames_sent: self.frames_sent.load(Ordering::Relaxed),
            // A byte stream's writer thread drops what it could not write.
            send_errors: self.send_errors.load(Ordering::Relaxed)
                + match &self.transport {
                    Transport::Stream { tx } => tx.dropped(),
                    Transport::Udp { .. } => 0,
                },
            no_route: self.no_route.load(Ordering::Relaxed),
        }
    }

    /// Encodes `msg` with our identity and sends it to vehicle `sysid`. Never blocks: a
    /// datagram the socket cannot take right now is dropped and counted.
    ///
    /// # Errors
    /// [`SendError::NoAddress`] before a `udpin` endpoint has heard from `sysid`;
    /// [`SendError::Io`] when the socket refuses.
    pub fn send(&self, sysid: u8, msg: &MavMessage) -> Result<(), SendError> {
        let out = self.prepare(None, sysid, msg)?;
        self.write(out.dest, out.frame.as_bytes())
    }

    /// Sends a frame that another system encoded (a ground station's command) to vehicle
    /// `sysid`: its bytes unchanged, or, when that vehicle signs, re-encoded with the
    /// sender's own sysid, compid and sequence and signed with the vehicle's key.
    ///
    /// # Errors
    /// As [`Endpoint::send`].
    pub fn forward(&self, sysid: u8, frame: &Frame, raw: &[u8]) -> Result<(), SendError> {
        let signed;
        let bytes = match self.signing_of(sysid) {
            Some(s) => {
                signed = skein_mavlink::encode_frame(
                    frame.sysid,
                    frame.compid,
                    frame.seq,
                    &frame.msg,
                    Some(&s),
                );
                signed.as_bytes()
            }
            None => raw,
        };
        let dest = self.dest(None, sysid)?;
        self.write(dest, bytes)
    }

    /// Encodes `msg` for `sysid` (sequence, signing) and finds where it goes, without
    /// sending it (the sent tap sees it now). `peer` is the record of `sysid` when the
    /// caller keeps it ([`Endpoint::peer`]), saving the lookup.
    ///
    /// # Errors
    /// [`SendError::NoAddress`] before a `udpin` endpoint has heard from `sysid`.
    pub(crate) fn prepare(
        &self,
        peer: Option<&Peer>,
        sysid: u8,
        msg: &MavMessage,
    ) -> Result<Outgoing, SendError> {
        if let Some(tap) = self.sent_tap.load().as_deref() {
            tap(sysid, msg);
        }
        let dest = self.dest(peer, sysid)?;
        let signing = self.signing_of(sysid);
        let seq = self.seq.fetch_add(1, Ordering::Relaxed);
        let frame = skein_mavlink::encode_frame(
            self.identity.sysid,
            self.identity.compid,
            seq,
            msg,
            signing.as_deref(),
        );
        Ok(Outgoing { dest, frame })
    }

    /// Where frames to `sysid` go (`None` on a byte stream); `peer` as in
    /// [`Endpoint::prepare`].
    fn dest(&self, peer: Option<&Peer>, sysid: u8) -> Result<Option<SocketAddr>, SendError> {
        let Transport::Udp { remote, .. } = &self.transport else {
            return Ok(None);
        };
        let addr = remote.or_else(|| match peer {
            Some(p) => p.addr(),
            None => self.known_peer(sysid).and_then(|p| p.addr()),
        });
        match addr {
            Some(a) => Ok(Some(a)),
            None => {
                self.no_route.fetch_add(1, Ordering::Relaxed);
                Err(SendError::NoAddress(sysid))
            }
        }
    }

    fn write(&self, dest: Option<SocketAddr>, bytes: &[u8]) -> Result<(), SendError> {
        self.write_counted(dest, bytes).map_err(|e| match e {
            WriteError::Io(e) => SendError::Io(e.to_string()),
            WriteError::Closed => SendError::Io("stream closed".into()),
            WriteError::NoDestination => SendError::Io("no destination".into()),
        })
    }

    /// [`Endpoint::write`] without describing the error (nothing allocated on a UDP
    /// endpoint, even when the socket refuses: the setpoint thread's path).
    fn write_counted(&self, dest: Option<SocketAddr>, bytes: &[u8]) -> Result<(), WriteError> {
        let result = match (&self.transport, dest) {
            // Straight to the kernel: the socket is non-blocking, so a full buffer is an
            // error at once, as it would be through the runtime; this way a send made
            // from any thread (the setpoint streams' own) never waits for the runtime to
            // have seen the socket writable, and costs one system call.
            (Transport::Udp { socket, .. }, Some(dest)) => socket2::SockRef::from(&**socket)
                .send_to(bytes, &dest.into())
                .map(|_| ())
                .map_err(WriteError::Io),
            (Transport::Stream { tx }, _) => tx.try_send(bytes).map_err(|r| match r {
                stream::Refused::Full => WriteError::Io(io::ErrorKind::WouldBlock.into()),
                stream::Refused::TooLong => WriteError::Io(io::ErrorKind::InvalidInput.into()),
                stream::Refused::Closed => WriteError::Closed,
            }),
            (Transport::Udp { .. }, None) => Err(WriteError::NoDestination),
        };
        match &result {
            Ok(()) => self.frames_sent.fetch_add(1, Ordering::Relaxed),
            Err(_) => self.send_errors.fetch_add(1, Ordering::Relaxed),
        };
        result
    }

    /// Sends the frame of every item of `items` (each to its own destination) and tells
    /// `done` whether each one left. On a UDP endpoint several frames go to the socket in
    /// as few `sendmmsg` calls as it takes; a frame the socket refuses (full buffer,
    /// unreachable) is dropped and counted, and the frames after it are still sent.
    pub(crate) fn write_batch<T>(
        &self,
        items: &[T],
        frame: impl Fn(&T) -> &Outgoing,
        mut done: impl FnMut(&T, bool),
    ) {
        let socket = match &self.transport {
            // One frame gains nothing from a batch: one `sendto`.
            Transport::Udp { socket, .. } if items.len() > 1 => socket,
            _ => {
                for item in items {
                    let out = frame(item);
                    done(
                        item,
                        self.write_counted(out.dest, out.frame.as_bytes()).is_ok(),
                    );
                }
                return;
            }
        };
        // The call's arrays on the stack and its headers kept by the thread: nothing
        // allocated (see `crate::setpoint`).
        let mut addrs: [Option<SockaddrStorage>; MAX_BATCH] = [None; MAX_BATCH];
        let mut at = 0;
        while at < items.len() {
            let end = items.len().min(at + MAX_BATCH);
            let chunk = &items[at..end];
            for (a, i) in addrs.iter_mut().zip(chunk) {
                *a = frame(i).dest.map(SockaddrStorage::from);
            }
            let iov: [[IoSlice<'_>; 1]; MAX_BATCH] = std::array::from_fn(|k| {
                [IoSlice::new(
                    chunk.get(k).map_or(&[][..], |i| frame(i).frame.as_bytes()),
                )]
            });
            // How many left before the first one the socket refused (an error on the
            // first frame is the call's error).
            let taken = SEND_HEADERS.with_borrow_mut(|headers| {
                sendmmsg(
                    socket.as_raw_fd(),
                    headers,
                    &iov[..chunk.len()],
                    &addrs[..chunk.len()],
                    [],
                    MsgFlags::MSG_DONTWAIT,
                )
                .map_or(0, |sent| sent.count())
            });
            self.frames_sent.fetch_add(taken as u64, Ordering::Relaxed);
            for item in &chunk[..taken] {
                done(item, true);
            }
            at += taken;
            if at < end {
                self.send_errors.fetch_add(1, Ordering::Relaxed);
                done(&items[at], false);
                at += 1;
            }
        }
    }

    /// Sends `msg` where vehicles of this endpoint will hear it: to the remote (`udpout`,
    /// `tcpout`), or to every vehicle heard so far (`udpin`). Returns how many were sent.
    pub fn broadcast(&self, msg: &MavMessage) -> usize {
        match &self.transport {
            Transport::Udp { remote: None, .. } => {
                let sysids: Vec<u8> = self
                    .peers
                    .read()
                    .expect("peers lock")
                    .iter()
                    .filter(|(_, p)| p.addr().is_some())
                    .map(|(s, _)| *s)
                    .collect();
                sysids
                    .iter()
                    .filter(|s| self.send(**s, msg).is_ok())
                    .count()
            }
            _ => usize::from(self.send(0, msg).is_ok()),
        }
    }
}
