//! Where the operator is, for each `OPEN_DRONE_ID_SYSTEM`, and what a vehicle's status
//! says of it.
//!
//! With `operator_gnss` configured, the location is the ground station's receiver's
//! (`MAV_ODID_OPERATOR_LOCATION_TYPE_LIVE_GNSS`) while its latest report is a fix no
//! older than [`LIVE_FIX_MAX_AGE`]; otherwise, and without `operator_gnss`, it is the
//! configured `operator_location` (`FIXED`), else the vehicle's takeoff point, its home
//! (`TAKEOFF`). When live GNSS is configured but not used, the reason is kept
//! ([`OperatorLocation::fallback`]) and shown in the vehicle's `remote_id` status.
//!
//! Heights: `operator_altitude_geo` is the height above the WGS84 ellipsoid. A live
//! fix gives it (the receiver's own, or its height above mean sea level plus its geoid
//! separation, [`skein_gnss::GnssFix::alt_hae_m`]), or it is sent as unknown (-1000 m)
//! when the receiver gave neither. The fixed location and the home carry heights above
//! mean sea level (`alt_amsl_m`, PX4's `HOME_POSITION.altitude`), sent as they are.

use super::RemoteIdConfig;
use skein_gnss::{GnssFix, GnssReader, GnssState};
use skein_model::geo::GeoPoint;
use skein_model::vehicle::{
    OperatorGnssStatus, OperatorLocationSource, RemoteIdArmStatus, RemoteIdStatus,
};
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};

/// The oldest fix sent as the operator's live location. Receivers report once a second
/// (NMEA's usual rate, one gpsd `TPV` a cycle), so 3 s is three reports missed: a
/// receiver gone rather than a late sentence (the link's own silence limit,
/// `LINK_TIMEOUT`, is 3 s for the same reason). A walking operator moves about 4.5 m in
/// that time, within a consumer receiver's error; past it the messages fall back to a
/// location that is not stale.
pub const LIVE_FIX_MAX_AGE: Duration = Duration::from_secs(3);

/// The operator location for one `OPEN_DRONE_ID_SYSTEM`, and where it came from.
#[derive(Debug, Clone, PartialEq)]
pub struct OperatorLocation {
    /// Where it came from (`operator_location_type`).
    pub source: OperatorLocationSource,
    /// Latitude and longitude, degrees; `None`: unknown (sent as 0, 0: a takeoff point
    /// before the vehicle reported its home).
    pub lat_lon_deg: Option<(f64, f64)>,
    /// `operator_altitude_geo`, metres (see the module docs); `None`: unknown (-1000).
    pub altitude_m: Option<f64>,
    /// When the live fix arrived (`LiveGnss` only), for its age.
    pub fix_at: Option<Instant>,
    /// Why it is not the live GNSS location, when `operator_gnss` is configured.
    pub fallback: Option<String>,
}

impl RemoteIdConfig {
    /// The operator location at `now` (see the module docs): from `gnss`, the state of
    /// the `operator_gnss` reader (`None` when there is none), else the configured
    /// location, else `home`, the vehicle's takeoff point.
    pub fn operator_location(
        &self,
        gnss: Option<&GnssState>,
        home: Option<GeoPoint>,
        now: Instant,
    ) -> OperatorLocation {
        let fallback = match (&self.operator_gnss, gnss) {
            (None, _) => None,
            (Some(source), None) => Some(format!("{source} is not read in this process")),
            (Some(_), Some(state)) => match live_fix(state, now) {
                Ok((fix, at)) => return live(fix, at),
                Err(why) => Some(why),
            },
        };
        let (source, at) = match self.operator_location {
            Some(p) => (OperatorLocationSource::Fixed, Some(p)),
            None => (OperatorLocationSource::Takeoff, home),
        };
        OperatorLocation {
            source,
            lat_lon_deg: at.map(|p| (p.lat_deg, p.lon_deg)),
            altitude_m: at.map(|p| p.alt_amsl_m),
            fix_at: None,
            fallback,
        }
    }
}

fn live(fix: GnssFix, at: Instant) -> OperatorLocation {
    OperatorLocation {
        source: OperatorLocationSource::LiveGnss,
        lat_lon_deg: Some((fix.lat_deg, fix.lon_deg)),
        altitude_m: fix.alt_hae_m,
        fix_at: Some(at),
        fallback: None,
    }
}

