//! One connection to a corrections source: open it (for NTRIP, ask for the mountpoint and
//! read the caster's answer), then read RTCM3 frames and hand each to the hub until the
//! source fails, closes, or sends no frame for the stall timeout. Reconnecting is the
//! service's business ([`crate::service`]).

use crate::config::{GGA_PERIOD, RtkSettings};
use crate::framer::RtcmFramer;
use crate::hub::Hub;
use crate::ntrip::{self, Answer, Dechunker, Framing};
use crate::source::{NtripSource, Source};
use std::io;
use std::time::{Duration, Instant, SystemTime};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::{TcpStream, UdpSocket};

/// Longest wait for a TCP connection.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(10);

/// How a connection ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Ended {
    /// It could not be opened, was refused, broke or closed (why).
    Failed(String),
    /// No frame for the stall timeout (how long).
    Stalled(String),
}

/// An open source: bytes in, and for NTRIP the way back to the caster (GGA).
struct Connection {
    input: Input,
    to_caster: Option<Box<dyn AsyncWrite + Send + Unpin>>,
    /// Bytes of the body that arrived with the caster's answer.
    first: Vec<u8>,
    dechunker: Option<Dechunker>,
}

enum Input {
    Stream(Box<dyn AsyncRead + Send + Unpin>),
    Datagrams(UdpSocket),
}

impl Input {
    async fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        match self {
            Input::Stream(r) => r.read(buf).await,
            Input::Datagrams(s) => s.recv(buf).await,
        }
    }
}

/// Runs one connection to `settings.source` until it ends; frames go to `hub`.
pub(crate) async fn run(settings: &RtkSettings, hub: &Hub, framer: &mut RtcmFramer) -> Ended {
    let opened = tokio::time::timeout(settings.stall_timeout.max(CONNECT_TIMEOUT), open(settings))
        .await
        .unwrap_or_else(|_| Err("no answer from the source".into()));
    match opened {
        Ok(c) => read(c, settings, hub, framer).await,
        Err(e) => Ended::Failed(e),
    }
}

async fn open(settings: &RtkSettings) -> Result<Connection, String> {
    match &settings.source {
        Source::Ntrip(n) => open_ntrip(n).await,
        Source::Tcp { host, port } => {
            let s = connect(host, *port).await?;
            Ok(stream(Box::new(s)))
        }
        Source::Udp(addr) => {
            let s = UdpSocket::bind(addr)
                .await
                .map_err(|e| format!("udp {addr}: {e}"))?;
            Ok(Connection {
                input: Input::Datagrams(s),
                to_caster: None,
                first: Vec::new(),
                dechunker: None,
            })
        }
        Source::Serial { device, baud } => {
            let port = tokio_serial::SerialStream::open(&tokio_serial::new(device, *baud))
                .map_err(|e| format!("serial:{device}:{baud}: {e}"))?;
            Ok(stream(Box::new(port)))
        }
    }
}

fn stream(r: Box<dyn AsyncRead + Send + Unpin>) -> Connection {
    Connection {
        input: Input::Stream(r),
        to_caster: None,
        first: Vec::new(),
        dechunker: None,
    }
}

async fn connect(host: &str, port: u16) -> Result<TcpStream, String> {
    let s = TcpStream::connect((host, port))
        .await
        .map_err(|e| format!("{host}:{port}: {e}"))?;
    let _ = s.set_nodelay(true);
    Ok(s)
}

/// Connects to the caster, asks for the mountpoint and reads the answer.
async fn open_ntrip(n: &NtripSource) -> Result<Connection, String> {
    let s = connect(&n.host, n.port).await?;
    let (mut rx, mut tx) = s.into_split();
    tx.write_all(ntrip::request(n).as_bytes())
        .await
        .map_err(|e| format!("{}:{}: {e}", n.host, n.port))?;
    let mut head = Vec::new();
    let mut buf = [0u8; 4096];
    loop {
        let got = rx.read(&mut buf).await.map_err(|e| e.to_string())?;
        if got == 0 {
            return Err(closed_during_answer(&head, &n.mountpoint));
        }
        head.extend_from_slice(&buf[..got]);
        if let Answer::Streaming {
            framing,
            body_start,
        } = ntrip::answer(&head, &n.mountpoint)?
        {
            return Ok(Connection {
                input: Input::Stream(Box::new(rx)),
                to_caster: Some(Box::new(tx)),
                first: head.split_off(body_start),
                dechunker: (framing == Framing::Chunked).then(Dechunker::default),
            });
        }
    }
}

