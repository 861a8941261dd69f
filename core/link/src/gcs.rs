//! Ground-station forwarding, as mavlink-router does it: every frame a vehicle sends
//! reaches the ground station (QGroundControl) unchanged, with the vehicle's own sysid,
//! and frames from the ground station go back to the vehicle their `target_system` names
//! (0, or no target at all: every vehicle).
//!
//! One rule is skein's own: skein is the only source of setpoints. A vehicle in OFFBOARD
//! follows whichever setpoint arrived last, so a ground station's
//! `SET_POSITION_TARGET_LOCAL_NED`, `SET_POSITION_TARGET_GLOBAL_INT` or
//! `SET_ATTITUDE_TARGET` would fight the formation's stream 50 times a second and could
//! fly a member into its neighbours, past the separation and geofence checks that every
//! skein setpoint goes through. Those are counted and dropped; commands, mode changes,
//! parameters and missions pass.
//!
//! A vehicle whose link signs (see [`Endpoint::set_signing`]) gets the ground station's
//! frames re-encoded with the ground station's sysid, compid and sequence and signed with
//! its key; to the ground station frames go as the vehicle sent them (signed or not).
//! The forwarder owns one UDP socket: `udpout:HOST:PORT` sends to QGroundControl's port
//! (14550) from an ephemeral port, `udpin:ADDR:PORT` binds and answers the last sender.

use crate::address::ConnectionAddress;
use crate::endpoint::Endpoint;
use skein_mavlink::dialect::MavMessage;
use skein_mavlink::{DecodeCounts, DecodeStats, Decoder, Frame};
use std::io;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, Weak};
use tokio::net::UdpSocket;
use tokio::task::JoinHandle;

/// Counters of a ground-station forwarder.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct ForwardCounts {
    /// Vehicle frames sent to the ground station.
    pub to_gcs: u64,
    /// Vehicle frames not sent: no ground-station address yet (`udpin` before it spoke)
    /// or the socket refused.
    pub to_gcs_dropped: u64,
    /// Ground-station frames delivered to a vehicle (a broadcast counts once per vehicle).
    pub from_gcs: u64,
    /// Ground-station setpoints dropped (skein is the only source of setpoints).
    pub setpoints_dropped: u64,
    /// Ground-station frames for a sysid no endpoint has heard.
    pub no_route: u64,
}

#[derive(Debug, Default)]
struct Stats {
    to_gcs: AtomicU64,
    to_gcs_dropped: AtomicU64,
    from_gcs: AtomicU64,
    setpoints_dropped: AtomicU64,
    no_route: AtomicU64,
}

/// Forwards the frames of a set of endpoints to a ground station and back (see the module
/// docs).
pub struct GcsForwarder {
    address: ConnectionAddress,
    local_addr: SocketAddr,
    socket: Arc<UdpSocket>,
    /// Where vehicle frames go: fixed for `udpout`, the last sender for `udpin`.
    remote: Mutex<Option<SocketAddr>>,
    fixed_remote: bool,
    vehicles: Vec<Arc<Endpoint>>,
    decode_stats: Arc<DecodeStats>,
    stats: Stats,
    task: Mutex<Option<JoinHandle<()>>>,
}

impl std::fmt::Debug for GcsForwarder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GcsForwarder")
            .field("address", &self.address)
            .field("local_addr", &self.local_addr)
            .finish_non_exhaustive()
    }
}

impl Drop for GcsForwarder {
    fn drop(&mut self) {
        if let Some(t) = self.task.lock().unwrap_or_else(|e| e.into_inner()).take() {
            t.abort();
        }
    }
}

/// True for the messages a ground station may not send through skein: setpoints.
pub fn is_setpoint(msg: &MavMessage) -> bool {
    matches!(
        msg,
        MavMessage::SET_POSITION_TARGET_LOCAL_NED(_)
            | MavMessage::SET_POSITION_TARGET_GLOBAL_INT(_)
            | MavMessage::SET_ATTITUDE_TARGET(_)
    )
}

