//! The swarm a plan is rehearsed with: its vehicles as they are now (where each stands,
//! its model's limits, its battery, whether it can observe), the geofence in force and
//! the separation the swarm keeps. The coordinator fills it in for
//! `POST /api/v1/missions/{id}/rehearse`; `skein mission rehearse` builds it from the
//! configuration and the simulated fleet.

use skein_model::geo::{GeoPoint, Ned};
use skein_model::geofence::Geofence;
use skein_model::safety::MotionLimits;

/// One vehicle of the rehearsed swarm.
#[derive(Debug, Clone, PartialEq)]
pub struct VehicleSetup {
    /// Vehicle id (`uav-1`).
    pub id: String,
    /// Its model's name (`generic`, `observation`).
    pub model: String,
    /// Where it stands (its takeoff point), swarm-frame NED metres (down 0: the swarm
    /// origin's height; a rehearsal starts every vehicle on the ground there).
    pub home: Ned,
    /// Its model's limits: every setpoint respects them.
    pub limits: MotionLimits,
    /// Battery now, percent (`None`: unknown, taken as full).
    pub battery_percent: Option<f64>,
    /// Its pack's capacity, mAh (PX4 `BAT1_CAPACITY`; `None`: unknown, the simulator's
    /// 5000 mAh).
    pub battery_capacity_mah: Option<f64>,
    /// It carries a gimbal: it can observe a track.
    pub observer: bool,
}

/// The swarm as a rehearsal flies it.
#[derive(Debug, Clone, PartialEq)]
pub struct SwarmSetup {
    /// The swarm frame's origin (geodetic): the rehearsal's simulated vehicles take off
    /// from their homes around it.
    pub origin: GeoPoint,
    /// Every vehicle, in id order.
    pub vehicles: Vec<VehicleSetup>,
    /// The geofence in force.
    pub fence: Geofence,
    /// The least distance between two vehicles, metres (`[swarm] min_separation_m`).
    pub min_separation_m: f64,
    /// What setpoints keep on top of it, metres (`[swarm] separation_margin_m`).
    pub separation_margin_m: f64,
    /// The control loop's rate, Hz (`[swarm] control_rate_hz`).
    pub control_rate_hz: f64,
    /// The formation loop's rate, Hz (`[swarm] formation_rate_hz`).
    pub formation_rate_hz: f64,
}

impl SwarmSetup {
    /// The distance setpoints keep from each other, metres (separation + margin).
    pub fn setpoint_separation_m(&self) -> f64 {
        self.min_separation_m + self.separation_margin_m
    }

    /// The inner limit between members flying a formation's transition plan, metres
    /// (separation + half the margin).
    pub fn planned_separation_m(&self) -> f64 {
        self.min_separation_m + 0.5 * self.separation_margin_m
    }

    /// The vehicle `id`.
    pub fn vehicle(&self, id: &str) -> Option<&VehicleSetup> {
        self.vehicles.iter().find(|v| v.id == id)
    }
}

/// What a rehearsal of a stored mission needs: its plan, each step's vehicles (its
/// groups resolved against the swarm now), and the swarm.
#[derive(Debug, Clone, PartialEq)]
pub struct RehearsalSetup {
    /// The plan.
    pub plan: crate::MissionPlan,
    /// Each step's vehicles, in step order ([`crate::resolve::groups`]).
    pub groups: Vec<Vec<String>>,
    /// The swarm as it is.
    pub swarm: SwarmSetup,
}

/// The members `vehicles` are to [`crate::resolve::groups`] (id and model of each).
pub fn members(vehicles: &[VehicleSetup]) -> Vec<crate::resolve::Member> {
    vehicles
        .iter()
        .map(|v| crate::resolve::Member {
            id: v.id.clone(),
            model: v.model.clone(),
        })
        .collect()
}
