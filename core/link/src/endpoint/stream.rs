//! The byte-stream transports, `tcpout:` and `serial:`: a session task on the process's
//! runtime (re)opens the connection with capped backoff and decodes what arrives, and a
//! writer thread of the endpoint's own writes what is sent.
//!
//! The writer is not a task on the process's worker threads. The setpoint streams hand it
//! their frames from the setpoint thread, and a worker that is kept busy (a plugin call,
//! a large body) or starved of CPU would hold every setpoint to a vehicle on a serial port
//! (a Pixhawk's TELEM2 on a companion computer's UART) for as long as it is held: the
//! pause the setpoint thread exists to prevent, and PX4 fails safe after `COM_OF_LOSS_T`.
//! So the writer thread asks for the setpoint thread's priority ([`crate::priority`]),
//! takes frames from a bounded queue that allocates nothing (each frame is copied into a
//! slot of [`MAX_FRAME_SIZE`] bytes; a full queue refuses the frame, as a full socket buffer
//! would), and writes each to a duplicate of the connection's descriptor, which the
//! session hands over on every (re)connection. A frame sent while the stream is down waits
//! [`RECONNECTING`] for it to come back; one that cannot leave then, or within
//! [`WRITE_TIMEOUT`] once written, is dropped and counted (setpoints are repeated anyway;
//! commands are resent by the command protocol).

use super::Endpoint;
use skein_mavlink::{Decoder, MAX_FRAME_SIZE};
use std::io::{self, Write};
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, SyncSender, TrySendError, sync_channel};
use std::sync::{Arc, Weak};
use std::time::{Duration, Instant};
use tokio::io::{AsyncRead, AsyncReadExt};
use tokio::net::TcpStream;
use tokio::sync::oneshot;
use tokio::task::JoinHandle;

/// Frames the writer may have queued: over a second of setpoints to a few vehicles.
const QUEUE: usize = 128;

/// How long a frame waits for the session to reopen a stream that closed.
const RECONNECTING: Duration = Duration::from_millis(200);

/// How long one frame may wait for the connection to take it (a serial port's buffer
/// full at a low baud rate) before it is dropped.
const WRITE_TIMEOUT: Duration = Duration::from_millis(50);

/// How a byte-stream transport (re)opens.
#[derive(Debug, Clone)]
pub(crate) enum Connector {
    /// `tcpout:`: connects to the remote.
    Tcp(SocketAddr),
    /// `serial:`: opens the device at the baud rate.
    Serial { device: String, baud: u32 },
}

/// Opens `device` at `baud` and closes it again: a wrong path or baud rate is an error
/// when the endpoint opens, not a silent retry loop.
///
/// # Errors
/// The open's error, naming `serial:DEVICE:BAUD`.
pub(crate) fn check_serial(device: &str, baud: u32) -> io::Result<()> {
    open_serial(device, baud).map(drop)
}

fn open_serial(device: &str, baud: u32) -> io::Result<serialport::TTYPort> {
    serialport::new(device, baud)
        .timeout(WRITE_TIMEOUT)
        .open_native()
        .map_err(|e| serial_error(device, baud, e))
}

/// A serial port's error, naming `serial:DEVICE:BAUD`.
fn serial_error(device: &str, baud: u32, e: impl std::fmt::Display) -> io::Error {
    io::Error::other(format!("serial:{device}:{baud}: {e}"))
}

impl Connector {
    /// A new connection: its reading side (registered with this runtime) and its writing
    /// side (a duplicate of the same descriptor, for the writer thread).
    async fn open(&self) -> io::Result<(Box<dyn AsyncRead + Send + Unpin>, Sink)> {
        match self {
            Connector::Tcp(remote) => {
                let s = TcpStream::connect(remote).await?;
                let _ = s.set_nodelay(true);
                let s = s.into_std()?;
                let writer = s.try_clone()?;
                Ok((Box::new(TcpStream::from_std(s)?), Sink::Tcp(writer)))
            }
            Connector::Serial { device, baud } => {
                let port = open_serial(device, *baud)?;
                let writer = port
                    .try_clone_native()
                    .map_err(|e| serial_error(device, *baud, e))?;
                let reader = tokio_serial::SerialStream::try_from(port)
                    .map_err(|e| serial_error(device, *baud, e))?;
                Ok((Box::new(reader), Sink::Serial(writer)))
            }
        }
    }
}

