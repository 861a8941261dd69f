//! gpsd's JSON protocol (gpsd 3.x, `proto_major` 3): the client asks for reports with
//! [`WATCH`]; gpsd answers `VERSION`, `DEVICES` and `WATCH`, then one `TPV`
//! (time-position-velocity) report per receiver cycle, with `SKY` and others between.
//! Only `TPV` says where the receiver is:
//!
//! - `mode`: 0 unknown, 1 no fix, 2 2D fix, 3 3D fix;
//! - `lat`, `lon`: degrees; `altHAE`: height above the WGS84 ellipsoid, `altMSL` (`alt`
//!   in gpsd before 3.20) above mean sea level, `geoidSep` their difference, metres;
//! - `eph`: estimated horizontal error, `epx`/`epy` along longitude and latitude, metres;
//! - `status`: 5 is dead reckoning only, not a GNSS position.

use crate::fix::{GnssFix, GnssReport};
use serde::Deserialize;

/// The command that asks gpsd for JSON reports, with its line end.
pub const WATCH: &str = "?WATCH={\"enable\":true,\"json\":true}\n";

/// gpsd's `TPV.status` for dead reckoning only.
const STATUS_DR: u8 = 5;

/// What one line said.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Decoded {
    /// A `TPV`: the receiver's fix, or that it has none.
    Report(GnssReport),
    /// Another report (`VERSION`, `DEVICES`, `WATCH`, `SKY`, ...) or an empty line.
    Ignored,
}

/// Why a line was dropped.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Malformed(pub String);

/// The fields of a gpsd report skein reads (every other is ignored).
#[derive(Debug, Deserialize)]
struct Report {
    class: String,
    mode: Option<u8>,
    status: Option<u8>,
    lat: Option<f64>,
    lon: Option<f64>,
    #[serde(rename = "altHAE")]
    alt_hae: Option<f64>,
    #[serde(rename = "altMSL")]
    alt_msl: Option<f64>,
    alt: Option<f64>,
    #[serde(rename = "geoidSep")]
    geoid_sep: Option<f64>,
    eph: Option<f64>,
    epx: Option<f64>,
    epy: Option<f64>,
    message: Option<String>,
}

/// Decodes one line from gpsd (without its line end).
///
/// # Errors
/// A line that is not a JSON object with a `class`, a `TPV` whose fields have the
/// wrong types, a `TPV` with a fix but no valid position, or gpsd's own `ERROR`
/// report (its message).
pub fn decode(line: &[u8]) -> Result<Decoded, Malformed> {
    if line.iter().all(u8::is_ascii_whitespace) {
        return Ok(Decoded::Ignored);
    }
    let r: Report = serde_json::from_slice(line).map_err(|e| Malformed(e.to_string()))?;
    match r.class.as_str() {
        "TPV" => tpv(&r).map(Decoded::Report),
        "ERROR" => Err(Malformed(format!(
            "gpsd: {}",
            r.message.as_deref().unwrap_or("error")
        ))),
        _ => Ok(Decoded::Ignored),
    }
}

fn tpv(r: &Report) -> Result<GnssReport, Malformed> {
    let mode = r.mode.unwrap_or(0);
    if mode < 2 || r.status == Some(STATUS_DR) {
        return Ok(GnssReport::NoFix);
    }
    let (Some(lat), Some(lon)) = (r.lat, r.lon) else {
        return Err(Malformed(format!("TPV mode {mode} without lat and lon")));
    };
    let fix = GnssFix::at(lat, lon)
        .ok_or_else(|| Malformed(format!("TPV position {lat}, {lon} out of range")))?;
    let mut fix = if mode >= 3 {
        fix.with_heights(r.alt_hae, r.alt_msl.or(r.alt), r.geoid_sep)
    } else {
        fix
    };
    fix.eph_m = r
        .eph
        .or_else(|| Some(r.epx?.hypot(r.epy?)))
        .filter(|e| e.is_finite() && *e >= 0.0);
    Ok(GnssReport::Fix(fix))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fix(line: &str) -> GnssFix {
        match decode(line.as_bytes()) {
            Ok(Decoded::Report(GnssReport::Fix(f))) => f,
            other => panic!("{line}: {other:?}"),
        }
    }

    #[test]
    fn a_3d_tpv_gives_position_heights_and_error() {
        // As gpsd 3.22 reports a GGA + RMC receiver (gpsfake).
        let f = fix(
            r#"{"class":"TPV","device":"/dev/pts/1","mode":3,"time":"2026-01-01T12:00:00.000Z","ept":0.005,"lat":60.171234000,"lon":24.945678000,"altHAE":42.5000,"altMSL":25.0000,"alt":25.0000,"track":0.0000,"magtrack":9.2246,"magvar":9.2,"speed":0.000,"geoidSep":17.500,"eph":17.100}"#,
        );
        assert_eq!((f.lat_deg, f.lon_deg), (60.171234, 24.945678));
        assert_eq!(
            (f.alt_hae_m, f.alt_msl_m, f.eph_m),
            (Some(42.5), Some(25.0), Some(17.1))
        );
    }

    #[test]
    fn heights_come_from_msl_and_the_geoid_and_a_2d_fix_has_none() {
        let f = fix(
            r#"{"class":"TPV","mode":3,"lat":1.0,"lon":2.0,"alt":100.0,"geoidSep":-20.0,"epx":3.0,"epy":4.0}"#,
        );
        assert_eq!(
            (f.alt_hae_m, f.alt_msl_m, f.eph_m),
            (Some(80.0), Some(100.0), Some(5.0))
        );
        let f = fix(r#"{"class":"TPV","mode":2,"lat":1.0,"lon":2.0,"altHAE":5.0}"#);
        assert_eq!((f.alt_hae_m, f.alt_msl_m, f.eph_m), (None, None, None));
    }

    #[test]
    fn no_fix_and_dead_reckoning_are_no_fix() {
        for line in [
            r#"{"class":"TPV","device":"/dev/ttyACM0","mode":1}"#,
            r#"{"class":"TPV","mode":0,"lat":1.0,"lon":2.0}"#,
            r#"{"class":"TPV","mode":3,"status":5,"lat":1.0,"lon":2.0}"#,
        ] {
            assert_eq!(
                decode(line.as_bytes()),
                Ok(Decoded::Report(GnssReport::NoFix)),
                "{line}"
            );
        }
    }

    #[test]
    fn other_reports_are_ignored_and_bad_lines_refused() {
        for line in [
            r#"{"class":"VERSION","release":"3.22","rev":"3.22","proto_major":3,"proto_minor":14}"#,
            r#"{"class":"SKY","device":"/dev/pts/1","satellites":[]}"#,
            "",
        ] {
            assert_eq!(decode(line.as_bytes()), Ok(Decoded::Ignored), "{line}");
        }
        for (line, says) in [
            (r#"{"class":"TPV","mode":3,"lat":1.0"#, "EOF"),
            (r#"{"class":"TPV","mode":"3D"}"#, "invalid type"),
            (r#"{"mode":3}"#, "class"),
            (
                r#"{"class":"TPV","mode":3,"lat":1.0}"#,
                "without lat and lon",
            ),
            (
                r#"{"class":"TPV","mode":2,"lat":91.0,"lon":0.0}"#,
                "out of range",
            ),
            (
                r#"{"class":"ERROR","message":"Unrecognized request"}"#,
                "Unrecognized",
            ),
            ("$GPGGA,1", "expected value"),
        ] {
            let e = decode(line.as_bytes()).unwrap_err();
            assert!(e.0.contains(says), "{line}: {e:?}");
        }
    }
}
