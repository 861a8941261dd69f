//! The swarm protocol's DDS envelope: every sample of the `/skein/swarm/*` topics and of
//! `/skein/formation` is a `skein_msgs/SwarmMessage` ([`Envelope`]) carrying one
//! `skein_swarm::protocol` type as JSON, with the vehicle it is about, its sender's id
//! and epoch, and its sender's swarm origin, for the receiver's frame conversion
//! ([`crate::reframe`]). The topics are in [`crate::topics`]; which role writes and reads
//! which is in [`crate::agent`], [`crate::remote`] and [`crate::mirror`].

use crate::counters::DdsCounters;
use crate::msgs::{Header, SwarmMessage};
use crate::reframe::{Positions, Reframe, reframed};
use ros2_client::builtin_interfaces::Time;
use serde::{Deserialize, Serialize};
use skein_model::geo::{GeoPoint, NedFrame};
use skein_model::vehicle::VehicleSnapshot;
use skein_swarm::protocol::VehicleReport;

/// The body of a `/skein/swarm/report` sample.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReportBody {
    /// What the formation engine needs.
    pub report: VehicleReport,
    /// What the API shows.
    pub snapshot: VehicleSnapshot,
}

/// A received [`SwarmMessage`], its origin decoded.
#[derive(Debug, Clone, PartialEq)]
pub struct Envelope {
    /// The vehicle it is about.
    pub vehicle_id: String,
    /// Its sender.
    pub sender_id: String,
    /// The sender's epoch (coordinator to agent).
    pub epoch: u64,
    /// The sender's swarm origin, `None` when it had none (all three fields NaN).
    pub origin: Option<GeoPoint>,
    /// The body, JSON.
    pub body: String,
    /// The origin's fields when they are no WGS-84 point (see [`Envelope::from_msg`]):
    /// [`Envelope::body`] then refuses the sample.
    bad_origin: Option<[f64; 3]>,
}

/// The altitudes an origin may have, metres above mean sea level: the Dead Sea shore to
/// well above any multicopter's ceiling.
const ORIGIN_ALT_M: std::ops::RangeInclusive<f64> = -1_000.0..=100_000.0;

impl Envelope {
    /// Wraps `body` from `sender_id` about `vehicle_id`; `origin` is the sender's frame.
    ///
    /// # Errors
    /// The body does not serialise (never for the protocol types).
    pub fn message<B: Serialize>(
        vehicle_id: &str,
        sender_id: &str,
        epoch: u64,
        origin: Option<NedFrame>,
        body: &B,
    ) -> Result<SwarmMessage, serde_json::Error> {
        let o = origin.map(|f| f.origin);
        Ok(SwarmMessage {
            header: Header {
                stamp: Time::now(),
                frame_id: crate::FRAME_ID.into(),
            },
            vehicle_id: vehicle_id.into(),
            sender_id: sender_id.into(),
            epoch,
            origin_lat_deg: o.map_or(f64::NAN, |o| o.lat_deg),
            origin_lon_deg: o.map_or(f64::NAN, |o| o.lon_deg),
            origin_alt_m: o.map_or(f64::NAN, |o| o.alt_amsl_m),
            body: serde_json::to_string(body)?,
        })
    }

    /// Unwraps a sample. Its origin is `None` when all three fields are NaN (the sender
    /// has no frame yet), a point when they are one (latitude within ±90°, longitude
    /// within ±180°, altitude within −1 km to 100 km); anything else (a lone NaN, an
    /// infinity, a latitude of 500°) would turn every position of the body into nonsense
    /// or NaN in the receiver's frame, so [`Envelope::body`] refuses such a sample.
    pub fn from_msg(m: SwarmMessage) -> Envelope {
        let raw = [m.origin_lat_deg, m.origin_lon_deg, m.origin_alt_m];
        let [lat, lon, alt] = raw;
        let point = lat.abs() <= 90.0 && lon.abs() <= 180.0 && ORIGIN_ALT_M.contains(&alt);
        let (origin, bad_origin) = match (raw.iter().all(|v| v.is_nan()), point) {
            (true, _) => (None, None),
            (false, true) => (Some(GeoPoint::new(lat, lon, alt)), None),
            (false, false) => (None, Some(raw)),
        };
        Envelope {
            vehicle_id: m.vehicle_id,
            sender_id: m.sender_id,
            epoch: m.epoch,
            origin,
            body: m.body,
            bad_origin,
        }
    }

