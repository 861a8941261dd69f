//! NMEA 0183 from a receiver: each sentence checked (its checksum, its fields) and
//! parsed by the `nmea` crate; `GGA` (fix data: quality, position, height above mean
//! sea level, geoid separation) and `RMC` (recommended minimum: status, position) are
//! turned into [`GnssReport`]s, other well-formed sentences (`GSV`, `GSA`, `VTG`) and a
//! receiver's proprietary ones (`$P…`: `$PUBX`, `$PMTK`) are ignored.
//!
//! A receiver sends both for each epoch, in an order of its own: an `RMC` carries no
//! height, so it takes the heights of the `GGA` of the same epoch (same UTC time) when
//! that came first.

use crate::fix::{GnssFix, GnssReport};
use chrono::NaiveTime;
use nmea::sentences::rmc::RmcStatusOfFix;
use nmea::sentences::{FixType, GgaData, RmcData};
use nmea::{Error, ParseResult};

/// What one line said.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Decoded {
    /// A `GGA` or `RMC`: the receiver's fix, or that it has none.
    Report(GnssReport),
    /// A well-formed sentence that says nothing of the position (or an empty line).
    Ignored,
}

/// Why a line was dropped (the parser's words).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Malformed(pub String);

/// Turns NMEA lines into reports (see the module docs).
#[derive(Debug, Default)]
pub struct NmeaDecoder {
    /// The last valid `GGA`'s time and fix.
    last_gga: Option<(NaiveTime, GnssFix)>,
}

impl NmeaDecoder {
    /// Decodes one line (without its line end).
    ///
    /// # Errors
    /// A line that is not a well-formed NMEA sentence: no `$`, not ASCII, a checksum that
    /// does not match, a field the parser refuses.
    pub fn decode(&mut self, line: &[u8]) -> Result<Decoded, Malformed> {
        let text = std::str::from_utf8(line)
            .map_err(|_| Malformed("not UTF-8".into()))?
            .trim();
        // `$P…`: a receiver's proprietary sentence (NMEA 0183's talker `P`), whose
        // layout is its maker's.
        if text.is_empty() || text.starts_with("$P") {
            return Ok(Decoded::Ignored);
        }
        match nmea::parse_str(text) {
            Ok(ParseResult::GGA(g)) => Ok(Decoded::Report(self.gga(&g))),
            Ok(ParseResult::RMC(r)) => Ok(Decoded::Report(self.rmc(&r))),
            Ok(_) => Ok(Decoded::Ignored),
            Err(Error::DisabledSentence | Error::Unsupported(_) | Error::Unknown(_)) => {
                Ok(Decoded::Ignored)
            }
            Err(e) => Err(Malformed(e.to_string())),
        }
    }

    fn gga(&mut self, g: &GgaData) -> GnssReport {
        let valid = g.fix_type.is_some_and(FixType::is_valid);
        let fix = match (valid, g.latitude, g.longitude) {
            (true, Some(lat), Some(lon)) => GnssFix::at(lat, lon),
            _ => None,
        };
        let Some(fix) = fix else {
            self.last_gga = None;
            return GnssReport::NoFix;
        };
        let fix = fix.with_heights(
            None,
            g.altitude.map(f64::from),
            g.geoid_separation.map(f64::from),
        );
        self.last_gga = g.fix_time.map(|t| (t, fix));
        GnssReport::Fix(fix)
    }

    fn rmc(&self, r: &RmcData) -> GnssReport {
        let valid = r.status_of_fix != RmcStatusOfFix::Invalid;
        let fix = match (valid, r.lat, r.lon) {
            (true, Some(lat), Some(lon)) => GnssFix::at(lat, lon),
            _ => None,
        };
        let Some(mut fix) = fix else {
            return GnssReport::NoFix;
        };
        if let Some((t, gga)) = self.last_gga
            && r.fix_time == Some(t)
        {
            fix.alt_hae_m = gga.alt_hae_m;
            fix.alt_msl_m = gga.alt_msl_m;
        }
        GnssReport::Fix(fix)
    }
}

