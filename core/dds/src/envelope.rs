//! The swarm protocol's DDS envelope: every sample of the `/skein/swarm/*` topics and of
//! `/skein/formation` is a `skein_msgs/SwarmMessage` ([`Envelope`]) carrying one
//! `skein_swarm::protocol` type as JSON, with the vehicle it is about, its sender's id
//! and epoch, and its sender's swarm origin, for the receiver's frame conversion
//! ([`crate::reframe`]). The topics are in [`crate::topics`]; which role writes and reads
//! which is in [`crate::agent`], [`crate::remote`] and [`crate::mirror`].

use crate::counters::DdsCounters;
use crate::msgs::{Header, SwarmMessage};
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
    /// The sender's swarm origin, `None` when it had none.
    pub origin: Option<GeoPoint>,
    /// The body, JSON.
    pub body: String,
}

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

    /// Unwraps a sample.
    pub fn from_msg(m: SwarmMessage) -> Envelope {
        let origin = [m.origin_lat_deg, m.origin_lon_deg, m.origin_alt_m]
            .iter()
            .all(|v| v.is_finite())
            .then(|| GeoPoint::new(m.origin_lat_deg, m.origin_lon_deg, m.origin_alt_m));
        Envelope {
            vehicle_id: m.vehicle_id,
            sender_id: m.sender_id,
            epoch: m.epoch,
            origin,
            body: m.body,
        }
    }

    /// The body as `B`.
    ///
    /// # Errors
    /// It is not a `B` (the sample is counted as malformed and dropped).
    pub fn body<B: for<'de> Deserialize<'de>>(&self) -> Result<B, serde_json::Error> {
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
}
