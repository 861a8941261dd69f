//! Where corrections come from, as the operator writes it (`[rtk] source`, `PUT
//! /api/v1/rtk`): an NTRIP caster, a TCP or UDP stream of RTCM3, or a base station
//! receiver on a serial port.
//!
//! - `ntrip://[USER[:PASSWORD]@]HOST[:PORT]/MOUNTPOINT[?version=1]`: an NTRIP caster
//!   (port 2101 by default). skein asks in NTRIP 2.0 (HTTP/1.1) and understands a
//!   caster's 1.0 (`ICY 200 OK`) or 2.0 (chunked) answer; `?version=1` asks in NTRIP 1.0
//!   for casters that refuse 2.0 requests. User and password may be percent-encoded.
//! - `tcp://HOST:PORT`: a raw RTCM3 stream from a TCP server (a base station's or
//!   `str2str`'s `tcpsvr://`).
//! - `udp://[ADDRESS]:PORT`: RTCM3 datagrams arriving on a local UDP port.
//! - `serial:DEVICE:BAUD`: a base station receiver streaming RTCM3 on a serial port.

use std::fmt;
use std::net::SocketAddr;
use std::str::FromStr;

/// The NTRIP caster's default port (IANA `ntrip`).
pub const NTRIP_PORT: u16 = 2101;

/// The NTRIP version skein asks in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NtripVersion {
    /// NTRIP 1.0: an HTTP/1.0-like request, answered `ICY 200 OK` and raw bytes.
    V1,
    /// NTRIP 2.0: HTTP/1.1 with `Ntrip-Version: Ntrip/2.0`, answered chunked.
    V2,
}

/// An NTRIP caster's mountpoint and credentials.
#[derive(Clone, PartialEq, Eq)]
pub struct NtripSource {
    /// Caster host name or address.
    pub host: String,
    /// Caster TCP port.
    pub port: u16,
    /// The mountpoint (the stream's name in the caster's source table).
    pub mountpoint: String,
    /// User name (HTTP Basic authentication), if any.
    pub user: Option<String>,
    /// Password, if any; never shown ([`Source::redacted`]).
    pub password: Option<String>,
    /// The version skein asks in.
    pub version: NtripVersion,
}

impl fmt::Debug for NtripSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("NtripSource")
            .field("host", &self.host)
            .field("port", &self.port)
            .field("mountpoint", &self.mountpoint)
            .field("user", &self.user)
            .field("password", &self.password.as_ref().map(|_| "***"))
            .field("version", &self.version)
            .finish()
    }
}

/// A corrections source (see the module docs for the forms).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Source {
    /// An NTRIP caster's mountpoint.
    Ntrip(NtripSource),
    /// A TCP server streaming RTCM3 (host, port).
    Tcp {
        /// Host name or address.
        host: String,
        /// TCP port.
        port: u16,
    },
    /// RTCM3 datagrams to this local address.
    Udp(SocketAddr),
    /// A serial device at a baud rate.
    Serial {
        /// Device path, e.g. `/dev/ttyUSB0`.
        device: String,
        /// Baud rate.
        baud: u32,
    },
}

pub use skein_model::endpoint::SourceError;
use skein_model::endpoint::{bracket, host_port, serial_device_baud};

const FORMS: &str = "ntrip://[USER[:PASSWORD]@]HOST[:PORT]/MOUNTPOINT, tcp://HOST:PORT, \
                     udp://[ADDRESS]:PORT or serial:DEVICE:BAUD";

impl FromStr for Source {
    type Err = SourceError;

    fn from_str(s: &str) -> Result<Self, SourceError> {
        let err = |what: &str| SourceError(format!("`{}`: {what}", redact_text(s)));
        if let Some(rest) = s.strip_prefix("ntrip://") {
            return parse_ntrip(rest).map(Source::Ntrip).map_err(|e| err(&e));
        }
        if let Some(rest) = s.strip_prefix("tcp://") {
            let (host, port) = host_port(rest, None).map_err(|e| err(&e))?;
            return Ok(Source::Tcp { host, port });
        }
        if let Some(rest) = s.strip_prefix("udp://") {
            let (host, port) = host_port(rest, None).map_err(|e| err(&e))?;
            let host = if host.is_empty() { "0.0.0.0" } else { &host };
            let ip = host
                .parse()
                .map_err(|_| err(&format!("`{host}` is not a local IP address")))?;
            return Ok(Source::Udp(SocketAddr::new(ip, port)));
        }
        if let Some(rest) = s.strip_prefix("serial:") {
            let (device, baud) = serial_device_baud(rest).map_err(|e| err(&e))?;
            return Ok(Source::Serial { device, baud });
        }
        Err(err(&format!("expected {FORMS}")))
    }
}

