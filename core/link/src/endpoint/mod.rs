//! One MAVLink endpoint: one fixed socket (PX4 locks onto the first address it hears), a
//! receive task that decodes frames, counts malformed input and routes frames by system
//! id, and a send path shared by the link actors, the heartbeat and the setpoint streams.
//!
//! An endpoint may carry one vehicle (PX4 SITL convention, a port per instance) or many
//! (PX4 instances ≥ 10 all send to 14549, telemetry radios, mavlink-router): frames are
//! demultiplexed by sysid, and a HEARTBEAT from an autopilot whose sysid has no route yet
//! is reported through the discovery callback so the coordinator can create its vehicle.
//!
//! The endpoint outlives the actors that use it: a restarted link actor re-registers its
//! route on the same socket, so the vehicle never sees a new address.
//!
//! MAVLink 2 signing is per vehicle ([`Endpoint::set_signing`]): frames to a signing
//! vehicle are signed, and its frames are checked before anything else looks at them
//! (routing, discovery, the address a `udpin` endpoint replies to): unsigned, badly
//! signed and replayed frames are counted ([`Endpoint::signing_counts`]) and dropped.

use crate::address::ConnectionAddress;
use arc_swap::ArcSwapOption;
use signing::SigningTable;
use skein_mavlink::dialect::{MavAutopilot, MavType};
use skein_mavlink::signing::PX4_UNSIGNED_OK;
use skein_mavlink::{DecodeCounts, DecodeStats, Decoder, Frame, MavMessage};
use std::collections::HashMap;
use std::io;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicU8, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError, RwLock, Weak};
use std::time::{Duration, Instant};
use tokio::net::UdpSocket;
use tokio::task::JoinHandle;

mod send;
mod signing;
mod stream;
pub(crate) use send::Outgoing;
pub use send::{SendCounts, SendError};
pub use signing::SigningSpec;

/// Our own MAVLink identity on an endpoint (sender of heartbeats, commands, setpoints).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Identity {
    /// Our system id (255 is the usual ground station id).
    pub sysid: u8,
    /// Our component id (190 = `MAV_COMP_ID_MISSIONPLANNER`, 191 = `MAV_COMP_ID_ONBOARD_COMPUTER`).
    pub compid: u8,
    /// The MAV_TYPE our heartbeat announces: `MAV_TYPE_GCS` on a ground station,
    /// `MAV_TYPE_ONBOARD_CONTROLLER` on a companion computer. PX4 tracks each with its own
    /// timeout (GCS loss drives `NAV_DLL_ACT`).
    pub mav_type: MavType,
}

impl Default for Identity {
    fn default() -> Self {
        Identity {
            sysid: 255,
            compid: 190,
            mav_type: MavType::MAV_TYPE_GCS,
        }
    }
}

/// A HEARTBEAT from an autopilot the endpoint has no route for.
#[derive(Debug, Clone, Copy)]
pub struct Discovery {
    /// The vehicle's system id.
    pub sysid: u8,
    /// The component that sent the heartbeat (1 for PX4's autopilot).
    pub compid: u8,
    /// Its `HEARTBEAT.type`.
    pub mav_type: MavType,
}

/// Receives the frames of one routed sysid. Called on the receive task: must be cheap
/// (typically an actor `cast`).
pub type FrameHandler = Arc<dyn Fn(Frame) + Send + Sync>;
/// Receives discoveries (see [`Discovery`]).
pub type DiscoveryHandler = Arc<dyn Fn(Discovery) + Send + Sync>;
/// Sees every accepted frame with its bytes as received (after the signature check),
/// e.g. to forward it to a ground station. Called on the receive task: must be cheap.
pub type FrameTap = Arc<dyn Fn(&Frame, &[u8]) + Send + Sync>;
/// Sees every message skein sends (to `sysid`), before encoding: what a recording
/// keeps of the setpoints and commands that left skein.
pub type SentTap = Arc<dyn Fn(u8, &MavMessage) + Send + Sync>;

/// What the endpoint knows of one system id. Shared between the receive path (which
/// updates it for every datagram) and the send path (setpoints, commands) without a lock
/// between them: the receive task may be descheduled at any instant (a starved process,
/// a CPU quota), and a send must never wait for it.
#[derive(Default)]
pub(crate) struct Peer {
    /// Where its datagrams come from (`udpin`), written only when it changes; read
    /// without a lock (the setpoint thread reads it for every setpoint, and a reader
    /// never waits for a descheduled writer).
    addr: ArcSwapOption<SocketAddr>,
    /// A fingerprint of `addr`, so the receive path compares without the lock.
    addr_key: AtomicU64,
    handler: Mutex<Option<FrameHandler>>,
    /// When a valid frame last arrived: nanoseconds since the endpoint opened + 1 (0:
    /// never).
    last_seen_ns: AtomicU64,
    discovered: AtomicBool,
}