/// Why a caster closed before a whole answer: its source table (a caster closes after
/// sending one), or nothing at all (RTKLIB's caster closes on a request it refuses).
fn closed_during_answer(head: &[u8], mountpoint: &str) -> String {
    if head.starts_with(b"SOURCETABLE") || head.windows(3).any(|w| w == b"STR") {
        ntrip::unknown_mountpoint(head, mountpoint)
    } else if head.is_empty() {
        format!("the caster closed the connection without an answer (is /{mountpoint} right?)")
    } else {
        format!(
            "the caster closed the connection during its answer ({} bytes)",
            head.len()
        )
    }
}

/// Reads until the connection ends (see the module docs).
async fn read(mut c: Connection, s: &RtkSettings, hub: &Hub, framer: &mut RtcmFramer) -> Ended {
    let mut last_frame = Instant::now();
    let mut next_gga = Instant::now();
    let mut buf = vec![0u8; 8192];
    let mut body = Vec::new();
    let first = std::mem::take(&mut c.first);
    if let Err(e) = take(&mut c, &first, &mut body, hub, framer, &mut last_frame) {
        return Ended::Failed(e);
    }
    loop {
        if s.send_gga && c.to_caster.is_some() && Instant::now() >= next_gga {
            next_gga = Instant::now() + GGA_PERIOD;
            if let Err(e) = send_gga(&mut c, hub).await {
                return Ended::Failed(format!("telling the caster where the fleet is: {e}"));
            }
        }
        let stall_at = last_frame + s.stall_timeout;
        let wake = if c.to_caster.is_some() && s.send_gga {
            stall_at.min(next_gga)
        } else {
            stall_at
        };
        let got = match tokio::time::timeout_at(
            tokio::time::Instant::from_std(wake),
            c.input.read(&mut buf),
        )
        .await
        {
            Err(_) if Instant::now() >= stall_at => {
                return Ended::Stalled(format!(
                    "no RTCM frame for {:.0} s",
                    s.stall_timeout.as_secs_f64()
                ));
            }
            Err(_) => continue,
            Ok(Ok(0)) => return Ended::Failed("the source closed the connection".into()),
            Ok(Ok(n)) => n,
            Ok(Err(e)) => return Ended::Failed(e.to_string()),
        };
        if let Err(e) = take(&mut c, &buf[..got], &mut body, hub, framer, &mut last_frame) {
            return Ended::Failed(e);
        }
    }
}

/// Frames the bytes `got` (dechunked first for NTRIP 2.0) and delivers the frames.
fn take(
    c: &mut Connection,
    got: &[u8],
    body: &mut Vec<u8>,
    hub: &Hub,
    framer: &mut RtcmFramer,
    last_frame: &mut Instant,
) -> Result<(), String> {
    if got.is_empty() {
        return Ok(());
    }
    let data = match &mut c.dechunker {
        Some(d) => {
            body.clear();
            d.feed(got, body)?;
            if d.is_done() {
                return Err("the caster ended the stream".into());
            }
            &body[..]
        }
        None => got,
    };
    let frames = framer.push(data);
    if !frames.is_empty() {
        *last_frame = Instant::now();
    }
    hub.received(got.len(), framer.counts());
    for f in &frames {
        hub.deliver(f);
    }
    Ok(())
}

async fn send_gga(c: &mut Connection, hub: &Hub) -> io::Result<()> {
    let (Some(to), Some(p)) = (c.to_caster.as_mut(), hub.fleet_position()) else {
        return Ok(());
    };
    to.write_all(ntrip::gga(&p, SystemTime::now()).as_bytes())
        .await?;
    hub.told_position(p);
    Ok(())
}
