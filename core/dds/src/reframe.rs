//! The conversion of positions between the swarm frames of two processes ([`Reframe`]).
//!
//! Every process anchors its swarm frame at its own origin (the `[swarm] origin` of its
//! config, else its first vehicle's home, or for a coordinator without vehicles the first
//! origin it hears). So each envelope carries its sender's origin
//! ([`crate::envelope::Envelope::origin`]), and the receiver converts the body's positions
//! into its own frame through geodetic coordinates. Velocities are not rotated: the
//! frames' axes differ by the convergence of meridians over the distance between origins
//! (10⁻⁵ rad for a kilometre), far below a velocity's noise.
//!
//! The roles find this process's frame through a [`FrameSource`] ([`SwarmFrame`]): the
//! coordinator's in skein ([`crate::swarm_adapter`]), an [`AnchoredFrame`] in the unit
//! tests.

use skein_model::geo::{GeoPoint, Ned, NedFrame};
use skein_model::vehicle::{Position, VehicleSnapshot};
use skein_swarm::formation::{FormationMirror, LeaderMotion};
use skein_swarm::protocol::{ToVehicle, VehicleReport};
use std::future::Future;
use std::sync::{Arc, OnceLock};

/// This process's swarm frame: NED about its origin, anchored once.
pub trait SwarmFrame: Send + Sync {
    /// The frame, once anchored.
    fn frame(&self) -> Option<NedFrame>;

    /// Anchors the frame at `origin` unless it is already anchored; the frame in force.
    fn anchor(&self, origin: GeoPoint) -> NedFrame;
}

/// Where a role finds this process's [`SwarmFrame`].
pub trait FrameSource: Send + Sync + 'static {
    /// The frame; `None` when it cannot be had (the coordinator does not answer).
    fn swarm_frame(&self) -> impl Future<Output = Option<Arc<dyn SwarmFrame>>> + Send;
}

/// A [`SwarmFrame`] anchored at a given origin, or at the first one it is asked to.
#[derive(Debug, Default)]
pub struct AnchoredFrame(OnceLock<NedFrame>);

impl AnchoredFrame {
    /// A frame about `origin`; `None`: not anchored until [`SwarmFrame::anchor`].
    pub fn new(origin: Option<GeoPoint>) -> Self {
        let cell = OnceLock::new();
        if let Some(o) = origin {
            let _ = cell.set(NedFrame::new(o));
        }
        AnchoredFrame(cell)
    }
}

impl SwarmFrame for AnchoredFrame {
    fn frame(&self) -> Option<NedFrame> {
        self.0.get().copied()
    }

    fn anchor(&self, origin: GeoPoint) -> NedFrame {
        *self.0.get_or_init(|| NedFrame::new(origin))
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
                command: skein_swarm::Command::GoTo(goto),
                ..
            } => *goto = self.point(goto.target()).into(),
            _ => {}
        }
        msg
    }
}

/// The conversion of a received envelope's positions into this process's `frame`. A
/// frame not anchored yet (a coordinator without vehicles of its own) is anchored at the
/// sender's origin.
pub fn into_frame(frame: &dyn SwarmFrame, origin: Option<GeoPoint>) -> Option<Reframe> {
    let frame = match (frame.frame(), origin) {
        (Some(f), _) => f,
        (None, Some(o)) => frame.anchor(o),
        (None, None) => return None,
    };
    Reframe::new(origin, frame)
}

/// What a conversion between frames must leave finite: every position of a received
/// body.
pub trait Positions {
    /// Whether every position is finite.
    fn positions_finite(&self) -> bool;
}

fn finite(p: &Ned) -> bool {
    p.north_m.is_finite() && p.east_m.is_finite() && p.down_m.is_finite()
}

impl Positions for VehicleReport {
    fn positions_finite(&self) -> bool {
        self.position.iter().chain(&self.target).all(finite)
    }
}

impl Positions for VehicleSnapshot {
    fn positions_finite(&self) -> bool {
        let geo = |p: &Position| p.lat_deg.is_finite() && p.lon_deg.is_finite();
        self.position.iter().chain(&self.home).all(geo)
            && self.formation.as_ref().is_none_or(|f| finite(&f.target))
    }
}

impl Positions for FormationMirror {
    fn positions_finite(&self) -> bool {
        finite(&self.reference.position)
            && match &self.reference.motion {
                LeaderMotion::Hold => true,
                LeaderMotion::GoTo { target, .. } => finite(target),
                LeaderMotion::Waypoints { points, .. } => points.iter().all(finite),
                LeaderMotion::Orbit { centre, .. } => finite(centre),
            }
    }
}

impl Positions for skein_swarm::coordinator::missions::MissionMirror {
    fn positions_finite(&self) -> bool {
        self.run.positions_finite()
    }
}

impl Positions for ToVehicle {
    fn positions_finite(&self) -> bool {
        match self {
            ToVehicle::Slot {
                target: Some(target),
            } => finite(&target.position) && finite(&target.goal),
            ToVehicle::Command {
                command: skein_swarm::Command::GoTo(goto),
                ..
            } => finite(&goto.target()),
            _ => true,
        }
    }
}

/// Applies `reframe` when there is one. `None` when a position is not finite after it: a
/// body's positions are finite (JSON has no NaN), but one absurdly far from its origin
/// (1e300 m north) is no point in another frame; the caller drops such a sample.
pub fn reframed<T: Positions>(
    value: T,
    reframe: Option<&Reframe>,
    f: impl Fn(&Reframe, T) -> T,
) -> Option<T> {
    let value = match reframe {
        Some(r) => f(r, value),
        None => value,
    };
    value.positions_finite().then_some(value)
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
    fn a_position_that_is_no_point_in_the_other_frame_is_refused() {
        let a = NedFrame::new(GeoPoint::new(47.397742, 8.545594, 488.0));
        let b = NedFrame::new(a.to_geo(Ned::new(30.0, 10.0, 0.0)));
        let ab = Reframe::new(Some(a.origin), b);
        let mut r = VehicleReport::disconnected();
        r.position = Some(Ned::new(1e300, 0.0, -10.0));
        // The same frame: nothing to convert, the vehicle's own checks see it.
        assert!(reframed(r, None, |r, x| r.report(x)).is_some());
        assert!(reframed(r, ab.as_ref(), |r, x| r.report(x)).is_none());
        r.position = Some(Ned::new(5.0, 0.0, -10.0));
        assert!(reframed(r, ab.as_ref(), |r, x| r.report(x)).is_some());
    }
}