impl Peer {
    fn addr(&self) -> Option<SocketAddr> {
        self.addr.load().as_deref().copied()
    }

    fn handler(&self) -> Option<FrameHandler> {
        self.handler
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    fn set_handler(&self, handler: Option<FrameHandler>) {
        *self.handler.lock().unwrap_or_else(PoisonError::into_inner) = handler;
    }

    /// Records `from` as its address (stored only when it changed).
    fn heard_from(&self, from: SocketAddr) {
        use std::hash::{Hash, Hasher};
        let mut h = std::collections::hash_map::DefaultHasher::new();
        from.hash(&mut h);
        let key = h.finish() | 1; // never 0, the key of "no address"
        if self.addr_key.load(Ordering::Acquire) != key {
            self.addr.store(Some(Arc::new(from)));
            self.addr_key.store(key, Ordering::Release);
        }
    }
}

enum Transport {
    Udp {
        socket: Arc<UdpSocket>,
        /// Remote address for `udpout`; `None` for `udpin` (reply to each sender).
        remote: Option<SocketAddr>,
    },
    /// `tcpout:`, `serial:`: frames go to the writer thread ([`stream`]).
    Stream { tx: stream::StreamTx },
}

/// A MAVLink endpoint (see module docs). Shared as `Arc<Endpoint>`; the receive task holds
/// only a weak reference and stops when the last `Arc` is dropped.
pub struct Endpoint {
    address: ConnectionAddress,
    local_addr: Option<SocketAddr>,
    identity: Identity,
    transport: Transport,
    /// Our sequence number (MAVLink `seq`), shared by every sender on the endpoint.
    seq: AtomicU8,
    /// When the endpoint opened (the peers' `last_seen_ns` count from here).
    opened: Instant,
    /// Peers by sysid; the map changes only when a new sysid is heard or routed.
    peers: RwLock<HashMap<u8, Arc<Peer>>>,
    discovery: RwLock<Option<DiscoveryHandler>>,
    signing: RwLock<SigningTable>,
    tap: RwLock<Option<FrameTap>>,
    sent_tap: ArcSwapOption<SentTap>,
    decode_stats: Arc<DecodeStats>,
    frames_sent: AtomicU64,
    send_errors: AtomicU64,
    no_route: AtomicU64,
    tasks: Mutex<Vec<JoinHandle<()>>>,
}

impl std::fmt::Debug for Endpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Endpoint")
            .field("address", &self.address)
            .field("local_addr", &self.local_addr)
            .finish_non_exhaustive()
    }
}

impl Drop for Endpoint {
    fn drop(&mut self) {
        for t in self.tasks.lock().expect("tasks lock").drain(..) {
            t.abort();
        }
    }
}

const MAX_DATAGRAM: usize = 65_536;

