//! The pieces of the source strings an operator writes for a receiver or a stream
//! (`[rtk] source`, `[remote_id] operator_gnss`): `HOST:PORT` (IPv6 in brackets), a serial
//! `DEVICE:BAUD`, and the error that names the text and what is wrong with it. Each source
//! type (the RTK corrections' `Source`, the ground station's `GnssSource`) parses its own
//! schemes (`ntrip://`, `gpsd://`, ...) from these.

use std::fmt;

/// Why a source string was refused: the whole text (credentials redacted) and what is
/// wrong with it, e.g. "`tcp://host`: no port (HOST:PORT)".
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SourceError(pub String);

impl fmt::Display for SourceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for SourceError {}

/// `HOST:PORT`, `[V6]:PORT`, or `HOST` alone with the `default` port.
///
/// Returns the host (brackets removed; empty when the text names none: the caller
/// decides whether that means "any local address" or an error) and the port (1 to
/// 65535). Errors: an unclosed `[`, a port that is not 1 to 65535, no port and no
/// default.
pub fn host_port(s: &str, default: Option<u16>) -> Result<(String, u16), String> {
    let (host, port) = if let Some(v6) = s.strip_prefix('[') {
        let (h, after) = v6.split_once(']').ok_or("unclosed `[` in the host")?;
        (h, after.strip_prefix(':'))
    } else {
        match s.rsplit_once(':') {
            Some((h, p)) => (h, Some(p)),
            None => (s, None),
        }
    };
    let port = match (port, default) {
        (Some(p), _) => p
            .parse::<u16>()
            .ok()
            .filter(|p| *p > 0)
            .ok_or_else(|| format!("port `{p}` is not 1 to 65535"))?,
        (None, Some(d)) => d,
        (None, None) => return Err("no port (HOST:PORT)".into()),
    };
    Ok((host.to_string(), port))
}

/// What follows `serial:` (or `serial://`): `DEVICE:BAUD`, e.g. `/dev/ttyACM0:9600`.
///
/// Returns the device path and the baud rate (bit/s, positive). Errors: no `:BAUD`, a
/// baud that is not a positive number, an empty device.
pub fn serial_device_baud(rest: &str) -> Result<(String, u32), String> {
    let rest = rest.strip_prefix("//").unwrap_or(rest);
    let (device, baud) = rest.rsplit_once(':').ok_or("expected serial:DEVICE:BAUD")?;
    let baud = baud
        .parse::<u32>()
        .ok()
        .filter(|b| *b > 0)
        .ok_or_else(|| format!("baud `{baud}` is not a positive number"))?;
    if device.is_empty() {
        return Err("empty serial device".into());
    }
    Ok((device.to_string(), baud))
}

/// `host` as it is written before `:PORT`: an IPv6 address in brackets, anything else
/// as it is.
pub fn bracket(host: &str) -> String {
    if host.contains(':') {
        format!("[{host}]")
    } else {
        host.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn host_and_port_in_every_form() {
        assert_eq!(host_port("h:5", None), Ok(("h".into(), 5)));
        assert_eq!(host_port("[::1]:7", None), Ok(("::1".into(), 7)));
        assert_eq!(host_port("h", Some(2101)), Ok(("h".into(), 2101)));
        assert_eq!(host_port(":9000", None), Ok(("".into(), 9000)));
        assert!(host_port("h", None).unwrap_err().contains("no port"));
        assert!(host_port("h:0", None).unwrap_err().contains("port `0`"));
        assert!(host_port("[::1", None).unwrap_err().contains("unclosed"));
    }

    #[test]
    fn a_serial_device_and_its_baud() {
        assert_eq!(
            serial_device_baud("/dev/ttyUSB0:115200"),
            Ok(("/dev/ttyUSB0".into(), 115_200))
        );
        assert_eq!(serial_device_baud("///dev/x:9600").unwrap().0, "/dev/x");
        for (s, says) in [
            ("/dev/ttyUSB0:fast", "baud `fast`"),
            ("/dev/ttyUSB0:0", "baud `0`"),
            (":9600", "empty serial device"),
            ("/dev/ttyUSB0", "serial:DEVICE:BAUD"),
        ] {
            assert!(serial_device_baud(s).unwrap_err().contains(says), "{s}");
        }
        assert_eq!((bracket("::1"), bracket("h")), ("[::1]".into(), "h".into()));
    }
}