/// The receiver's fix and when it arrived, if it is live at `now`: its latest report is
/// a fix no older than [`LIVE_FIX_MAX_AGE`].
///
/// # Errors
/// Why not, naming the source, with why its connection ended if it did.
pub fn live_fix(state: &GnssState, now: Instant) -> Result<(GnssFix, Instant), String> {
    let source = &state.source;
    let connection = match (&state.error, state.connected) {
        (Some(e), _) => format!("; {e}"),
        (None, false) => "; not connected".into(),
        (None, true) => String::new(),
    };
    if let Some(since) = state.no_fix_since {
        let for_s = now.saturating_duration_since(since).as_secs_f64();
        return Err(format!("{source} reports no fix (for {for_s:.1} s)"));
    }
    match state.last_fix {
        None => Err(format!("no fix yet from {source}{connection}")),
        Some((_, at)) if now.saturating_duration_since(at) > LIVE_FIX_MAX_AGE => {
            let age_s = now.saturating_duration_since(at).as_secs_f64();
            Err(format!(
                "no fix from {source} for {age_s:.1} s (the limit is {} s){connection}",
                LIVE_FIX_MAX_AGE.as_secs()
            ))
        }
        Some(fix) => Ok(fix),
    }
}

/// The vehicle's side of Remote ID: the operator location last sent (a field of
/// [`VehicleLink`](crate::VehicleLink)).
#[derive(Debug, Default)]
pub struct RemoteIdLink {
    last: Mutex<Option<OperatorLocation>>,
}

impl RemoteIdLink {
    /// The operator location was sent.
    pub fn sent(&self, location: OperatorLocation) {
        *self.last.lock().unwrap_or_else(PoisonError::into_inner) = Some(location);
    }

