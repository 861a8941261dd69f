//! An RTSP camera (RFC 2326; the gimbal cameras such UAVs carry stream it over Ethernet)
//! as a source of decoded frames: a thread of its own runs the session with `retina` on a
//! single-threaded tokio runtime, decodes each H.264 access unit ([`crate::h264`]) and
//! keeps the newest frame for the camera to take. A stream that ends, stalls (no frame
//! decoded within the stall timeout) or cannot be opened is reported in
//! [`StreamStatus`] and opened again with backoff (0.5 s doubling to 5 s); the camera
//! and the vehicle never wait on it.

use crate::clock::CaptureClock;
use crate::h264::{DecodeError, H264Decoder};
use crate::recent::Recent;
use crate::scale::RgbFrame;
use crate::status::{Dropped, SourceState, StreamStatus};
use futures_util::StreamExt;
use retina::client::{Credentials, PlayOptions, Session, SessionOptions, SetupOptions, Transport};
use retina::codec::{CodecItem, FrameFormat};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};
use tokio::sync::Notify;
pub use url::Url;

/// First wait before opening a failed stream again; doubled after each failure.
pub const MIN_BACKOFF: Duration = Duration::from_millis(500);
/// Longest wait between attempts to open a stream.
pub const MAX_BACKOFF: Duration = Duration::from_secs(5);
/// How long `DESCRIBE`, `SETUP` and `PLAY` may each take before the attempt fails.
pub const REQUEST_TIMEOUT: Duration = Duration::from_secs(5);
/// The window over which `stream_rate_hz` is measured.
const RATE_WINDOW: Duration = Duration::from_secs(3);

/// RTP transport (RFC 2326 §12.39).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RtpTransport {
    /// Interleaved on the RTSP TCP connection: through NAT and firewalls, no loss.
    Tcp,
    /// RTP over UDP: lower latency on a clean LAN, loses what the network loses.
    Udp,
}

impl RtpTransport {
    /// `"tcp"` or `"udp"`.
    pub fn name(self) -> &'static str {
        match self {
            RtpTransport::Tcp => "tcp",
            RtpTransport::Udp => "udp",
        }
    }
}

/// What the source opens.
#[derive(Debug, Clone, PartialEq)]
pub struct RtspConfig {
    /// `rtsp://[user:password@]host[:port]/path`.
    pub url: Url,
    /// RTP transport.
    pub transport: RtpTransport,
    /// No frame decoded for this long: stalled, the session is closed and opened again.
    pub stall_timeout: Duration,
    /// Time from capture to the camera's output, ms, subtracted from capture stamps
    /// ([`CaptureClock`]).
    pub latency_ms: f64,
}

impl RtspConfig {
    /// Parses `url` (scheme `rtsp`).
    ///
    /// # Errors
    /// Not a URL, another scheme, or no host, with the reason.
    pub fn parse_url(url: &str) -> Result<Url, String> {
        let u = Url::parse(url).map_err(|e| format!("not an RTSP URL ({e}): {url}"))?;
        if u.scheme() != "rtsp" {
            return Err(format!("not an RTSP URL (scheme {}): {url}", u.scheme()));
        }
        if u.host_str().is_none_or(str::is_empty) {
            return Err(format!("an RTSP URL needs a host: {url}"));
        }
        Ok(u)
    }
}

/// The URL as shown in the state and the logs: without its password.
fn shown(url: &Url) -> String {
    let mut u = url.clone();
    if u.password().is_some() {
        let _ = u.set_password(Some("***"));
    }
    u.to_string()
}

/// `text` with the URL's password, wherever a library's message quotes it, as `***`.
fn scrub(text: String, url: &Url) -> String {
    match url.password() {
        Some(p) if !p.is_empty() => text.replace(p, "***"),
        _ => text,
    }
}

/// A decoded frame and when the camera captured it.
#[derive(Debug, Clone, PartialEq)]
pub struct DecodedFrame {
    /// The pixels, at the stream's size.
    pub frame: RgbFrame,
    /// Capture time, wall-clock µs since the Unix epoch ([`CaptureClock`]).
    pub capture_us: u64,
}

struct Health {
    status: StreamStatus,
    /// The frames decoded in the last [`RATE_WINDOW`].
    recent: Recent<()>,
}

struct Shared {
    latest: Mutex<Option<DecodedFrame>>,
    health: Mutex<Health>,
    stop: AtomicBool,
    wake: Notify,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panic elsewhere while holding the lock leaves the data as it was: still usable.
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

impl Shared {
    fn health<R>(&self, f: impl FnOnce(&mut Health) -> R) -> R {
        f(&mut lock(&self.health))
    }

