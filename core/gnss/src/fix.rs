//! A receiver's position fix, and what one line from a receiver says.

/// A position fix of the receiver (WGS84).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GnssFix {
    /// Latitude, degrees north.
    pub lat_deg: f64,
    /// Longitude, degrees east.
    pub lon_deg: f64,
    /// Height above the WGS84 ellipsoid, metres: the receiver's own (gpsd's `altHAE`),
    /// else its height above mean sea level plus its geoid separation (gpsd's
    /// `altMSL` + `geoidSep`, NMEA `GGA` fields 9 + 11); `None` when it gave neither,
    /// or for a 2D fix.
    pub alt_hae_m: Option<f64>,
    /// Height above mean sea level, metres (gpsd's `altMSL`, NMEA `GGA` field 9);
    /// `None` when not given or for a 2D fix.
    pub alt_msl_m: Option<f64>,
    /// Estimated horizontal error, metres (gpsd's `eph`, else the root sum of squares of
    /// `epx` and `epy`); `None` when not given (NMEA `GGA` has only the HDOP).
    pub eph_m: Option<f64>,
}

/// What one report of a receiver says of its position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GnssReport {
    /// A valid fix (gpsd `TPV` mode 2 or 3; NMEA `GGA` quality 1 to 5, or `RMC` status
    /// `A` or `D`).
    Fix(GnssFix),
    /// The receiver says it has no fix (gpsd `TPV` mode 0 or 1, or dead reckoning
    /// only; NMEA `GGA` quality 0 or 6 to 8, or `RMC` status `V`).
    NoFix,
}

impl GnssFix {
    /// A fix at `lat_deg`, `lon_deg` when both are finite and in range (±90°, ±180°).
    pub fn at(lat_deg: f64, lon_deg: f64) -> Option<GnssFix> {
        let valid = lat_deg.is_finite()
            && lon_deg.is_finite()
            && lat_deg.abs() <= 90.0
            && lon_deg.abs() <= 180.0;
        valid.then_some(GnssFix {
            lat_deg,
            lon_deg,
            alt_hae_m: None,
            alt_msl_m: None,
            eph_m: None,
        })
    }

    /// This fix with its heights: above mean sea level `msl_m`, and above the ellipsoid
    /// `hae_m` when given, else `msl_m` + `geoid_sep_m` (non-finite values left out).
    pub fn with_heights(
        mut self,
        hae_m: Option<f64>,
        msl_m: Option<f64>,
        geoid_sep_m: Option<f64>,
    ) -> GnssFix {
        let finite = |v: Option<f64>| v.filter(|v| v.is_finite());
        self.alt_msl_m = finite(msl_m);
        self.alt_hae_m = finite(hae_m).or_else(|| Some(self.alt_msl_m? + finite(geoid_sep_m)?));
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ellipsoid_height_is_the_receivers_or_msl_plus_the_geoid_separation() {
        let f = GnssFix::at(60.0, 25.0).unwrap();
        assert_eq!(
            f.with_heights(Some(42.5), Some(25.0), Some(17.0)).alt_hae_m,
            Some(42.5)
        );
        let g = f.with_heights(None, Some(25.0), Some(17.5));
        assert_eq!((g.alt_hae_m, g.alt_msl_m), (Some(42.5), Some(25.0)));
        assert_eq!(f.with_heights(None, Some(25.0), None).alt_hae_m, None);
        assert_eq!(f.with_heights(None, None, Some(17.5)).alt_hae_m, None);
        assert_eq!(f.with_heights(Some(f64::NAN), None, None).alt_hae_m, None);
    }

    #[test]
    fn a_position_out_of_range_is_no_fix() {
        assert!(GnssFix::at(90.5, 0.0).is_none());
        assert!(GnssFix::at(0.0, -180.1).is_none());
        assert!(GnssFix::at(f64::NAN, 0.0).is_none());
        assert!(GnssFix::at(-90.0, 180.0).is_some());
    }
}
