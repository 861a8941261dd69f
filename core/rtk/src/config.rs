//! `[rtk]` of the configuration and the body of `PUT /api/v1/rtk`: the corrections source
//! and how corrections are sent.

use crate::source::Source;
use serde::{Deserialize, Serialize};
use std::time::Duration;

/// The default rate cap of corrections to one vehicle, bytes/s: a 1 Hz MSM4 stream of
/// four constellations (about 1-1.5 kB/s) with room, while a 57600-baud telemetry radio
/// (about 5.7 kB/s) keeps most of its capacity for telemetry and a 50 Hz setpoint stream.
pub const DEFAULT_MAX_BYTES_S: f64 = 2000.0;

/// The default stall timeout: RTCM bases send every second; 10 s without a frame is a
/// dead stream (RTKLIB's `str2str` uses the same default).
pub const DEFAULT_STALL_TIMEOUT_S: f64 = 10.0;

/// How often a network RTK caster is told where the fleet is (NMEA `GGA`).
pub const GGA_PERIOD: Duration = Duration::from_secs(10);

fn default_max_bytes_s() -> f64 {
    DEFAULT_MAX_BYTES_S
}

fn default_stall_timeout_s() -> f64 {
    DEFAULT_STALL_TIMEOUT_S
}

fn yes() -> bool {
    true
}

/// The corrections source and how corrections are sent (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct RtkConfig {
    /// Where corrections come from:
    /// `ntrip://[USER[:PASSWORD]@]HOST[:PORT]/MOUNTPOINT[?version=1]`, `tcp://HOST:PORT`,
    /// `udp://[ADDRESS]:PORT` or `serial:DEVICE:BAUD`.
    pub source: String,
    /// Rate cap of corrections to each vehicle, bytes/s, MAVLink framing included
    /// (100 to 1,000,000; default 2000). A message that does not fit is dropped whole.
    #[serde(default = "default_max_bytes_s")]
    #[schema(minimum = 100, maximum = 1_000_000, default = 2000)]
    pub max_bytes_s: f64,
    /// Seconds without an RTCM frame after which the source is stalled and reconnected
    /// (1 to 600; default 10).
    #[serde(default = "default_stall_timeout_s")]
    #[schema(minimum = 1, maximum = 600, default = 10)]
    pub stall_timeout_s: f64,
    /// Tell an NTRIP caster where the fleet is (NMEA `GGA` every 10 s, the mean of the
    /// vehicles' positions), which a network RTK caster needs; default true.
    #[serde(default = "yes")]
    #[schema(default = true)]
    pub send_gga: bool,
}

/// A checked [`RtkConfig`]: the source parsed, the numbers in range.
#[derive(Debug, Clone, PartialEq)]
pub struct RtkSettings {
    /// The parsed source.
    pub source: Source,
    /// Rate cap per vehicle, bytes/s.
    pub max_bytes_s: f64,
    /// Stall timeout.
    pub stall_timeout: Duration,
    /// Send GGA to NTRIP casters.
    pub send_gga: bool,
}

/// A field of [`RtkConfig`] that is wrong, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConfigError {
    /// The field (`source`, `max_bytes_s`, `stall_timeout_s`).
    pub field: &'static str,
    /// What is wrong.
    pub error: String,
}

impl std::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.field, self.error)
    }
}

impl std::error::Error for ConfigError {}

impl RtkConfig {
    /// Checks the configuration.
    ///
    /// # Errors
    /// The first field that is wrong: a source that does not parse, a rate cap or stall
    /// timeout out of range.
    pub fn settings(&self) -> Result<RtkSettings, ConfigError> {
        let source: Source = self
            .source
            .parse()
            .map_err(|e: crate::SourceError| ConfigError {
                field: "source",
                error: e.0,
            })?;
        if !(100.0..=1e6).contains(&self.max_bytes_s) {
            return Err(ConfigError {
                field: "max_bytes_s",
                error: format!("{} is outside 100 to 1000000 bytes/s", self.max_bytes_s),
            });
        }
        if !(1.0..=600.0).contains(&self.stall_timeout_s) {
            return Err(ConfigError {
                field: "stall_timeout_s",
                error: format!("{} is outside 1 to 600 s", self.stall_timeout_s),
            });
        }
        Ok(RtkSettings {
            source,
            max_bytes_s: self.max_bytes_s,
            stall_timeout: Duration::from_secs_f64(self.stall_timeout_s),
            send_gga: self.send_gga,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(json: &str) -> RtkConfig {
        serde_json::from_str(json).unwrap()
    }

    #[test]
    fn defaults_fill_what_is_left_out() {
        let s = config(r#"{"source": "tcp://base:5000"}"#)
            .settings()
            .unwrap();
        assert_eq!(s.max_bytes_s, DEFAULT_MAX_BYTES_S);
        assert_eq!(s.stall_timeout, Duration::from_secs(10));
        assert!(s.send_gga);
    }

    #[test]
    fn each_bad_field_is_named() {
        for (json, field) in [
            (r#"{"source": "ftp://x"}"#, "source"),
            (
                r#"{"source": "tcp://b:1", "max_bytes_s": 10}"#,
                "max_bytes_s",
            ),
            (
                r#"{"source": "tcp://b:1", "stall_timeout_s": 0}"#,
                "stall_timeout_s",
            ),
        ] {
            assert_eq!(config(json).settings().unwrap_err().field, field, "{json}");
        }
        let e = serde_json::from_str::<RtkConfig>(r#"{"source": "tcp://b:1", "mount": 1}"#);
        assert!(e.unwrap_err().to_string().contains("unknown field `mount`"));
    }
}