fn parse_ntrip(rest: &str) -> Result<NtripSource, String> {
    let (authority, path) = rest
        .split_once('/')
        .ok_or("no mountpoint (ntrip://HOST:PORT/MOUNTPOINT)")?;
    let (path, query) = match path.split_once('?') {
        Some((p, q)) => (p, Some(q)),
        None => (path, None),
    };
    let version = match query {
        None | Some("") | Some("version=2") => NtripVersion::V2,
        Some("version=1") => NtripVersion::V1,
        Some(q) => return Err(format!("unknown option `{q}` (version=1 or version=2)")),
    };
    if path.is_empty() || path.contains('/') {
        return Err(format!("`{path}` is not a mountpoint name"));
    }
    let (credentials, hostport) = match authority.rsplit_once('@') {
        Some((c, h)) => (Some(c), h),
        None => (None, authority),
    };
    let (user, password) = match credentials {
        None => (None, None),
        Some(c) => match c.split_once(':') {
            Some((u, p)) => (Some(percent_decode(u)?), Some(percent_decode(p)?)),
            None => (Some(percent_decode(c)?), None),
        },
    };
    let (host, port) = host_port(hostport, Some(NTRIP_PORT))?;
    if host.is_empty() {
        return Err("no caster host".into());
    }
    Ok(NtripSource {
        host,
        port,
        mountpoint: percent_decode(path)?,
        user,
        password,
        version,
    })
}

fn percent_decode(s: &str) -> Result<String, String> {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = s
                .get(i + 1..i + 3)
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or("a `%` not followed by two hex digits")?;
            out.push(hex);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).map_err(|_| "percent-encoding that is not UTF-8".into())
}

/// `text` with the password of an `ntrip://user:password@` replaced by `***`.
fn redact_text(text: &str) -> String {
    let Some(rest) = text.strip_prefix("ntrip://") else {
        return text.to_string();
    };
    let authority = rest.split('/').next().unwrap_or(rest);
    match authority.rsplit_once('@') {
        Some((cred, _)) => match cred.split_once(':') {
            Some((user, _)) => format!("ntrip://{user}:***@{}", &rest[cred.len() + 1..]),
            None => text.to_string(),
        },
        None => text.to_string(),
    }
}

impl Source {
    /// The source as the operator wrote it, the password shown as `***` (what the API
    /// and the logs show).
    pub fn redacted(&self) -> String {
        match self {
            Source::Ntrip(n) => {
                let cred = match (&n.user, &n.password) {
                    (Some(u), Some(_)) => format!("{u}:***@"),
                    (Some(u), None) => format!("{u}@"),
                    _ => String::new(),
                };
                let v1 = if n.version == NtripVersion::V1 {
                    "?version=1"
                } else {
                    ""
                };
                format!(
                    "ntrip://{cred}{}:{}/{}{v1}",
                    bracket(&n.host),
                    n.port,
                    n.mountpoint
                )
            }
            Source::Tcp { host, port } => format!("tcp://{}:{port}", bracket(host)),
            Source::Udp(a) => format!("udp://{a}"),
            Source::Serial { device, baud } => format!("serial:{device}:{baud}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ntrip(s: &str) -> NtripSource {
        match s.parse::<Source>() {
            Ok(Source::Ntrip(n)) => n,
            other => panic!("{s}: {other:?}"),
        }
    }

    #[test]
    fn an_ntrip_url_gives_caster_mountpoint_and_credentials() {
        let n = ntrip("ntrip://crew:s%40cret@caster.example:2102/BASE01");
        assert_eq!(n.host, "caster.example");
        assert_eq!(n.port, 2102);
        assert_eq!(n.mountpoint, "BASE01");
        assert_eq!(n.user.as_deref(), Some("crew"));
        assert_eq!(n.password.as_deref(), Some("s@cret"));
        assert_eq!(n.version, NtripVersion::V2);
        let d = ntrip("ntrip://127.0.0.1/MNT?version=1");
        assert_eq!((d.port, d.user, d.version), (2101, None, NtripVersion::V1));
        assert_eq!(ntrip("ntrip://[::1]:2000/M").host, "::1");
    }

    #[test]
    fn the_password_is_never_shown() {
        let s: Source = "ntrip://crew:hunter2@h:2101/M".parse().unwrap();
        assert_eq!(s.redacted(), "ntrip://crew:***@h:2101/M");
        assert!(!format!("{s:?}").contains("hunter2"));
        let e = "ntrip://crew:hunter2@h:99999/M"
            .parse::<Source>()
            .unwrap_err();
        assert!(!e.0.contains("hunter2"), "{e}");
        assert!(e.0.contains("port `99999`"), "{e}");
    }

    #[test]
    fn stream_sources_parse() {
        assert_eq!(
            "tcp://base.local:5000".parse::<Source>().unwrap(),
            Source::Tcp {
                host: "base.local".into(),
                port: 5000
            }
        );
        assert_eq!(
            "udp://:9000".parse::<Source>().unwrap(),
            Source::Udp("0.0.0.0:9000".parse().unwrap())
        );
        assert_eq!(
            "serial:/dev/ttyUSB0:115200".parse::<Source>().unwrap(),
            Source::Serial {
                device: "/dev/ttyUSB0".into(),
                baud: 115_200
            }
        );
    }

    #[test]
    fn bad_sources_say_what_is_wrong() {
        for (s, says) in [
            ("http://x/M", "expected ntrip://"),
            ("ntrip://host:2101", "no mountpoint"),
            ("ntrip://host:2101/", "not a mountpoint"),
            ("ntrip://host/M?v=3", "unknown option"),
            ("tcp://host", "no port"),
            ("udp://example.com:9", "not a local IP"),
            ("serial:/dev/ttyUSB0:fast", "baud `fast`"),
            ("ntrip://u:%zz@h/M", "hex digits"),
        ] {
            let e = s.parse::<Source>().unwrap_err();
            assert!(e.0.contains(says), "{s}: {e}");
        }
    }
}