impl Endpoint {
    /// Opens the endpoint and starts its receive task. `udpin` binds the address (port 0
    /// picks a free port, see [`Endpoint::local_addr`]); `udpout` binds an ephemeral local
    /// port and sends to the remote; `tcpout` connects (and reconnects with backoff).
    ///
    /// # Errors
    /// The bind or connect error; `serial:` is refused until the serial transport exists.
    pub async fn open(address: ConnectionAddress, identity: Identity) -> io::Result<Arc<Self>> {
        let (transport, local_addr, reader) = match &address {
            ConnectionAddress::UdpIn(bind) => {
                let socket = Arc::new(UdpSocket::bind(bind).await?);
                let local = socket.local_addr()?;
                (
                    Transport::Udp {
                        socket: socket.clone(),
                        remote: None,
                    },
                    Some(local),
                    Reader::Udp(socket),
                )
            }
            ConnectionAddress::UdpOut(remote) => {
                let bind: SocketAddr = if remote.is_ipv4() {
                    "0.0.0.0:0".parse().expect("literal")
                } else {
                    "[::]:0".parse().expect("literal")
                };
                let socket = Arc::new(UdpSocket::bind(bind).await?);
                let local = socket.local_addr()?;
                (
                    Transport::Udp {
                        socket: socket.clone(),
                        remote: Some(*remote),
                    },
                    Some(local),
                    Reader::Udp(socket),
                )
            }
            ConnectionAddress::TcpOut(remote) => {
                let (tx, session) = stream::start(stream::Connector::Tcp(*remote))?;
                (Transport::Stream { tx }, None, Reader::Stream(session))
            }
            ConnectionAddress::Serial { device, baud } => {
                stream::check_serial(device, *baud)?;
                let (tx, session) = stream::start(stream::Connector::Serial {
                    device: device.clone(),
                    baud: *baud,
                })?;
                (Transport::Stream { tx }, None, Reader::Stream(session))
            }
        };
        // Show the port actually bound (`udpin:127.0.0.1:0` becomes `…:41234`).
        let address = match (address, local_addr) {
            (ConnectionAddress::UdpIn(_), Some(local)) => ConnectionAddress::UdpIn(local),
            (a, _) => a,
        };
        let endpoint = Arc::new(Endpoint {
            address,
            local_addr,
            identity,
            transport,
            seq: AtomicU8::new(0),
            opened: Instant::now(),
            peers: RwLock::new(HashMap::new()),
            discovery: RwLock::new(None),
            signing: RwLock::new(SigningTable::default()),
            tap: RwLock::new(None),
            sent_tap: ArcSwapOption::empty(),
            decode_stats: Arc::new(DecodeStats::default()),
            frames_sent: AtomicU64::new(0),
            send_errors: AtomicU64::new(0),
            no_route: AtomicU64::new(0),
            tasks: Mutex::new(Vec::new()),
        });
        let weak = Arc::downgrade(&endpoint);
        let task = match reader {
            Reader::Udp(socket) => tokio::spawn(udp_reader(weak, socket)),
            Reader::Stream(session) => session.spawn(weak),
        };
        endpoint.tasks.lock().expect("tasks lock").push(task);
        Ok(endpoint)
    }

    /// The connection string this endpoint was opened with.
    pub fn address(&self) -> &ConnectionAddress {
        &self.address
    }

    /// The bound local socket address (UDP endpoints).
    pub fn local_addr(&self) -> Option<SocketAddr> {
        self.local_addr
    }

    /// Our identity on this endpoint.
    pub fn identity(&self) -> Identity {
        self.identity
    }

    /// Installs the callback for HEARTBEATs of unrouted autopilots.
    pub fn set_discovery(&self, handler: DiscoveryHandler) {
        *self.discovery.write().expect("discovery lock") = Some(handler);
    }

    /// Installs (or removes) the tap that sees every accepted frame.
    pub fn set_tap(&self, tap: Option<FrameTap>) {
        *self.tap.write().expect("tap lock") = tap;
    }

    /// Installs (or removes) the tap that sees every message sent with
    /// [`Endpoint::send`] (and [`Endpoint::broadcast`]), whether or not it could be sent.
    pub fn set_sent_tap(&self, tap: Option<SentTap>) {
        self.sent_tap.store(tap.map(Arc::new));
    }

    /// The system ids heard on this endpoint.
    pub fn sysids(&self) -> Vec<u8> {
        self.peers
            .read()
            .expect("peers lock")
            .iter()
            .filter(|(_, p)| p.last_seen_ns.load(Ordering::Relaxed) != 0)
            .map(|(s, _)| *s)
            .collect()
    }

    /// The peer of `sysid`, made on first use (a sender that sends to it every period
    /// keeps it rather than looking it up each time).
    pub(crate) fn peer(&self, sysid: u8) -> Arc<Peer> {
        if let Some(p) = self.peers.read().expect("peers lock").get(&sysid) {
            return p.clone();
        }
        self.peers
            .write()
            .expect("peers lock")
            .entry(sysid)
            .or_default()
            .clone()
    }

    /// The peer of `sysid`, if it is known.
    fn known_peer(&self, sysid: u8) -> Option<Arc<Peer>> {
        self.peers.read().expect("peers lock").get(&sysid).cloned()
    }

    /// Routes every frame from `sysid` (any component) to `handler`, replacing a previous
    /// route (a restarted link actor re-registers here).
    pub fn route(&self, sysid: u8, handler: FrameHandler) {
        let p = self.peer(sysid);
        p.set_handler(Some(handler));
        p.discovered.store(true, Ordering::Release);
    }

