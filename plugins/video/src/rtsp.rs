//! An RTSP camera (RFC 2326; the gimbal cameras such UAVs carry stream it over Ethernet)
//! as a source of decoded frames: a thread of its own runs the session with `retina` on a
//! single-threaded tokio runtime, decodes each H.264 access unit ([`crate::h264`]) and
//! keeps the newest frame for the camera to take. A stream that ends, stalls (no frame
//! decoded within the stall timeout) or cannot be opened is reported in
//! the source's status and opened again with backoff ([`crate::input`]); the camera
//! and the vehicle never wait on it.

use crate::clock::CaptureClock;
use crate::h264::{DecodeError, H264Decoder};
use crate::input::{Shared, VideoInput, runtime};
use futures_util::StreamExt;
use retina::client::{Credentials, PlayOptions, Session, SessionOptions, SetupOptions, Transport};
use retina::codec::{CodecItem, FrameFormat};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};
pub use url::Url;

/// How long `DESCRIBE`, `SETUP` and `PLAY` may each take before the attempt fails.
pub const REQUEST_TIMEOUT: Duration = Duration::from_secs(5);

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

/// Starts receiving `config`'s stream on a thread of its own; it connects at once and
/// keeps trying.
///
/// # Errors
/// The thread could not be started.
pub fn start(config: RtspConfig) -> Result<VideoInput, String> {
    let url = shown(&config.url);
    VideoInput::spawn("skein-rtsp", url, config.transport.name(), move |shared| {
        if let Some(rt) = runtime(shared, "RTSP session") {
            rt.block_on(
                shared.sessions(|| session(shared, &config), |why| scrub(why, &config.url)),
            );
        }
    })
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
    use crate::status::SourceState;

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
        let source = start(RtspConfig {
            url: RtspConfig::parse_url(&format!("rtsp://127.0.0.1:{port}/main")).unwrap(),
            transport: RtpTransport::Tcp,
            stall_timeout: Duration::from_secs(1),
            latency_ms: 0.0,
        })
        .unwrap();
        let status = source.status_when(SourceState::Failed, Duration::from_secs(20));
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
