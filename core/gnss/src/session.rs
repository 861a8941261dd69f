//! One connection to a GNSS source: open it (for gpsd, ask for JSON reports), then read
//! lines and hand each report to the shared state until the source fails, closes, or
//! sends no report for [`STALL_TIMEOUT`]. Reopening is the reader's business
//! ([`crate::reader`]).

use crate::fix::GnssReport;
use crate::gpsd;
use crate::lines::{Line, LineSplitter};
use crate::nmea0183::NmeaDecoder;
use crate::reader::{STALL_TIMEOUT, Shared};
use crate::source::GnssSource;
use std::time::{Duration, Instant};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

/// Longest wait for a TCP connection.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(5);

/// How a connection ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Ended {
    /// It could not be opened, broke or closed (why).
    Failed(String),
    /// No report for [`STALL_TIMEOUT`].
    Stalled,
}

/// What the lines are.
enum Decoder {
    Gpsd,
    Nmea(NmeaDecoder),
}

impl Decoder {
    fn decode(&mut self, line: &[u8]) -> Result<Option<GnssReport>, String> {
        match self {
            Decoder::Gpsd => match gpsd::decode(line) {
                Ok(gpsd::Decoded::Report(r)) => Ok(Some(r)),
                Ok(gpsd::Decoded::Ignored) => Ok(None),
                Err(e) => Err(e.0),
            },
            Decoder::Nmea(d) => match d.decode(line) {
                Ok(crate::nmea0183::Decoded::Report(r)) => Ok(Some(r)),
                Ok(crate::nmea0183::Decoded::Ignored) => Ok(None),
                Err(e) => Err(e.0),
            },
        }
    }
}

/// Runs one connection to `source` until it ends; reports go to `shared`.
pub(crate) async fn run(source: &GnssSource, shared: &Shared) -> Ended {
    let input = match tokio::time::timeout(CONNECT_TIMEOUT, open(source)).await {
        Ok(Ok(input)) => input,
        Ok(Err(e)) => return Ended::Failed(e),
        Err(_) => return Ended::Failed("no answer".into()),
    };
    shared.connected();
    let decoder = match source {
        GnssSource::Gpsd { .. } => Decoder::Gpsd,
        GnssSource::Serial { .. } | GnssSource::Tcp { .. } => Decoder::Nmea(NmeaDecoder::default()),
    };
    read(input, decoder, source, shared).await
}

async fn open(source: &GnssSource) -> Result<Box<dyn AsyncRead + Send + Unpin>, String> {
    match source {
        GnssSource::Gpsd { host, port } => {
            let mut s = connect(host, *port).await?;
            s.write_all(gpsd::WATCH.as_bytes())
                .await
                .map_err(|e| format!("asking gpsd for reports: {e}"))?;
            Ok(Box::new(s))
        }
        GnssSource::Tcp { host, port } => Ok(Box::new(connect(host, *port).await?)),
        GnssSource::Serial { device, baud } => {
            let port = tokio_serial::SerialStream::open(&tokio_serial::new(device, *baud))
                .map_err(|e| e.to_string())?;
            Ok(Box::new(port))
        }
    }
}

async fn connect(host: &str, port: u16) -> Result<TcpStream, String> {
    TcpStream::connect((host, port))
        .await
        .map_err(|e| e.to_string())
}

/// Reads until the connection ends (see the module docs).
async fn read(
    mut input: Box<dyn AsyncRead + Send + Unpin>,
    mut decoder: Decoder,
    source: &GnssSource,
    shared: &Shared,
) -> Ended {
    let mut lines = LineSplitter::default();
    let mut buf = vec![0u8; 4096];
    let mut last_report = Instant::now();
    loop {
        let stall_at = tokio::time::Instant::from_std(last_report + STALL_TIMEOUT);
        let got = match tokio::time::timeout_at(stall_at, input.read(&mut buf)).await {
            Err(_) => return Ended::Stalled,
            Ok(Ok(0)) => return Ended::Failed("the source closed the connection".into()),
            Ok(Ok(n)) => n,
            Ok(Err(e)) => return Ended::Failed(e.to_string()),
        };
        lines.push(&buf[..got], |line| {
            let decoded = match line {
                Line::Text(text) => decoder.decode(text),
                Line::TooLong => Err(format!("a line over {} bytes", crate::lines::MAX_LINE)),
            };
            match decoded {
                Ok(Some(report)) => {
                    last_report = Instant::now();
                    shared.report(report, last_report);
                }
                Ok(None) => {}
                Err(why) => dropped(source, shared, &why),
            }
        });
    }
}

/// Counts a malformed line; the first of the reader's life is a warning, the rest
/// debug records (a receiver that speaks another protocol would fill the log).
fn dropped(source: &GnssSource, shared: &Shared, why: &str) {
    if shared.malformed() == 1 {
        tracing::warn!("operator GNSS {source}: dropped a malformed line ({why})");
    } else {
        tracing::debug!("operator GNSS {source}: dropped a malformed line ({why})");
    }
}
