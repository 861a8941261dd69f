//! A mission plan as the operator writes it (`POST /api/v1/missions`, a TOML file for
//! `skein mission`): named groups of vehicles, ordered steps for the whole swarm or a
//! group, and what an abort does. Positions are swarm-frame `[north_m, east_m]` pairs, as
//! the geofence takes them (a request may give a point as `{"lat_deg", "lon_deg"}`: it is
//! put into the swarm frame before the plan is read, see [`crate::geodetic`]); altitudes
//! are metres above the swarm origin, as a formation's.

use serde::{Deserialize, Serialize};
use skein_model::formation::Shape;
use std::collections::BTreeMap;
use utoipa::ToSchema;

/// A swarm-frame horizontal position, `[north_m, east_m]` (the geofence's).
pub use skein_model::geofence::polygon::Point;

/// A whole plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct MissionPlan {
    /// The plan's name (1 to 64 characters).
    pub name: String,
    /// Named groups the steps refer to (`"observers": {"model": "observation"}`).
    #[serde(default)]
    pub groups: BTreeMap<String, GroupSpec>,
    /// The steps, in order (at least one).
    pub steps: Vec<Step>,
    /// What every airborne vehicle does on an abort, after holding: `return` (default)
    /// or `land`.
    #[serde(default)]
    pub abort: AbortAction,
    /// What the swarm does by itself when something happens during a step.
    #[serde(default)]
    pub reactions: Reactions,
}

/// The plan's reactions.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Reactions {
    /// A vehicle running low during a survey, patrol, station or transit is replaced by a
    /// reserve (persistent coverage).
    #[serde(default)]
    pub low_battery: Option<LowBattery>,
    /// A confirmed track inside a zone is observed by vehicles of the step (gimbals on
    /// it, flown to observation stations) while the rest carry on.
    #[serde(default)]
    pub intruder: Option<IntruderReaction>,
}

/// The intruder reaction: during a step whose vehicles fly their own routes (survey,
/// patrol, station, transit without a formation), a confirmed track inside `zone` is
/// observed by the `observers` nearest vehicles of the step that carry a gimbal: their
/// gimbals follow it (the API's `observe`) and, with `stations`, they fly to the
/// stations that fix it best. The rest carry on. When the track is lost or gone (or the
/// step ends) they go back to their routes where they left them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct IntruderReaction {
    /// The zone, `[north_m, east_m]` vertices in order (at least 3, a simple polygon);
    /// absent: anywhere.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub zone: Option<Vec<[f64; 2]>>,
    /// Vehicles sent to observe each track (1 to 8; default 2).
    #[serde(default = "two_observers")]
    #[schema(minimum = 1, maximum = 8, default = 2)]
    pub observers: usize,
    /// Also fly them to observation stations (default true; needs two observers).
    #[serde(default = "yes")]
    #[schema(default = true)]
    pub stations: bool,
    /// The stations' least horizontal distance from the track, metres (10 to 60;
    /// absent: the coordinator's default, 25 m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(minimum = 10, maximum = 60)]
    pub standoff_m: Option<f64>,
}

fn two_observers() -> usize {
    2
}

fn yes() -> bool {
    true
}

/// The low-battery reaction: a vehicle of the step flown below `below_percent` is
/// replaced by the first idle (landed) reserve, which takes off, takes its place on the
/// route, and the low vehicle returns to launch; without a reserve left it returns all
/// the same (its survey lanes go to the others).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct LowBattery {
    /// Battery below which a vehicle is replaced, percent (21 to 99: above the plan's
    /// 20 % reserve).
    #[schema(minimum = 21, maximum = 99)]
    pub below_percent: f64,
    /// Vehicles kept on the ground to take over, in order (ids); none: the low vehicle
    /// returns and is not replaced.
    #[serde(default)]
    pub reserves: Vec<String>,
}

/// Who a group is: listed vehicles, or every vehicle of a model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct GroupSpec {
    /// Vehicle ids (`["uav-1", "uav-3"]`).
    #[serde(default)]
    pub vehicles: Vec<String>,
    /// Every vehicle of this model (`"observation"`).
    #[serde(default)]
    pub model: Option<String>,
}

/// What an abort does after every vehicle holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum AbortAction {
    /// Return to launch (PX4 RTL).
    #[default]
    Return,
    /// Land where each is.
    Land,
}

/// One step: what it does, and for whom.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Step {
    /// The group it is for (a name of `groups`); absent: every vehicle.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub group: Option<String>,
    /// What it does.
    #[serde(flatten)]
    pub kind: StepKind,
}

/// Every step kind, named by `kind`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum StepKind {
    /// Take off one vehicle after the other.
    Takeoff(Takeoff),
    /// Fly a route, in a formation (the whole swarm) or each vehicle keeping its place
    /// in the group.
    Transit(Transit),
    /// Sweep a polygon in parallel lanes, the lanes split among the group.
    Survey(Survey),
    /// Fly a closed route, the group spaced along it, for a time or until skipped.
    Patrol(Patrol),
    /// Hold points (one per vehicle) for a time.
    Station(Station),
    /// Return to launch, one vehicle after the other.
    Return(InTurn),
    /// Land where each is, one vehicle after the other.
    Land(InTurn),
}