    /// The operator location last sent.
    pub fn last(&self) -> Option<OperatorLocation> {
        self.last
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// The vehicle's Remote ID status at `now`: whether skein sends the operator's part
    /// (`config`), what it last sent, the process's receiver (`gnss`), and what the
    /// transmitter said; `None` when skein sends nothing and no transmitter reported.
    pub fn status(
        &self,
        config: Option<&RemoteIdConfig>,
        gnss: Option<&GnssReader>,
        transmitter: Option<RemoteIdArmStatus>,
        now: Instant,
    ) -> Option<RemoteIdStatus> {
        if config.is_none() && transmitter.is_none() {
            return None;
        }
        let last = self.last();
        Some(RemoteIdStatus {
            operator_sent: config.is_some(),
            transmitter,
            operator_location_source: last.as_ref().map(|l| l.source),
            operator_location_age_s: last
                .as_ref()
                .and_then(|l| l.fix_at)
                .map(|at| now.saturating_duration_since(at).as_secs_f64()),
            operator_location_fallback: last.and_then(|l| l.fallback),
            operator_gnss: gnss.map(|g| gnss_status(&g.state(), now)),
        })
    }
}

/// What the API shows of the receiver.
fn gnss_status(s: &GnssState, now: Instant) -> OperatorGnssStatus {
    OperatorGnssStatus {
        source: s.source.to_string(),
        connected: s.connected,
        fix_age_s: s.fix_age(now).map(|a| a.as_secs_f64()),
        eph_m: s.last_fix.and_then(|(f, _)| f.eph_m),
        no_fix: s.no_fix_since.is_some(),
        error: s.error.clone(),
        malformed: s.malformed,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skein_gnss::GnssSource;

    const HOME: GeoPoint = GeoPoint {
        lat_deg: 47.397742,
        lon_deg: 8.545594,
        alt_amsl_m: 488.0,
    };

    fn config(fixed: bool) -> RemoteIdConfig {
        let fixed = if fixed {
            "operator_location = { lat_deg = 60.1699, lon_deg = 24.9384, alt_amsl_m = 25.0 }\n"
        } else {
            ""
        };
        toml::from_str(&format!(
            "operator_id = \"OP1\"\noperator_gnss = \"gpsd://127.0.0.1\"\n{fixed}"
        ))
        .unwrap()
    }

    /// A receiver connected to gpsd whose last fix arrived at `fix_at`.
    fn receiver(fix_at: Option<Instant>) -> GnssState {
        let fix =
            GnssFix::at(60.171234, 24.945678)
                .unwrap()
                .with_heights(None, Some(25.0), Some(17.5));
        GnssState {
            source: "gpsd://127.0.0.1".parse::<GnssSource>().unwrap(),
            connected: true,
            error: None,
            last_fix: fix_at.map(|at| (fix, at)),
            no_fix_since: None,
            reports: 10,
            malformed: 0,
            connects: 1,
        }
    }

    #[test]
    fn a_fresh_fix_is_the_live_location_with_its_ellipsoid_height() {
        let now = Instant::now();
        let at = now - Duration::from_millis(400);
        let l = config(true).operator_location(Some(&receiver(Some(at))), Some(HOME), now);
        assert_eq!(l.source, OperatorLocationSource::LiveGnss);
        assert_eq!(l.lat_lon_deg, Some((60.171234, 24.945678)));
        assert_eq!(
            (l.altitude_m, l.fix_at, l.fallback),
            (Some(42.5), Some(at), None)
        );
        let edge = now - LIVE_FIX_MAX_AGE;
        let l = config(false).operator_location(Some(&receiver(Some(edge))), Some(HOME), now);
        assert_eq!(l.source, OperatorLocationSource::LiveGnss, "{l:?}");
    }

    #[test]
    fn a_stale_fix_falls_back_to_the_fixed_location_else_the_takeoff_point() {
        let now = Instant::now();
        let mut gnss = receiver(Some(now - LIVE_FIX_MAX_AGE - Duration::from_millis(200)));
        gnss.connected = false;
        gnss.error = Some("Connection refused (os error 111)".into());
        let l = config(true).operator_location(Some(&gnss), Some(HOME), now);
        assert_eq!(l.source, OperatorLocationSource::Fixed);
        assert_eq!(l.lat_lon_deg, Some((60.1699, 24.9384)));
        assert_eq!((l.altitude_m, l.fix_at), (Some(25.0), None));
        assert_eq!(
            l.fallback.as_deref(),
            Some(
                "no fix from gpsd://127.0.0.1:2947 for 3.2 s (the limit is 3 s); \
                 Connection refused (os error 111)"
            )
        );
        let l = config(false).operator_location(Some(&gnss), Some(HOME), now);
        assert_eq!(l.source, OperatorLocationSource::Takeoff);
        assert_eq!(l.lat_lon_deg, Some((HOME.lat_deg, HOME.lon_deg)));
        assert!(l.fallback.unwrap().starts_with("no fix from"));
    }

    #[test]
    fn no_fix_yet_or_a_receiver_saying_it_has_none_falls_back() {
        let now = Instant::now();
        let mut gnss = receiver(None);
        gnss.connected = false;
        let l = config(true).operator_location(Some(&gnss), None, now);
        assert_eq!(l.source, OperatorLocationSource::Fixed);
        assert_eq!(
            l.fallback.as_deref(),
            Some("no fix yet from gpsd://127.0.0.1:2947; not connected")
        );
        // A fresh fix, then the receiver says it lost it: no waiting for the fix to age.
        let mut gnss = receiver(Some(now - Duration::from_millis(900)));
        gnss.no_fix_since = Some(now - Duration::from_millis(100));
        let l = config(false).operator_location(Some(&gnss), None, now);
        assert_eq!(
            (l.source, l.lat_lon_deg),
            (OperatorLocationSource::Takeoff, None)
        );
        assert_eq!(
            l.fallback.as_deref(),
            Some("gpsd://127.0.0.1:2947 reports no fix (for 0.1 s)")
        );
        let l = config(true).operator_location(None, None, now);
        assert!(l.fallback.unwrap().contains("is not read"));
    }

    #[test]
    fn without_operator_gnss_nothing_falls_back() {
        let mut c = config(true);
        c.operator_gnss = None;
        let l = c.operator_location(Some(&receiver(Some(Instant::now()))), None, Instant::now());
        assert_eq!(
            (l.source, l.fallback),
            (OperatorLocationSource::Fixed, None)
        );
    }

    #[test]
    fn the_status_says_what_was_sent_and_how_old_it_is() {
        let link = RemoteIdLink::default();
        let now = Instant::now();
        let c = config(true);
        assert_eq!(link.status(None, None, None, now), None);
        let s = link.status(Some(&c), None, None, now).unwrap();
        assert_eq!((s.operator_sent, s.operator_location_source), (true, None));
        let at = now - Duration::from_millis(500);
        link.sent(c.operator_location(Some(&receiver(Some(at))), None, now));
        let later = now + Duration::from_millis(250);
        let s = link.status(Some(&c), None, None, later).unwrap();
        assert_eq!(
            s.operator_location_source,
            Some(OperatorLocationSource::LiveGnss)
        );
        assert_eq!(s.operator_location_age_s, Some(0.75));
        assert_eq!(s.operator_location_fallback, None);
    }
}
