//! Where the ground station's GNSS position comes from, as the operator writes it
//! (`[remote_id] operator_gnss`):
//!
//! - `gpsd://HOST[:PORT]`: a gpsd daemon (port 2947 by default), asked for JSON reports
//!   (`?WATCH={"enable":true,"json":true}`); its `TPV` reports are read.
//! - `serial:DEVICE:BAUD`: a receiver streaming NMEA 0183 on a serial port
//!   (`serial:/dev/ttyACM0:9600`).
//! - `tcp://HOST:PORT`: NMEA 0183 from a TCP server (a receiver's or a phone's NMEA
//!   stream, gpsd's `gpspipe -r` behind a socket).

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// gpsd's port (IANA `gpsd`).
pub const GPSD_PORT: u16 = 2947;

/// A GNSS source (see the module docs for the forms).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum GnssSource {
    /// A gpsd daemon: JSON `TPV` reports.
    Gpsd {
        /// Host name or address.
        host: String,
        /// TCP port.
        port: u16,
    },
    /// NMEA 0183 on a serial port.
    Serial {
        /// Device path, e.g. `/dev/ttyACM0`.
        device: String,
        /// Baud rate.
        baud: u32,
    },
    /// NMEA 0183 from a TCP server.
    Tcp {
        /// Host name or address.
        host: String,
        /// TCP port.
        port: u16,
    },
}

pub use skein_model::endpoint::SourceError;
use skein_model::endpoint::{bracket, host_port, serial_device_baud};

const FORMS: &str = "gpsd://HOST[:PORT], serial:DEVICE:BAUD or tcp://HOST:PORT";

impl FromStr for GnssSource {
    type Err = SourceError;

    fn from_str(s: &str) -> Result<Self, SourceError> {
        let err = |what: &str| SourceError(format!("`{s}`: {what}"));
        if let Some(rest) = s.strip_prefix("gpsd://") {
            let (host, port) =
                host_named(rest.trim_end_matches('/'), Some(GPSD_PORT)).map_err(|e| err(&e))?;
            return Ok(GnssSource::Gpsd { host, port });
        }
        if let Some(rest) = s.strip_prefix("tcp://") {
            let (host, port) = host_named(rest, None).map_err(|e| err(&e))?;
            return Ok(GnssSource::Tcp { host, port });
        }
        if let Some(rest) = s.strip_prefix("serial:") {
            let (device, baud) = serial_device_baud(rest).map_err(|e| err(&e))?;
            return Ok(GnssSource::Serial { device, baud });
        }
        Err(err(&format!("expected {FORMS}")))
    }
}

/// [`host_port`] with a host required (gpsd and a TCP receiver are somewhere).
fn host_named(s: &str, default: Option<u16>) -> Result<(String, u16), String> {
    let (host, port) = host_port(s, default)?;
    if host.is_empty() {
        return Err("no host".into());
    }
    Ok((host, port))
}

impl fmt::Display for GnssSource {
    /// The source in its canonical form (the port always given).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GnssSource::Gpsd { host, port } => write!(f, "gpsd://{}:{port}", bracket(host)),
            GnssSource::Serial { device, baud } => write!(f, "serial:{device}:{baud}"),
            GnssSource::Tcp { host, port } => write!(f, "tcp://{}:{port}", bracket(host)),
        }
    }
}

impl TryFrom<String> for GnssSource {
    type Error = SourceError;

    fn try_from(s: String) -> Result<Self, SourceError> {
        s.parse()
    }
}

impl From<GnssSource> for String {
    fn from(s: GnssSource) -> String {
        s.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_three_forms_parse_and_print_back() {
        for (text, source, canonical) in [
            (
                "gpsd://127.0.0.1",
                GnssSource::Gpsd {
                    host: "127.0.0.1".into(),
                    port: 2947,
                },
                "gpsd://127.0.0.1:2947",
            ),
            (
                "gpsd://[::1]:3000/",
                GnssSource::Gpsd {
                    host: "::1".into(),
                    port: 3000,
                },
                "gpsd://[::1]:3000",
            ),
            (
                "serial:/dev/ttyACM0:9600",
                GnssSource::Serial {
                    device: "/dev/ttyACM0".into(),
                    baud: 9600,
                },
                "serial:/dev/ttyACM0:9600",
            ),
            (
                "tcp://phone.local:10110",
                GnssSource::Tcp {
                    host: "phone.local".into(),
                    port: 10110,
                },
                "tcp://phone.local:10110",
            ),
        ] {
            let parsed: GnssSource = text.parse().unwrap();
            assert_eq!(parsed, source, "{text}");
            assert_eq!(parsed.to_string(), canonical);
        }
    }

    #[test]
    fn bad_sources_say_what_is_wrong() {
        for (s, says) in [
            ("http://x", "expected gpsd://"),
            ("gpsd://", "no host"),
            ("gpsd://host:0", "port `0`"),
            ("tcp://host", "no port"),
            ("serial:/dev/ttyUSB0:fast", "baud `fast`"),
            ("serial::9600", "empty serial device"),
            ("serial:/dev/ttyUSB0", "serial:DEVICE:BAUD"),
        ] {
            let e = s.parse::<GnssSource>().unwrap_err();
            assert!(e.0.contains(says), "{s}: {e}");
        }
    }

    #[test]
    fn a_source_is_a_string_in_toml() {
        #[derive(Deserialize)]
        struct T {
            operator_gnss: GnssSource,
        }
        let t: T = serde_json::from_str(r#"{"operator_gnss": "gpsd://gnss.local"}"#).unwrap();
        assert_eq!(t.operator_gnss.to_string(), "gpsd://gnss.local:2947");
        let e = serde_json::from_str::<T>(r#"{"operator_gnss": "gps://x"}"#)
            .err()
            .unwrap();
        assert!(e.to_string().contains("expected gpsd://"), "{e}");
    }
}