    fn publish(&self, frame: RgbFrame, capture_us: u64) {
        let (w, h) = (frame.width_px, frame.height_px);
        let superseded = lock(&self.latest)
            .replace(DecodedFrame { frame, capture_us })
            .is_some();
        let now = Instant::now();
        self.health(|h_| {
            let s = &mut h_.status;
            s.frames_decoded += 1;
            s.dropped.superseded += u64::from(superseded);
            s.stream_width_px = Some(w);
            s.stream_height_px = Some(h);
            s.state = SourceState::Streaming;
            s.detail = None;
            h_.recent.push(now, ());
        });
    }

    /// The session ended or could not start: stalled once it has streamed, else failed.
    fn lost(&self, why: String) {
        self.health(|h| {
            h.status.state = if h.status.frames_decoded > 0 {
                SourceState::Stalled
            } else {
                SourceState::Failed
            };
            h.status.detail = Some(why);
        });
    }

    fn count(&self, f: impl FnOnce(&mut Dropped)) {
        self.health(|h| f(&mut h.status.dropped));
    }
}

/// A running RTSP source. Dropping it stops its thread and waits for it (a plugin's
/// library must not be unloaded under a thread still running its code).
pub struct RtspSource {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

impl RtspSource {
    /// Starts the source's thread; it connects at once and keeps trying.
    ///
    /// # Errors
    /// The thread could not be started.
    pub fn start(config: RtspConfig) -> Result<Self, String> {
        let status = StreamStatus {
            state: SourceState::Connecting,
            url: shown(&config.url),
            transport: config.transport.name(),
            detail: None,
            frames_decoded: 0,
            dropped: Dropped::default(),
            sessions: 0,
            stream_width_px: None,
            stream_height_px: None,
            stream_rate_hz: None,
            last_frame_age_ms: None,
        };
        let shared = Arc::new(Shared {
            latest: Mutex::new(None),
            health: Mutex::new(Health {
                status,
                recent: Recent::new(RATE_WINDOW),
            }),
            stop: AtomicBool::new(false),
            wake: Notify::new(),
        });
        let s = shared.clone();
        let thread = std::thread::Builder::new()
            .name("skein-rtsp".into())
            .spawn(move || run(&s, &config))
            .map_err(|e| format!("cannot start the RTSP thread: {e}"))?;
        Ok(RtspSource {
            shared,
            thread: Some(thread),
        })
    }

    /// The newest decoded frame not taken yet, taken (a later call gives it no more;
    /// `None` until a newer one is decoded).
    pub fn take_latest(&self) -> Option<DecodedFrame> {
        lock(&self.shared.latest).take()
    }

