//! The formation as the operator asks for it: its shape, spacing, leader, heading,
//! altitude and frame ([`FormationSpec`], [`FormationFrame`]), and how its reference
//! point is told to move ([`LeaderMotion`]). Plain data: the engine reads it each tick.

use serde::{Deserialize, Serialize};
use skein_model::formation::{Shape, custom_offsets, slot_offsets};
use skein_model::geo::Ned;
use skein_protocol::tracks::SWARM_PREFIX;

/// The name of the virtual leader in specs and status (`"leader": "virtual"`).
pub const VIRTUAL: &str = "virtual";

/// Leaders named `track-…` are tracks of the counter-UAS tracker.
pub const TRACK_PREFIX: &str = "track-";

/// How slot offsets are oriented.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum FormationFrame {
    /// Fixed in the swarm frame at `heading_deg`.
    #[default]
    World,
    /// Turning with the leader's heading.
    Leader,
}

/// A formation as the operator asks for it (`PUT /api/v1/formation`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct FormationSpec {
    /// The shape.
    pub shape: Shape,
    /// Distance between neighbouring slots, metres.
    pub spacing_m: f64,
    /// Leader: a vehicle id, [`VIRTUAL`], or `None` for the first member by id.
    pub leader: Option<String>,
    /// Formation heading, degrees clockwise from north (`world` frame).
    pub heading_deg: f64,
    /// Formation altitude above the swarm origin, metres; `None` = the leader's altitude.
    pub altitude_m: Option<f64>,
    /// How offsets are oriented.
    pub frame: FormationFrame,
    /// Follower offsets of a [`Shape::Custom`] formation (forward, right, down), metres.
    pub offsets: Vec<Ned>,
    /// With a track or a hostile swarm as leader (`"leader": "track-7"`, `"swarm-2"`): the
    /// horizontal distance the formation's reference point keeps from it, metres. `None`
    /// otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub standoff_m: Option<f64>,
}

impl FormationSpec {
    /// Slots the formation has for `n` members (custom: its offsets + the leader).
    pub fn capacity(&self, n: usize) -> usize {
        match self.shape {
            Shape::Custom => n.min(self.offsets.len() + 1),
            _ => n,
        }
    }

    /// The first `n` slot offsets (slot 0 is the leader's, at zero), pattern frame
    /// (forward, right, down), metres.
    pub(super) fn offsets(&self, n: usize) -> Vec<Ned> {
        match self.shape {
            Shape::Custom => custom_offsets(&self.offsets).into_iter().take(n).collect(),
            shape => slot_offsets(shape, n, self.spacing_m),
        }
    }

    /// True when the spec asks for the virtual leader (the operator's, or one that
    /// follows a track).
    pub(super) fn wants_virtual(&self) -> bool {
        self.leader.as_deref() == Some(VIRTUAL) || self.track_leader().is_some()
    }

    /// The track or hostile swarm the formation follows (`"leader": "track-7"`,
    /// `"swarm-2"`), if any: its virtual leader is then driven to keep `standoff_m` from
    /// it.
    pub fn track_leader(&self) -> Option<&str> {
        self.leader
            .as_deref()
            .filter(|l| l.starts_with(TRACK_PREFIX) || l.starts_with(SWARM_PREFIX))
    }
}

/// How the reference point moves.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(tag = "motion", rename_all = "snake_case")]
pub enum LeaderMotion {
    /// Stay where it is.
    Hold,
    /// Fly to a point.
    GoTo {
        /// Target, swarm-frame NED.
        target: Ned,
        /// Cruise speed, m/s.
        speed_m_s: f64,
    },
    /// Fly a list of points in order.
    Waypoints {
        /// The points, swarm-frame NED.
        points: Vec<Ned>,
        /// Cruise speed, m/s.
        speed_m_s: f64,
        /// Index of the point being flown to.
        next: usize,
        /// Start over after the last point.
        repeat: bool,
    },
    /// Circle a point.
    Orbit {
        /// Centre, swarm-frame NED (its `down_m` is the orbit altitude).
        centre: Ned,
        /// Radius, metres.
        radius_m: f64,
        /// Speed along the circle, m/s.
        speed_m_s: f64,
        /// Clockwise seen from above.
        clockwise: bool,
    },
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// A line of 5 m spacing led by `uav-2`, world frame, heading north.
    pub(crate) fn line() -> FormationSpec {
        FormationSpec {
            shape: Shape::Line,
            spacing_m: 5.0,
            leader: Some("uav-2".into()),
            heading_deg: 0.0,
            altitude_m: None,
            frame: FormationFrame::World,
            offsets: vec![],
            standoff_m: None,
        }
    }

    fn custom(followers: usize) -> FormationSpec {
        FormationSpec {
            shape: Shape::Custom,
            offsets: (1..=followers)
                .map(|k| Ned::new(-4.0 * k as f64, 0.0, 0.0))
                .collect(),
            ..line()
        }
    }

    #[test]
    fn capacity_is_every_member_except_for_custom_shapes() {
        assert_eq!(line().capacity(0), 0);
        assert_eq!(line().capacity(7), 7);
        // Custom: the leader's slot plus one per offset.
        assert_eq!(custom(2).capacity(1), 1);
        assert_eq!(custom(2).capacity(3), 3);
        assert_eq!(custom(2).capacity(10), 3);
        assert_eq!(custom(0).capacity(4), 1);
    }

    #[test]
    fn offsets_start_at_the_leaders_slot() {
        let line = line().offsets(3);
        assert_eq!(line.len(), 3);
        assert_eq!(line[0], Ned::ZERO);
        // Neighbours on alternating sides at the spacing: right, then left.
        assert_eq!(line[1], Ned::new(0.0, 5.0, 0.0));
        assert_eq!(line[2], Ned::new(0.0, -5.0, 0.0));
        let custom = custom(3).offsets(3);
        assert_eq!(
            custom,
            vec![
                Ned::ZERO,
                Ned::new(-4.0, 0.0, 0.0),
                Ned::new(-8.0, 0.0, 0.0)
            ]
        );
    }

    #[test]
    fn only_the_virtual_name_asks_for_the_virtual_leader() {
        assert!(!line().wants_virtual());
        let mut s = line();
        s.leader = None;
        assert!(!s.wants_virtual());
        s.leader = Some(VIRTUAL.into());
        assert!(s.wants_virtual());
        assert_eq!(FormationFrame::default(), FormationFrame::World);
    }
}