/// The writing side of one connection, owned by the writer thread.
enum Sink {
    Tcp(std::net::TcpStream),
    Serial(serialport::TTYPort),
}

impl Sink {
    /// Writes all of `bytes` within [`WRITE_TIMEOUT`] (the descriptor is non-blocking, as
    /// the session's reading side needs: a full buffer is waited out in 1 ms steps).
    ///
    /// # Errors
    /// `TimedOut` when the connection did not take it in time (the connection is kept);
    /// any other error means the connection is gone.
    fn write_frame(&mut self, mut bytes: &[u8]) -> io::Result<()> {
        let deadline = Instant::now() + WRITE_TIMEOUT;
        while !bytes.is_empty() {
            let written = match self {
                Sink::Tcp(s) => s.write(bytes),
                Sink::Serial(p) => p.write(bytes),
            };
            match written {
                Ok(0) => return Err(io::ErrorKind::WriteZero.into()),
                Ok(n) => bytes = &bytes[n..],
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                    ) =>
                {
                    if Instant::now() >= deadline {
                        return Err(io::ErrorKind::TimedOut.into());
                    }
                    std::thread::sleep(Duration::from_millis(1));
                }
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }
}

/// One queued frame.
struct Slot {
    len: usize,
    bytes: [u8; MAX_FRAME_SIZE],
}

/// Why [`StreamTx::try_send`] refused a frame.
pub(crate) enum Refused {
    /// The queue is full (the connection is slower than what is sent).
    Full,
    /// The writer thread is gone.
    Closed,
    /// Longer than a MAVLink frame can be.
    TooLong,
}

/// The sending side of a byte-stream endpoint (see the module docs): held by the
/// endpoint; dropping it ends the writer thread and the session.
pub(crate) struct StreamTx {
    frames: SyncSender<Slot>,
    /// Frames the writer thread dropped (stream down, timed out, write failed).
    dropped: Arc<AtomicU64>,
    /// Dropped with the endpoint: tells the session to end.
    _closed: oneshot::Sender<()>,
}

impl StreamTx {
    /// Queues `bytes` (one frame) for the writer thread. Never blocks, never allocates.
    pub(crate) fn try_send(&self, bytes: &[u8]) -> Result<(), Refused> {
        if bytes.len() > MAX_FRAME_SIZE {
            return Err(Refused::TooLong);
        }
        let mut slot = Slot {
            len: bytes.len(),
            bytes: [0; MAX_FRAME_SIZE],
        };
        slot.bytes[..bytes.len()].copy_from_slice(bytes);
        self.frames.try_send(slot).map_err(|e| match e {
            TrySendError::Full(_) => Refused::Full,
            TrySendError::Disconnected(_) => Refused::Closed,
        })
    }

