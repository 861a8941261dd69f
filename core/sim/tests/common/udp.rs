//! [`Client`]: a ground station over real UDP (its own socket, `skein_mavlink`'s encoder
//! and decoder, nothing shared with the simulator), and [`Streamer`], a setpoint stream
//! from its socket at a fixed rate.

use super::station::GroundStation;
use super::{CLIENT_COMPID, CLIENT_SYSID};
use skein_mavlink::{DecodeStats, Decoder, Encoder, Frame, MavMessage};
use std::collections::VecDeque;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::net::UdpSocket;

/// A ground station on its own UDP socket, talking to one simulated vehicle.
pub struct Client {
    /// The client's socket.
    pub sock: Arc<UdpSocket>,
    /// Encoder of what the client sends (sysid [`CLIENT_SYSID`]).
    pub enc: Encoder,
    /// Decoder of what the vehicle sends (its counters say what was malformed).
    pub dec: Decoder,
    /// The vehicle's socket.
    pub peer: SocketAddr,
    /// The vehicle's system id.
    pub sysid: u8,
    /// Datagrams read from the socket so far, decoded or dropped.
    pub datagrams_read: u64,
    queue: VecDeque<Frame>,
    buf: Vec<u8>,
}

impl Client {
    /// A client on `sock` for the vehicle `sysid` at `peer`, sending as `compid`.
    pub fn from_socket(sock: UdpSocket, peer: SocketAddr, sysid: u8, compid: u8) -> Client {
        Client {
            sock: Arc::new(sock),
            enc: Encoder::new(CLIENT_SYSID, compid),
            dec: Decoder::new(Arc::new(DecodeStats::default())),
            peer,
            sysid,
            datagrams_read: 0,
            queue: VecDeque::new(),
            buf: vec![0; 65536],
        }
    }

    /// A second client (own socket) talking to the same vehicle.
    pub async fn bind(peer: SocketAddr, sysid: u8, compid: u8) -> Client {
        let sock = UdpSocket::bind("127.0.0.1:0").await.expect("bind client");
        Client::from_socket(sock, peer, sysid, compid)
    }

    /// Sends bytes as they are (malformed input).
    pub async fn send_raw(&self, bytes: &[u8]) {
        self.sock.send_to(bytes, self.peer).await.expect("send raw");
    }

    /// The bytes of the next datagram from the vehicle, or None after `timeout`.
    pub async fn next_raw(&mut self, timeout: Duration) -> Option<Vec<u8>> {
        let (n, _) = tokio::time::timeout(timeout, self.sock.recv_from(&mut self.buf))
            .await
            .ok()?
            .expect("recv");
        self.datagrams_read += 1;
        Some(self.buf[..n].to_vec())
    }

    /// Drops everything received so far.
    pub fn clear(&mut self) {
        self.queue.clear();
        while self.sock.try_recv_from(&mut self.buf).is_ok() {
            self.datagrams_read += 1;
        }
    }
}

/// Drops what `clients` received and everything still on its way to them: polls until,
/// together, their sockets have received `sent` datagrams since they were bound (the
/// simulator's `datagrams_sent` of a vehicle that sends only to them, read once it has
/// stopped sending: silenced or killed). Panics after 5 s.
pub async fn clear_through(clients: &mut [&mut Client], sent: u64) {
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        for c in clients.iter_mut() {
            c.clear();
        }
        let read: u64 = clients.iter().map(|c| c.datagrams_read).sum();
        if read >= sent {
            return;
        }
        assert!(
            Instant::now() < deadline,
            "only {read} of the {sent} datagrams sent arrived"
        );
        tokio::time::sleep(Duration::from_millis(2)).await;
    }
}

impl GroundStation for Client {
    fn sysid(&self) -> u8 {
        self.sysid
    }

    fn now(&self) -> Instant {
        Instant::now()
    }

    async fn send(&mut self, msg: &MavMessage) {
        let frame = self.enc.encode(msg);
        self.sock
            .send_to(frame.as_bytes(), self.peer)
            .await
            .expect("send");
    }

    async fn next(&mut self, deadline: Instant) -> Option<Frame> {
        loop {
            if let Some(f) = self.queue.pop_front() {
                return Some(f);
            }
            let left = deadline.checked_duration_since(Instant::now())?;
            let (n, _) = tokio::time::timeout(left, self.sock.recv_from(&mut self.buf))
                .await
                .ok()?
                .expect("recv");
            self.datagrams_read += 1;
            let queue = &mut self.queue;
            self.dec
                .decode_datagram(&self.buf[..n], |f| queue.push_back(f));
        }
    }
}

/// Streams setpoints at a fixed rate from the client's socket until stopped.
pub struct Streamer {
    current: Arc<Mutex<MavMessage>>,
    task: tokio::task::JoinHandle<()>,
    /// When the stream started.
    pub started: Instant,
}

impl Streamer {
    /// Streams `msg` (changeable with [`Streamer::set`]).
    pub fn start(client: &Client, msg: MavMessage, rate_hz: f64) -> Streamer {
        let current = Arc::new(Mutex::new(msg));
        let shared = current.clone();
        Self::spawn(client, rate_hz, current, move |_| {
            shared.lock().expect("lock").clone()
        })
    }

    /// Streams `f(seconds since start)`.
    pub fn start_fn(
        client: &Client,
        rate_hz: f64,
        f: impl Fn(f64) -> MavMessage + Send + 'static,
    ) -> Streamer {
        let current = Arc::new(Mutex::new(f(0.0)));
        Self::spawn(client, rate_hz, current, f)
    }

    fn spawn(
        client: &Client,
        rate_hz: f64,
        current: Arc<Mutex<MavMessage>>,
        f: impl Fn(f64) -> MavMessage + Send + 'static,
    ) -> Streamer {
        let sock = client.sock.clone();
        let peer = client.peer;
        let started = Instant::now();
        let task = tokio::spawn(async move {
            let mut enc = Encoder::new(CLIENT_SYSID, CLIENT_COMPID + 1);
            let mut iv = tokio::time::interval(Duration::from_secs_f64(1.0 / rate_hz));
            loop {
                iv.tick().await;
                let msg = f(started.elapsed().as_secs_f64());
                let frame = enc.encode(&msg);
                let _ = sock.send_to(frame.as_bytes(), peer).await;
            }
        });
        Streamer {
            current,
            task,
            started,
        }
    }

    /// Streams `msg` from now on.
    pub fn set(&self, msg: MavMessage) {
        *self.current.lock().expect("lock") = msg;
    }

    /// Stops the stream.
    pub fn stop(self) {
        self.task.abort();
    }
}
