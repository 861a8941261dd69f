//! The swarm protocol's DDS envelope (`skein_msgs/SwarmMessage`, [`Envelope`]) and the
//! `/skein/swarm/*` topics ([`ProtocolTopics`]) that carry `skein_swarm::protocol`
//! between coordinators and agents. Each envelope carries its sender's swarm origin, for
//! the receiver's frame conversion ([`crate::reframe`]).

use crate::link::{DdsError, DdsShared, err};
use crate::msgs::{Header, RosMessage, SwarmMessage};
use crate::topics;
use ros2_client::builtin_interfaces::Time;
use ros2_client::{Name, Node, Publisher, QosProfile, Subscription};
use serde::{Deserialize, Serialize};
use skein_model::geo::{GeoPoint, NedFrame};
use skein_model::vehicle::VehicleSnapshot;
use skein_swarm::protocol::{ToVehicle, VehicleReport};
use std::sync::Arc;
use std::sync::atomic::Ordering;

/// The body of a `/skein/swarm/report` sample.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReportBody {
    /// What the formation engine needs.
    pub report: VehicleReport,
    /// What the API shows.
    pub snapshot: VehicleSnapshot,
}

/// A writer and a reader of one `/skein/swarm/*` topic.
pub struct Topic {
    /// Writes samples.
    pub writer: Publisher<SwarmMessage>,
    /// Reads everyone's samples (its own too: readers skip their own vehicles).
    pub reader: Arc<Subscription<SwarmMessage>>,
}

/// The four protocol topics of a coordinator or an agent.
pub struct ProtocolTopics {
    /// `/skein/swarm/report`: agent → coordinators.
    pub report: Topic,
    /// `/skein/swarm/target`: coordinator → agents, slot targets.
    pub target: Topic,
    /// `/skein/swarm/command`: coordinator → agents, every other [`ToVehicle`].
    pub command: Topic,
    /// `/skein/swarm/command_result`: agent → coordinators,
    /// [`FromVehicle`](skein_swarm::protocol::FromVehicle).
    pub command_result: Topic,
    /// `/skein/formation`: the active coordinator's formation, for the standbys
    /// ([`crate::mirror`]).
    pub formation: Topic,
    /// `/skein/swarm/events`: agent → coordinators, the events of its vehicles
    /// ([`skein_swarm::SwarmEvent::vehicle_id`]), for their event streams.
    pub events: Topic,
}

fn topic(node: &mut Node, name: &str, qos: &QosProfile) -> Result<Topic, DdsError> {
    topic_in(node, &format!("{}/swarm", topics::NAMESPACE), name, qos)
}

fn topic_in(node: &mut Node, ns: &str, name: &str, qos: &QosProfile) -> Result<Topic, DdsError> {
    let t = node
        .create_topic(
            &Name::new(ns, name).map_err(|e| DdsError(format!("{name}: {e:?}")))?,
            SwarmMessage::type_name(),
            qos,
        )
        .map_err(err(name))?;
    Ok(Topic {
        writer: node.create_publisher(&t, None).map_err(err("publisher"))?,
        reader: Arc::new(
            node.create_subscription(&t, None)
                .map_err(err("subscription"))?,
        ),
    })
}

impl ProtocolTopics {
    /// Creates the topics on `node`.
    ///
    /// # Errors
    /// A topic, reader or writer could not be created.
    pub fn new(node: &mut Node) -> Result<ProtocolTopics, DdsError> {
        Ok(ProtocolTopics {
            report: topic(node, "report", &topics::protocol_stream())?,
            target: topic(node, "target", &topics::protocol_stream())?,
            command: topic(node, "command", &topics::protocol_commands())?,
            command_result: topic(node, "command_result", &topics::protocol_commands())?,
            events: topic(node, "events", &topics::protocol_commands())?,
            formation: topic_in(
                node,
                topics::NAMESPACE,
                "formation",
                &topics::formation_mirror(),
            )?,
        })
    }

    /// The topic that carries `msg`: slot targets go best-effort, the rest reliable.
    pub fn to_vehicle_topic(&self, msg: &ToVehicle) -> &Topic {
        match msg {
            ToVehicle::Slot { .. } => &self.target,
            _ => &self.command,
        }
    }
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

/// The next sample of `reader`, unwrapped; a sample that cannot be read is counted as
/// malformed, logged naming `what`, and skipped.
pub(crate) async fn receive(
    shared: &DdsShared,
    reader: &Subscription<SwarmMessage>,
    what: &str,
) -> Envelope {
    loop {
        match reader.async_take().await {
            Ok((m, _)) => return Envelope::from_msg(m),
            Err(e) => {
                shared.counters.malformed.fetch_add(1, Ordering::Relaxed);
                tracing::warn!("dds: a {what} sample was dropped: {e:?}");
            }
        }
    }
}

/// The body of `env` as `B`; one that does not parse is counted as malformed, logged
/// naming `what` and the vehicle, and dropped (`None`).
pub(crate) fn body_or_drop<B: for<'de> Deserialize<'de>>(
    shared: &DdsShared,
    env: &Envelope,
    what: &str,
) -> Option<B> {
    match env.body() {
        Ok(b) => Some(b),
        Err(e) => {
            shared.counters.malformed.fetch_add(1, Ordering::Relaxed);
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