    /// The body as `B`.
    ///
    /// # Errors
    /// It is not a `B`, or the sample's origin is no point (see [`Envelope::from_msg`]);
    /// the sample is then counted as malformed and dropped.
    pub fn body<B: for<'de> Deserialize<'de>>(&self) -> Result<B, serde_json::Error> {
        if let Some([lat, lon, alt]) = self.bad_origin {
            return Err(serde::de::Error::custom(format!(
                "origin ({lat}°, {lon}°, {alt} m) is not a WGS-84 point"
            )));
        }
        serde_json::from_str(&self.body)
    }
}

/// The body of `env` as `B`; one that does not parse is counted as malformed in
/// `counters`, logged naming `what` and the vehicle, and dropped (`None`).
pub(crate) fn body_or_drop<B: for<'de> Deserialize<'de>>(
    counters: &DdsCounters,
    env: &Envelope,
    what: &str,
) -> Option<B> {
    match env.body() {
        Ok(b) => Some(b),
        Err(e) => {
            DdsCounters::add(&counters.malformed);
            tracing::warn!(
                "dds: a {what} of {} from `{}` was dropped: {e}",
                env.vehicle_id,
                env.sender_id
            );
            None
        }
    }
}

/// `value` (a body of `env`) converted by `reframe` ([`reframed`]); one with a position
/// that is no point in this frame is counted as malformed in `counters`, logged naming
/// `what` and the vehicle, and dropped (`None`).
pub(crate) fn reframed_or_drop<T: Positions>(
    counters: &DdsCounters,
    env: &Envelope,
    what: &str,
    value: T,
    reframe: Option<&Reframe>,
    f: impl Fn(&Reframe, T) -> T,
) -> Option<T> {
    let v = reframed(value, reframe, f);
    if v.is_none() {
        DdsCounters::add(&counters.malformed);
        tracing::warn!(
            "dds: a {what} of {} from `{}` was dropped: a position is no point in this \
             process's frame",
            env.vehicle_id,
            env.sender_id
        );
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn envelopes_carry_the_origin_or_nan() {
        let frame = NedFrame::new(GeoPoint::new(47.0, 8.0, 400.0));
        let m = Envelope::message(
            "uav-1",
            "agent-a",
            3,
            Some(frame),
            &VehicleReport::disconnected(),
        )
        .unwrap();
        let e = Envelope::from_msg(m);
        assert_eq!(e.origin, Some(frame.origin));
        assert_eq!(e.epoch, 3);
        assert_eq!(
            e.body::<VehicleReport>().unwrap(),
            VehicleReport::disconnected()
        );
        let m = Envelope::message("uav-1", "agent-a", 0, None, &1).unwrap();
        assert!(m.origin_lat_deg.is_nan());
        assert_eq!(Envelope::from_msg(m).origin, None);
    }

    #[test]
    fn a_sample_decodes_from_its_cdr_and_a_cut_one_does_not() {
        let frame = NedFrame::new(GeoPoint::new(47.0, 8.0, 400.0));
        let m = Envelope::message("uav-1", "c1", 7, Some(frame), &"body").unwrap();
        let bytes = crate::msgs::to_cdr(&m).unwrap();
        assert_eq!(crate::msgs::from_cdr::<SwarmMessage>(&bytes), Ok(m));
        let cut = crate::msgs::from_cdr::<SwarmMessage>(&bytes[..bytes.len() - 3]);
        assert!(cut.is_err(), "{cut:?}");
    }

    #[test]
    fn an_origin_that_is_no_point_makes_the_sample_malformed() {
        let good = Envelope::message("uav-1", "agent-a", 0, None, &1).unwrap();
        for origin in [
            [1e300, 8.0, 400.0],
            [47.0, 181.0, 400.0],
            [-90.5, 8.0, 400.0],
            [47.0, 8.0, f64::INFINITY],
            [47.0, 8.0, 2e5],
            [f64::NAN, 8.0, 400.0],
        ] {
            let mut m = good.clone();
            [m.origin_lat_deg, m.origin_lon_deg, m.origin_alt_m] = origin;
            let e = Envelope::from_msg(m);
            assert_eq!(e.origin, None, "{origin:?}");
            let counters = DdsCounters::default();
            assert_eq!(
                body_or_drop::<i32>(&counters, &e, "report"),
                None,
                "{origin:?}"
            );
            assert_eq!(counters.values()[3], ("malformed", 1), "{origin:?}");
            let why = e.body::<i32>().unwrap_err().to_string();
            assert!(why.contains("is not a WGS-84 point"), "{why}");
        }
        let mut m = good;
        [m.origin_lat_deg, m.origin_lon_deg, m.origin_alt_m] = [-90.0, 180.0, -400.0];
        let e = Envelope::from_msg(m);
        assert_eq!(e.origin, Some(GeoPoint::new(-90.0, 180.0, -400.0)));
        assert_eq!(e.body::<i32>().unwrap(), 1);
    }
}
