//! The DDS carrier of the swarm protocol (`skein_swarm::protocol`) between coordinators
//! and agents: the `/skein/swarm/*` topics ([`ProtocolTopics`]), the
//! `skein_msgs/SwarmMessage` envelope ([`Envelope`]), and the conversion of positions
//! between the swarm frames of two processes ([`Reframe`]).
//!
//! Every process anchors its swarm frame at its own origin (the `[swarm] origin` of its
//! config, else its first vehicle's home, or for a coordinator without vehicles the first
//! origin it hears). So each envelope carries its sender's origin, and the receiver
//! converts the body's positions into its own frame through geodetic coordinates.
//! Velocities are not rotated: the frames' axes differ by the convergence of meridians
//! over the distance between origins (10⁻⁵ rad for a kilometre), far below a velocity's
//! noise.

use crate::link::{DdsError, DdsShared, err};
use crate::msgs::{Header, RosMessage, SwarmMessage};
use crate::topics;
use ros2_client::builtin_interfaces::Time;
use ros2_client::{Name, Node, Publisher, QosProfile, Subscription};
use serde::{Deserialize, Serialize};
use skein_model::geo::{GeoPoint, Ned, NedFrame};
use skein_model::vehicle::{Position, VehicleSnapshot};
use skein_swarm::SwarmContext;
use skein_swarm::formation::{FormationMirror, LeaderMotion};
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

/// Converts positions from a sender's swarm frame to the receiver's.
#[derive(Debug, Clone, Copy)]
pub struct Reframe {
    from: NedFrame,
    to: NedFrame,
}

impl Reframe {
    /// From the sender's origin into `to`; `None` when the sender had no origin (then it
    /// sent no positions either) or both frames are the same.
    pub fn new(from: Option<GeoPoint>, to: NedFrame) -> Option<Reframe> {
        let from = from?;
        (from != to.origin).then(|| Reframe {
            from: NedFrame::new(from),
            to,
        })
    }

    /// A point.
    pub fn point(&self, p: Ned) -> Ned {
        self.from.convert_to(&self.to, p)
    }

    fn position(&self, p: Position) -> Position {
        let geo = GeoPoint::new(p.lat_deg, p.lon_deg, p.alt_amsl_m);
        Position::from_geo(geo, p.relative_alt_m, &self.to)
    }

    /// A report's position and target.
    pub fn report(&self, mut r: VehicleReport) -> VehicleReport {
        r.position = r.position.map(|p| self.point(p));
        r.target = r.target.map(|p| self.point(p));
        r
    }

    /// A snapshot's position, home and formation target.
    pub fn snapshot(&self, mut s: VehicleSnapshot) -> VehicleSnapshot {
        s.position = s.position.map(|p| self.position(p));
        s.home = s.home.map(|p| self.position(p));
        if let Some(f) = s.formation.as_mut() {
            f.target = self.point(f.target);
        }
        s
    }

    /// A formation mirror's reference point and the points of its motion.
    pub fn mirror(&self, mut m: FormationMirror) -> FormationMirror {
        m.reference.position = self.point(m.reference.position);
        match &mut m.reference.motion {
            LeaderMotion::Hold => {}
            LeaderMotion::GoTo { target, .. } => *target = self.point(*target),
            LeaderMotion::Waypoints { points, .. } => {
                points.iter_mut().for_each(|p| *p = self.point(*p));
            }
            LeaderMotion::Orbit { centre, .. } => *centre = self.point(*centre),
        }
        m
    }

    /// A coordinator's message's positions.
    pub fn to_vehicle(&self, mut msg: ToVehicle) -> ToVehicle {
        match &mut msg {
            ToVehicle::Slot {
                target: Some(target),
            } => {
                target.position = self.point(target.position);
                target.goal = self.point(target.goal);
            }
            ToVehicle::Command {
                command: skein_swarm::VehicleCommand::GoTo { target },
                ..
            } => *target = self.point(*target),
            _ => {}
        }
        msg
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

/// The conversion of a received envelope's positions into `view`'s swarm frame. A view
/// not anchored yet (a coordinator without vehicles of its own) is anchored at the
/// sender's origin.
pub fn into_view(view: &SwarmContext, origin: Option<GeoPoint>) -> Option<Reframe> {
    let frame = match (view.frame(), origin) {
        (Some(f), _) => f,
        (None, Some(o)) => view.anchor(o),
        (None, None) => return None,
    };
    Reframe::new(origin, frame)
}

/// Applies `reframe` when there is one.
pub fn reframed<T>(value: T, reframe: Option<&Reframe>, f: impl Fn(&Reframe, T) -> T) -> T {
    match reframe {
        Some(r) => f(r, value),
        None => value,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skein_model::fsm::VehicleState;
    use skein_swarm::protocol::SlotTarget;

    #[test]
    fn positions_move_between_frames_and_back() {
        let a = NedFrame::new(GeoPoint::new(47.397742, 8.545594, 488.0));
        // b's origin is 30 m north and 10 m east of a's.
        let b = NedFrame::new(a.to_geo(Ned::new(30.0, 10.0, 0.0)));
        let ab = Reframe::new(Some(a.origin), b).unwrap();
        let ba = Reframe::new(Some(b.origin), a).unwrap();
        let p = Ned::new(5.0, 5.0, -10.0);
        let q = ab.point(p);
        assert!(
            (q.north_m + 25.0).abs() < 0.01 && (q.east_m + 5.0).abs() < 0.01,
            "{q:?}"
        );
        assert!((q.down_m + 10.0).abs() < 0.01, "{q:?}");
        let back = ba.point(q);
        assert!((back - p).norm() < 1e-6, "{back:?}");
        assert!(Reframe::new(Some(a.origin), a).is_none());
        assert!(Reframe::new(None, a).is_none());

        let slot = ToVehicle::Slot {
            target: Some(SlotTarget {
                slot: 1,
                leader: false,
                position: p,
                goal: p,
                velocity: Ned::new(5.0, 0.0, 0.0),
                yaw_rad: 0.0,
                stamp_us: 1,
            }),
        };
        let ToVehicle::Slot { target: Some(t) } = ab.to_vehicle(slot) else {
            panic!("not a slot");
        };
        assert!((t.position - q).norm() < 1e-9 && (t.goal - q).norm() < 1e-9);
        assert_eq!(t.velocity, Ned::new(5.0, 0.0, 0.0));

        let mut r = VehicleReport::disconnected();
        r.state = VehicleState::Hovering;
        r.position = Some(p);
        assert!((ab.report(r).position.unwrap() - q).norm() < 1e-9);
    }

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
