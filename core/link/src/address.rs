//! Connection strings: `udpin:HOST:PORT`, `udpout:HOST:PORT`, `tcpout:HOST:PORT`,
//! `serial:DEVICE:BAUD` (the forms MAVSDK, mavlink-router and QGroundControl users know).

use serde::{Deserialize, Serialize};
use std::fmt;
use std::net::{SocketAddr, ToSocketAddrs};

/// Where and how to reach one or more autopilots.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ConnectionAddress {
    /// Listen on a local UDP address; reply to whichever address each vehicle sends from
    /// (PX4 SITL sends to 14540+i).
    UdpIn(SocketAddr),
    /// Send to a remote UDP address from one fixed local socket (PX4 locks onto the first
    /// sender it hears).
    UdpOut(SocketAddr),
    /// Connect to a TCP server (PX4 SITL's `-t` or a mavlink-router TCP port).
    TcpOut(SocketAddr),
    /// A serial device at a baud rate (telemetry radio, FMU USB).
    Serial {
        /// Device path, e.g. `/dev/ttyACM0`.
        device: String,
        /// Baud rate, e.g. 57600.
        baud: u32,
    },
}

/// Why a connection string was refused: the text and what is wrong with it (the
/// operator's source strings share one error, [`skein_model::endpoint::SourceError`]).
pub use skein_model::endpoint::SourceError as AddressError;

fn socket_addr(s: &str, whole: &str) -> Result<SocketAddr, AddressError> {
    if let Ok(a) = s.parse() {
        return Ok(a);
    }
    s.to_socket_addrs()
        .ok()
        .and_then(|mut it| it.next())
        .ok_or_else(|| {
            AddressError(format!(
                "`{whole}`: `{s}` is not HOST:PORT (e.g. 0.0.0.0:14540)"
            ))
        })
}

impl std::str::FromStr for ConnectionAddress {
    type Err = AddressError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let (scheme, rest) = s.split_once(':').ok_or_else(|| {
            AddressError(format!(
                "`{s}`: expected udpin:HOST:PORT, udpout:HOST:PORT, tcpout:HOST:PORT or serial:DEVICE:BAUD"
            ))
        })?;
        // Accept the MAVSDK URL spelling `udpin://host:port` too.
        let rest = rest.strip_prefix("//").unwrap_or(rest);
        match scheme {
            "udpin" | "udp" => Ok(ConnectionAddress::UdpIn(socket_addr(rest, s)?)),
            "udpout" => Ok(ConnectionAddress::UdpOut(socket_addr(rest, s)?)),
            "tcpout" | "tcp" => Ok(ConnectionAddress::TcpOut(socket_addr(rest, s)?)),
            "serial" => {
                let (device, baud) = skein_model::endpoint::serial_device_baud(rest)
                    .map_err(|e| AddressError(format!("`{s}`: {e}")))?;
                Ok(ConnectionAddress::Serial { device, baud })
            }
            other => Err(AddressError(format!(
                "`{s}`: unknown scheme `{other}` (udpin, udpout, tcpout, serial)"
            ))),
        }
    }
}

impl fmt::Display for ConnectionAddress {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConnectionAddress::UdpIn(a) => write!(f, "udpin:{a}"),
            ConnectionAddress::UdpOut(a) => write!(f, "udpout:{a}"),
            ConnectionAddress::TcpOut(a) => write!(f, "tcpout:{a}"),
            ConnectionAddress::Serial { device, baud } => write!(f, "serial:{device}:{baud}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_every_form() {
        assert_eq!(
            "udpin:0.0.0.0:14540".parse::<ConnectionAddress>().unwrap(),
            ConnectionAddress::UdpIn("0.0.0.0:14540".parse().unwrap())
        );
        assert_eq!(
            "udpin://127.0.0.1:14541"
                .parse::<ConnectionAddress>()
                .unwrap(),
            ConnectionAddress::UdpIn("127.0.0.1:14541".parse().unwrap())
        );
        assert_eq!(
            "udpout:127.0.0.1:14580"
                .parse::<ConnectionAddress>()
                .unwrap(),
            ConnectionAddress::UdpOut("127.0.0.1:14580".parse().unwrap())
        );
        assert_eq!(
            "tcpout:127.0.0.1:4560"
                .parse::<ConnectionAddress>()
                .unwrap(),
            ConnectionAddress::TcpOut("127.0.0.1:4560".parse().unwrap())
        );
        assert_eq!(
            "serial:/dev/ttyACM0:57600"
                .parse::<ConnectionAddress>()
                .unwrap(),
            ConnectionAddress::Serial {
                device: "/dev/ttyACM0".into(),
                baud: 57600
            }
        );
        for s in [
            "udpin:0.0.0.0:14540",
            "udpout:127.0.0.1:14580",
            "serial:/dev/ttyUSB0:921600",
        ] {
            assert_eq!(s.parse::<ConnectionAddress>().unwrap().to_string(), s);
        }
    }

    #[test]
    fn errors_name_the_problem() {
        let e = "udp-in:1.2.3.4:5".parse::<ConnectionAddress>().unwrap_err();
        assert!(e.0.contains("unknown scheme `udp-in`"), "{e}");
        let e = "udpin:nonsense".parse::<ConnectionAddress>().unwrap_err();
        assert!(e.0.contains("not HOST:PORT"), "{e}");
        let e = "serial:/dev/ttyS0:fast"
            .parse::<ConnectionAddress>()
            .unwrap_err();
        assert!(e.0.contains("baud `fast`"), "{e}");
        assert!("14540".parse::<ConnectionAddress>().is_err());
    }
}