    /// The source's health now.
    pub fn status(&self) -> StreamStatus {
        self.shared.health(|h| {
            let mut s = h.status.clone();
            s.last_frame_age_ms = h.recent.last_at().map(|t| t.elapsed().as_millis() as u64);
            s.stream_rate_hz = h.recent.rate_hz();
            s
        })
    }
}

impl Drop for RtspSource {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        self.shared.wake.notify_one();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The thread: sessions, one after the other, with backoff between failures.
fn run(shared: &Shared, config: &RtspConfig) {
    let rt = match tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
    {
        Ok(rt) => rt,
        Err(e) => return shared.lost(format!("no runtime for the RTSP session: {e}")),
    };
    rt.block_on(async {
        let mut backoff = MIN_BACKOFF;
        while !shared.stop.load(Ordering::SeqCst) {
            let before = shared.health(|h| {
                h.status.sessions += 1;
                if h.status.frames_decoded == 0 {
                    h.status.state = SourceState::Connecting;
                }
                h.status.frames_decoded
            });
            let outcome = tokio::select! {
                r = session(shared, config) => r,
                () = shared.wake.notified() => return,
            };
            if shared.stop.load(Ordering::SeqCst) {
                return;
            }
            let streamed = shared.health(|h| h.status.frames_decoded > before);
            if streamed {
                backoff = MIN_BACKOFF;
            }
            let why = scrub(
                outcome.err().unwrap_or_else(|| "the stream ended".into()),
                &config.url,
            );
            shared.lost(format!(
                "{why}; opening it again in {:.1} s",
                backoff.as_secs_f64()
            ));
            tokio::select! {
                () = tokio::time::sleep(backoff) => {}
                () = shared.wake.notified() => return,
            }
            backoff = (backoff * 2).min(MAX_BACKOFF);
        }
    });
}

async fn within<T, E: std::fmt::Display>(
    what: &str,
    f: impl Future<Output = Result<T, E>>,
) -> Result<T, String> {
    match tokio::time::timeout(REQUEST_TIMEOUT, f).await {
        Ok(r) => r.map_err(|e| format!("{what}: {e}")),
        Err(_) => Err(format!(
            "{what}: no answer within {} s",
            REQUEST_TIMEOUT.as_secs()
        )),
    }
}

/// One session: open, play, decode until the stream ends, fails or stalls.
async fn session(shared: &Shared, config: &RtspConfig) -> Result<(), String> {
    let creds = (!config.url.username().is_empty()).then(|| Credentials {
        username: config.url.username().to_string(),
        password: config.url.password().unwrap_or("").to_string(),
    });
    let options = SessionOptions::default()
        .creds(creds)
        .user_agent("skein".into());
    let mut described = within("DESCRIBE", Session::describe(config.url.clone(), options)).await?;
    let video = described
        .streams()
        .iter()
        .position(|s| s.media() == "video" && s.encoding_name().eq_ignore_ascii_case("h264"));
    let Some(video) = video else {
        let offered: Vec<String> = described
            .streams()
            .iter()
            .map(|s| format!("{} {}", s.media(), s.encoding_name()))
            .collect();
        return Err(format!(
            "no H.264 video in the stream (it offers: {}); this build decodes H.264 only",
            offered.join(", ")
        ));
    };
    let transport = match config.transport {
        RtpTransport::Tcp => Transport::Tcp(Default::default()),
        RtpTransport::Udp => Transport::Udp(Default::default()),
    };
    let setup = SetupOptions::default()
        .transport(transport)
        .frame_format(FrameFormat::SIMPLE);
    within("SETUP", described.setup(video, setup)).await?;
    let playing = within("PLAY", described.play(PlayOptions::default())).await?;
    let mut frames = playing
        .demuxed()
        .map_err(|e| format!("cannot depacketize the stream: {e}"))?;
    let mut decoder = H264Decoder::new()?;
    let mut clock = CaptureClock::new(config.latency_ms);
    let mut last_decoded = Instant::now();
    let mut pictures = 0u64;
    loop {
        let deadline = last_decoded + config.stall_timeout;
        let item = tokio::time::timeout_at(deadline.into(), frames.next()).await;
        let frame = match item {
            Err(_) => {
                return Err(format!(
                    "no frame decoded for {:.1} s",
                    config.stall_timeout.as_secs_f64()
                ));
            }
            Ok(None) => return Err("the server ended the stream".into()),
            Ok(Some(Err(e))) => {
                shared.count(|d| d.depacketize_error += 1);
                return Err(format!("the stream broke: {e}"));
            }
            Ok(Some(Ok(CodecItem::VideoFrame(f)))) => f,
            Ok(Some(Ok(_))) => continue,
        };
        if frame.loss() > 0 {
            shared.count(|d| d.lost_packets += u64::from(frame.loss()));
        }
        let arrival_us = SystemTime::from(frame.end_ctx().received_wall())
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_micros() as u64);
        let media_s = frame.timestamp().elapsed_secs();
        match decoder.decode(frame.data()) {
            Ok(Some(rgb)) => {
                last_decoded = Instant::now();
                pictures += 1;
                shared.publish(rgb, clock.capture_us(media_s, arrival_us));
            }
            Ok(None) => {}
            Err(DecodeError::Malformed(_)) => shared.count(|d| d.malformed += 1),
            // Joined mid-GOP: frames referring to pictures sent before the session began.
            Err(DecodeError::Corrupt(_)) if pictures == 0 => {
                shared.count(|d| d.before_key_frame += 1);
            }
            Err(DecodeError::Corrupt(_)) => shared.count(|d| d.decode_error += 1),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls_are_checked_and_passwords_never_shown() {
        assert!(
            RtspConfig::parse_url("http://cam/main")
                .unwrap_err()
                .contains("scheme http")
        );
        assert!(RtspConfig::parse_url("rtsp:///main").is_err());
        assert!(RtspConfig::parse_url("not a url").is_err());
        let u = RtspConfig::parse_url("rtsp://admin:s3cret@10.0.0.5:554/main").unwrap();
        assert_eq!(shown(&u), "rtsp://admin:***@10.0.0.5:554/main");
        let why = "401 Unauthorized for rtsp://admin:s3cret@10.0.0.5:554/main".to_string();
        assert!(!scrub(why, &u).contains("s3cret"));
    }

    #[test]
    fn a_source_that_cannot_connect_fails_with_the_reason_and_stops_when_dropped() {
        // A port nobody listens on: refused at once, retried with backoff.
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let source = RtspSource::start(RtspConfig {
            url: RtspConfig::parse_url(&format!("rtsp://127.0.0.1:{port}/main")).unwrap(),
            transport: RtpTransport::Tcp,
            stall_timeout: Duration::from_secs(1),
            latency_ms: 0.0,
        })
        .unwrap();
        let deadline = Instant::now() + Duration::from_secs(20);
        let status = loop {
            let s = source.status();
            if s.state == SourceState::Failed || Instant::now() > deadline {
                break s;
            }
            std::thread::sleep(Duration::from_millis(10));
        };
        assert_eq!(status.state, SourceState::Failed, "{status:?}");
        let detail = status.detail.unwrap();
        assert!(
            detail.contains("DESCRIBE") && detail.contains("again in"),
            "{detail}"
        );
        assert!(source.take_latest().is_none());
        let dropped = Instant::now();
        drop(source);
        assert!(
            dropped.elapsed() < Duration::from_secs(2),
            "the thread stops at once"
        );
    }
}