impl StepKind {
    /// The kind's name (`"takeoff"`, `"survey"`, ...).
    pub fn name(&self) -> &'static str {
        match self {
            StepKind::Takeoff(_) => "takeoff",
            StepKind::Transit(_) => "transit",
            StepKind::Survey(_) => "survey",
            StepKind::Patrol(_) => "patrol",
            StepKind::Station(_) => "station",
            StepKind::Return(_) => "return",
            StepKind::Land(_) => "land",
        }
    }
}

fn two_s() -> f64 {
    2.0
}

/// `takeoff`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Takeoff {
    /// Altitude above each vehicle's home, metres.
    pub altitude_m: f64,
    /// Seconds between one vehicle's takeoff and the next's (0 to 60; default 2).
    #[serde(default = "two_s")]
    #[schema(minimum = 0, maximum = 60, default = 2)]
    pub interval_s: f64,
}

/// `return` and `land`: one vehicle after the other.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct InTurn {
    /// Seconds between one vehicle and the next (0 to 60; default 2).
    #[serde(default = "two_s")]
    #[schema(minimum = 0, maximum = 60, default = 2)]
    pub interval_s: f64,
}

/// A formation for a transit: the shape and spacing behind a virtual leader that flies
/// the route.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct TransitFormation {
    /// The shape (`line`, `wedge`, ...).
    pub shape: Shape,
    /// Distance between neighbouring slots, metres.
    pub spacing_m: f64,
}

/// `transit`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Transit {
    /// The route, `[north_m, east_m]` points (at least one).
    pub waypoints: Vec<[f64; 2]>,
    /// Altitude above the swarm origin, metres.
    pub altitude_m: f64,
    /// Ground speed along the route, m/s (the formation's leader; without a formation
    /// each vehicle flies at its model's speed limit).
    pub speed_m_s: f64,
    /// Fly it in this formation (the whole swarm only); absent: each vehicle keeps its
    /// offset from the group's centre.
    #[serde(default)]
    pub formation: Option<TransitFormation>,
}

/// A camera's footprint, from which survey lanes are spaced.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Camera {
    /// Horizontal field of view across the lane, degrees (1 to 170).
    pub hfov_deg: f64,
    /// Fraction of the footprint the next lane overlaps (0 to 0.9).
    pub overlap: f64,
}

impl Camera {
    /// The lane spacing at `height_m` above the ground: the footprint's width less the
    /// overlap, metres.
    pub fn lane_spacing_m(&self, height_m: f64) -> f64 {
        2.0 * height_m * (self.hfov_deg.to_radians() / 2.0).tan() * (1.0 - self.overlap)
    }
}

/// `survey`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Survey {
    /// The area, `[north_m, east_m]` vertices in order (at least 3, a simple polygon).
    pub polygon: Vec<[f64; 2]>,
    /// Altitude above the swarm origin, metres.
    pub altitude_m: f64,
    /// Distance between lanes, metres; absent: from `camera`.
    #[serde(default)]
    pub lane_spacing_m: Option<f64>,
    /// The camera whose footprint spaces the lanes (with `lane_spacing_m` absent).
    #[serde(default)]
    pub camera: Option<Camera>,
}

/// `patrol`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Patrol {
    /// The closed route, `[north_m, east_m]` points (at least 2; the last leads back to
    /// the first).
    pub route: Vec<[f64; 2]>,
    /// Altitude above the swarm origin, metres.
    pub altitude_m: f64,
    /// Seconds to patrol once every vehicle is on the route; absent: until skipped.
    #[serde(default)]
    pub duration_s: Option<f64>,
}

/// `station`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Station {
    /// The points, `[north_m, east_m]`, one per vehicle of the group, in id order.
    pub points: Vec<[f64; 2]>,
    /// Altitude above the swarm origin, metres.
    pub altitude_m: f64,
    /// Seconds to hold once every vehicle is on its point.
    pub duration_s: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_issues_minimum_contract_parses() {
        let plan: MissionPlan = serde_json::from_str(
            r#"{"name": "sortie", "steps": [
                {"kind": "takeoff", "altitude_m": 10},
                {"kind": "survey", "polygon": [[0, 0], [0, 40], [30, 40], [30, 0]],
                 "altitude_m": 20, "lane_spacing_m": 8},
                {"kind": "land"}]}"#,
        )
        .unwrap();
        assert_eq!(plan.steps.len(), 3);
        assert_eq!(plan.steps[0].group, None);
        assert_eq!(plan.steps[2].kind.name(), "land");
        let StepKind::Takeoff(t) = &plan.steps[0].kind else {
            panic!("{plan:?}")
        };
        assert_eq!(t.interval_s, 2.0);
        assert_eq!(plan.abort, AbortAction::Return);
    }

    #[test]
    fn unknown_kinds_and_fields_are_refused() {
        for bad in [
            r#"{"name": "x", "steps": [{"kind": "loiter"}]}"#,
            r#"{"name": "x", "steps": [{"kind": "land", "speed_m_s": 3}]}"#,
            r#"{"name": "x", "steps": [], "extra": 1}"#,
        ] {
            assert!(serde_json::from_str::<MissionPlan>(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn a_camera_spaces_lanes_by_its_footprint() {
        let c = Camera {
            hfov_deg: 90.0,
            overlap: 0.2,
        };
        // 90° at 20 m: a 40 m footprint, 32 m between lanes at 20 % overlap.
        assert!((c.lane_spacing_m(20.0) - 32.0).abs() < 1e-9);
    }
}