/// `$<body>*<checksum>`: an NMEA sentence with its checksum (for tests and peers).
pub fn sentence(body: &str) -> String {
    let sum = body.bytes().fold(0u8, |c, b| c ^ b);
    format!("${body}*{sum:02X}")
}

#[cfg(test)]
mod tests {
    use super::*;

    const GGA: &str = "GPGGA,120000.00,6010.27404,N,02456.74068,E,1,09,0.9,25.0,M,17.5,M,,";
    const RMC: &str = "GPRMC,120000.00,A,6010.27404,N,02456.74068,E,0.0,0.0,010126,,,A";

    fn decode(d: &mut NmeaDecoder, body: &str) -> Result<Decoded, Malformed> {
        d.decode(sentence(body).as_bytes())
    }

    fn fix(d: Result<Decoded, Malformed>) -> GnssFix {
        match d {
            Ok(Decoded::Report(GnssReport::Fix(f))) => f,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_gga_gives_position_and_the_ellipsoid_height() {
        let f = fix(decode(&mut NmeaDecoder::default(), GGA));
        assert!((f.lat_deg - 60.171234).abs() < 1e-9, "{f:?}");
        assert!((f.lon_deg - 24.945678).abs() < 1e-9, "{f:?}");
        assert_eq!((f.alt_msl_m, f.alt_hae_m), (Some(25.0), Some(42.5)));
        assert_eq!(f.eph_m, None);
    }

    #[test]
    fn an_rmc_takes_the_heights_of_its_epochs_gga_only() {
        let mut d = NmeaDecoder::default();
        assert_eq!(fix(decode(&mut d, RMC)).alt_hae_m, None);
        decode(&mut d, GGA).unwrap();
        assert_eq!(fix(decode(&mut d, RMC)).alt_hae_m, Some(42.5));
        let next = RMC.replace("120000.00", "120001.00");
        let f = fix(decode(&mut d, &next));
        assert_eq!(
            (f.alt_hae_m, f.lat_deg),
            (None, fix(decode(&mut d, RMC)).lat_deg)
        );
    }

    #[test]
    fn a_receiver_without_a_fix_says_so() {
        let mut d = NmeaDecoder::default();
        let no_fix = [
            "GPGGA,120000.00,,,,,0,00,99.99,,,,,,",
            "GPGGA,120000.00,6010.27404,N,02456.74068,E,6,09,0.9,25.0,M,17.5,M,,",
            "GPRMC,120000.00,V,,,,,,,010126,,,N",
        ];
        for body in no_fix {
            assert_eq!(
                decode(&mut d, body),
                Ok(Decoded::Report(GnssReport::NoFix)),
                "{body}"
            );
        }
    }

    #[test]
    fn bad_sentences_are_refused_and_others_ignored() {
        let mut d = NmeaDecoder::default();
        let good = sentence(GGA);
        let (body, sum) = good.split_at(good.len() - 2);
        let other = if sum == "00" { "01" } else { "00" };
        let e = d.decode(format!("{body}{other}").as_bytes()).unwrap_err();
        assert!(e.0.contains("Checksum"), "{e:?}");
        assert!(d.decode(b"$GPGGA,garbage*00").is_err());
        assert!(d.decode(b"\xb5\x62\x01\x07").is_err());
        assert!(d.decode(b"hello").is_err());
        let bad_field = "GPGGA,120000.00,6010.27404,Q,02456.74068,E,1,09,0.9,25.0,M,17.5,M,,";
        assert!(decode(&mut d, bad_field).is_err());
        let gsv = "GPGSV,1,1,01,10,45,120,40";
        assert_eq!(decode(&mut d, gsv), Ok(Decoded::Ignored));
        assert_eq!(decode(&mut d, "PUBX,00"), Ok(Decoded::Ignored));
        assert_eq!(d.decode(b"  "), Ok(Decoded::Ignored));
    }
}