    /// Frames the writer thread has dropped so far.
    pub(crate) fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}

/// Starts the writer thread of a byte stream opened by `connector`; the session that
/// feeds it connections is [`Session::spawn`]ed once the endpoint exists.
///
/// # Errors
/// The OS refused a thread.
pub(crate) fn start(connector: Connector) -> io::Result<(StreamTx, Session)> {
    let (frames, queued) = sync_channel(QUEUE);
    let (sinks, new_sinks) = std::sync::mpsc::channel();
    let dropped = Arc::new(AtomicU64::new(0));
    let counted = dropped.clone();
    let name = match &connector {
        Connector::Tcp(_) => "skein-tcp-tx",
        Connector::Serial { .. } => "skein-serial-tx",
    };
    std::thread::Builder::new()
        .name(name.into())
        .spawn(move || writer(&queued, &new_sinks, &counted))?;
    let (closed, on_close) = oneshot::channel();
    Ok((
        StreamTx {
            frames,
            dropped,
            _closed: closed,
        },
        Session {
            connector,
            sinks,
            closed: on_close,
        },
    ))
}

/// What the session task needs (see [`start`]).
pub(crate) struct Session {
    connector: Connector,
    sinks: Sender<Option<Sink>>,
    closed: oneshot::Receiver<()>,
}

impl Session {
    /// Spawns the session on this runtime, for `endpoint`.
    pub(crate) fn spawn(self, endpoint: Weak<Endpoint>) -> JoinHandle<()> {
        tokio::spawn(session(endpoint, self.connector, self.sinks, self.closed))
    }
}

/// The writer thread: each queued frame to the current connection's sink. Without one
/// (the stream is being reopened), a frame waits up to [`RECONNECTING`] for the next, then
/// it and whatever queued behind it are dropped: a burst of stale setpoints must not
/// follow a long outage.
fn writer(queued: &Receiver<Slot>, sinks: &Receiver<Option<Sink>>, dropped: &AtomicU64) {
    crate::priority::raise_writer_thread();
    let mut sink: Option<Sink> = None;
    while let Ok(frame) = queued.recv() {
        while let Ok(s) = sinks.try_recv() {
            sink = s;
        }
        if sink.is_none() {
            match sinks.recv_timeout(RECONNECTING) {
                Ok(s) => sink = s,
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => return,
            }
        }
        let Some(s) = sink.as_mut() else {
            let stale = 1 + queued.try_iter().count() as u64;
            dropped.fetch_add(stale, Ordering::Relaxed);
            continue;
        };
        if let Err(e) = s.write_frame(&frame.bytes[..frame.len]) {
            dropped.fetch_add(1, Ordering::Relaxed);
            if e.kind() != io::ErrorKind::TimedOut {
                // Gone: the session reconnects and hands over the next one.
                sink = None;
            }
        }
    }
}

/// The session: (re)opens with capped backoff and decodes what arrives, until the
/// endpoint is dropped (`closed`).
async fn session(
    endpoint: Weak<Endpoint>,
    connector: Connector,
    sinks: Sender<Option<Sink>>,
    mut closed: oneshot::Receiver<()>,
) {
    let mut backoff = Duration::from_millis(100);
    loop {
        let (mut reader, sink) = match connector.open().await {
            Ok(s) => s,
            Err(e) => {
                tracing::debug!("{connector:?}: open failed: {e}; retrying in {backoff:?}");
                tokio::select! {
                    _ = tokio::time::sleep(backoff) => {}
                    _ = &mut closed => return,
                }
                backoff = (backoff * 2).min(Duration::from_secs(5));
                continue;
            }
        };
        backoff = Duration::from_millis(100);
        if sinks.send(Some(sink)).is_err() {
            return; // the writer thread is gone
        }
        let Some(stats) = endpoint.upgrade().map(|e| e.decode_stats.clone()) else {
            return;
        };
        let mut decoder = Decoder::new(stats);
        let mut buf = vec![0u8; 8192];
        loop {
            tokio::select! {
                r = reader.read(&mut buf) => {
                    let n = match r { Ok(0) | Err(_) => break, Ok(n) => n };
                    let Some(ep) = endpoint.upgrade() else { return };
                    decoder.push(&buf[..n]);
                    while decoder.next_frame_raw(|f, raw| ep.deliver(f, raw, None)).is_some() {}
                }
                _ = &mut closed => return,
            }
        }
        // Frames from now on wait for the next connection, not go to this dead one.
        if sinks.send(None).is_err() {
            return;
        }
        tracing::info!("{connector:?}: stream closed, reopening");
    }
}