    /// Removes the route of `sysid` (its frames are then dropped, and its next heartbeat is
    /// reported as a discovery again).
    pub fn unroute(&self, sysid: u8) {
        if let Some(p) = self.known_peer(sysid) {
            p.set_handler(None);
            p.discovered.store(false, Ordering::Release);
        }
    }

    /// When a valid frame from `sysid` last arrived.
    pub fn last_seen(&self, sysid: u8) -> Option<Instant> {
        self.seen(&*self.known_peer(sysid)?)
    }

    /// When a valid frame from `peer` (a record of this endpoint) last arrived.
    pub(crate) fn seen(&self, peer: &Peer) -> Option<Instant> {
        let ns = peer.last_seen_ns.load(Ordering::Acquire);
        (ns != 0).then(|| self.opened + Duration::from_nanos(ns - 1))
    }

    /// The address frames to `sysid` go to, if known.
    pub fn peer_addr(&self, sysid: u8) -> Option<SocketAddr> {
        match &self.transport {
            Transport::Udp {
                remote: Some(r), ..
            } => Some(*r),
            _ => self.known_peer(sysid).and_then(|p| p.addr()),
        }
    }

    /// Decoder counters (malformed, bad CRC, unknown messages …) of this endpoint.
    pub fn decode_counts(&self) -> DecodeCounts {
        self.decode_stats.snapshot()
    }

    /// Feeds one received datagram through the endpoint's ingress, as the receive task
    /// does with every datagram: MAVLink decoding (malformed bytes and frames counted in
    /// [`Endpoint::decode_counts`] and dropped), the signing check of a signing sysid,
    /// the peer address and discovery, then the handler routed to the frame's sysid
    /// (frames of an unrouted sysid are counted, not lost silently). `from` is the
    /// sender (`None` for byte streams). Public so the fuzz target drives the same path.
    pub fn ingest(&self, decoder: &mut Decoder, datagram: &[u8], from: Option<SocketAddr>) {
        decoder.decode_datagram_raw(datagram, |f, raw| self.deliver(f, raw, from));
    }

    fn deliver(&self, frame: Frame, raw: &[u8], from: Option<SocketAddr>) {
        let sysid = frame.sysid;
        if let Some(s) = self.signing_of(sysid)
            && !s.accept(raw, PX4_UNSIGNED_OK)
        {
            return;
        }
        let tap = self.tap.read().expect("tap lock").clone();
        if let Some(tap) = tap {
            tap(&frame, raw);
        }
        let p = self.peer(sysid);
        if let Some(from) = from {
            p.heard_from(from);
        }
        let since_open = self.opened.elapsed().as_nanos() as u64;
        p.last_seen_ns.store(since_open + 1, Ordering::Release);
        let handler = p.handler();
        let discover = match &frame.msg {
            MavMessage::HEARTBEAT(hb)
                if handler.is_none()
                    && hb.autopilot != MavAutopilot::MAV_AUTOPILOT_INVALID
                    && !p.discovered.swap(true, Ordering::AcqRel) =>
            {
                Some(Discovery {
                    sysid,
                    compid: frame.compid,
                    mav_type: hb.mavtype,
                })
            }
            _ => None,
        };
        if let Some(d) = discover {
            let cb = self.discovery.read().expect("discovery lock").clone();
            match cb {
                Some(cb) => cb(d),
                None => {
                    // Nobody to tell yet: forget it so the next heartbeat is reported.
                    p.discovered.store(false, Ordering::Release);
                }
            }
        }
        if let Some(h) = handler {
            h(frame);
        }
    }
}

enum Reader {
    Udp(Arc<UdpSocket>),
    Stream(stream::Session),
}

async fn udp_reader(endpoint: Weak<Endpoint>, socket: Arc<UdpSocket>) {
    let mut buf = vec![0u8; MAX_DATAGRAM];
    let Some(stats) = endpoint.upgrade().map(|e| e.decode_stats.clone()) else {
        return;
    };
    let mut decoder = Decoder::new(stats);
    loop {
        let (n, from) = match socket.recv_from(&mut buf).await {
            Ok(r) => r,
            // ICMP port unreachable from an earlier send shows up here on Linux: ignore.
            Err(e) if e.kind() == io::ErrorKind::ConnectionRefused => continue,
            Err(e) => {
                tracing::warn!("udp receive failed: {e}");
                continue;
            }
        };
        let Some(ep) = endpoint.upgrade() else { return };
        ep.ingest(&mut decoder, &buf[..n], Some(from));
    }
}