impl GcsForwarder {
    /// Opens the ground-station socket, taps every endpoint of `vehicles` and starts
    /// forwarding. Stops when the returned `Arc` is dropped (the taps hold a weak
    /// reference).
    ///
    /// # Errors
    /// A transport other than `udpout:` / `udpin:`, or the bind error.
    pub async fn start(
        address: ConnectionAddress,
        vehicles: Vec<Arc<Endpoint>>,
    ) -> io::Result<Arc<Self>> {
        let (bind, remote): (SocketAddr, Option<SocketAddr>) = match &address {
            ConnectionAddress::UdpOut(r) if r.is_ipv4() => {
                ("0.0.0.0:0".parse().expect("literal"), Some(*r))
            }
            ConnectionAddress::UdpOut(r) => ("[::]:0".parse().expect("literal"), Some(*r)),
            ConnectionAddress::UdpIn(b) => (*b, None),
            other => {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidInput,
                    format!("ground-station forwarding takes udpout: or udpin:, not {other}"),
                ));
            }
        };
        let socket = Arc::new(UdpSocket::bind(bind).await?);
        let local_addr = socket.local_addr()?;
        let address = match address {
            ConnectionAddress::UdpIn(_) => ConnectionAddress::UdpIn(local_addr),
            a => a,
        };
        let fwd = Arc::new(GcsForwarder {
            address,
            local_addr,
            socket: socket.clone(),
            remote: Mutex::new(remote),
            fixed_remote: remote.is_some(),
            vehicles,
            decode_stats: Arc::new(DecodeStats::default()),
            stats: Stats::default(),
            task: Mutex::new(None),
        });
        for ep in &fwd.vehicles {
            let weak = Arc::downgrade(&fwd);
            ep.set_tap(Some(Arc::new(move |_frame: &Frame, raw: &[u8]| {
                if let Some(f) = weak.upgrade() {
                    f.send_to_gcs(raw);
                }
            })));
        }
        let task = tokio::spawn(receive(Arc::downgrade(&fwd), socket));
        *fwd.task.lock().unwrap_or_else(|e| e.into_inner()) = Some(task);
        Ok(fwd)
    }

    /// The connection string (`udpin` with the port actually bound).
    pub fn address(&self) -> &ConnectionAddress {
        &self.address
    }

    /// The forwarder's own socket address.
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// The counters.
    pub fn counts(&self) -> ForwardCounts {
        let l = |a: &AtomicU64| a.load(Ordering::Relaxed);
        ForwardCounts {
            to_gcs: l(&self.stats.to_gcs),
            to_gcs_dropped: l(&self.stats.to_gcs_dropped),
            from_gcs: l(&self.stats.from_gcs),
            setpoints_dropped: l(&self.stats.setpoints_dropped),
            no_route: l(&self.stats.no_route),
        }
    }

    /// Decoder counters of what the ground station sent (malformed input).
    pub fn decode_counts(&self) -> DecodeCounts {
        self.decode_stats.snapshot()
    }

    fn bump(c: &AtomicU64) {
        c.fetch_add(1, Ordering::Relaxed);
    }

    /// One vehicle frame, as received, to the ground station.
    fn send_to_gcs(&self, raw: &[u8]) {
        let remote = *self.remote.lock().unwrap_or_else(|e| e.into_inner());
        match remote.map(|r| self.socket.try_send_to(raw, r)) {
            Some(Ok(_)) => Self::bump(&self.stats.to_gcs),
            _ => Self::bump(&self.stats.to_gcs_dropped),
        }
    }

    /// One ground-station frame to the vehicle(s) it is for.
    fn route_from_gcs(&self, frame: &Frame, raw: &[u8]) {
        if is_setpoint(&frame.msg) {
            Self::bump(&self.stats.setpoints_dropped);
            return;
        }
        let target = skein_mavlink::target_system(&frame.msg).unwrap_or(0);
        let mut delivered = 0;
        for ep in &self.vehicles {
            for sysid in ep.sysids() {
                if (target == 0 || sysid == target)
                    && sysid != frame.sysid
                    && ep.forward(sysid, frame, raw).is_ok()
                {
                    delivered += 1;
                }
            }
        }
        if delivered == 0 && target != 0 {
            Self::bump(&self.stats.no_route);
        }
        self.stats.from_gcs.fetch_add(delivered, Ordering::Relaxed);
    }
}

async fn receive(fwd: Weak<GcsForwarder>, socket: Arc<UdpSocket>) {
    let Some(stats) = fwd.upgrade().map(|f| f.decode_stats.clone()) else {
        return;
    };
    let mut decoder = Decoder::new(stats);
    let mut buf = vec![0u8; 65_536];
    loop {
        let (n, from) = match socket.recv_from(&mut buf).await {
            Ok(r) => r,
            Err(e) if e.kind() == io::ErrorKind::ConnectionRefused => continue,
            Err(e) => {
                tracing::warn!("ground-station socket: {e}");
                tokio::time::sleep(std::time::Duration::from_millis(5)).await;
                continue;
            }
        };
        let Some(f) = fwd.upgrade() else { return };
        if !f.fixed_remote {
            *f.remote.lock().unwrap_or_else(|e| e.into_inner()) = Some(from);
        }
        decoder.decode_datagram_raw(&buf[..n], |frame, raw| f.route_from_gcs(&frame, raw));
    }
}
