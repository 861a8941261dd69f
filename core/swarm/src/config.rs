//! Swarm-wide configuration: the vehicle models (the paper's UAV classes as profiles of
//! limits and payload slots) and the settings every vehicle and the coordinator fly by.
//! Plain data, set at start (`[swarm]`, `[models]`, `[supervision]`, `[hazards]` in the
//! config), never changed while the swarm flies (the geofence in force lives in the
//! [`crate::SwarmContext`]).

use crate::supervision::SupervisionConfig;
use serde::{Deserialize, Serialize};
use skein_model::geo::GeoPoint;
use skein_model::safety::{Geofence, MotionLimits};
use skein_payload::PayloadSpec;
use std::collections::BTreeMap;

/// A vehicle model: the paper's UAV classes as a named profile of limits and payload
/// slots (`generic` has none, `observation` a gimbal and a camera).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VehicleModel {
    /// Model name (`generic`, `observation`).
    pub name: String,
    /// Speed and acceleration limits every setpoint respects.
    pub limits: MotionLimits,
    /// Payload slots of every vehicle of this model.
    pub payloads: Vec<PayloadSpec>,
}

impl VehicleModel {
    /// The `generic` model: PX4 multicopter defaults, no payloads.
    pub fn generic() -> Self {
        VehicleModel {
            name: "generic".into(),
            limits: MotionLimits::default(),
            payloads: vec![],
        }
    }

    /// The `observation` model: a gimbal, a camera and a detector reading the camera's
    /// frames (the paper's ObservationUAVModel).
    pub fn observation() -> Self {
        let slot = |kind: &str| PayloadSpec {
            slot: kind.into(),
            kind: kind.into(),
            plugin: None,
            isolation: Default::default(),
            config: serde_json::Value::Object(Default::default()),
        };
        VehicleModel {
            name: "observation".into(),
            limits: MotionLimits::default(),
            payloads: vec![slot("gimbal"), slot("camera"), slot("detector")],
        }
    }
}

/// Swarm-wide settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SwarmConfig {
    /// Offboard setpoint stream rate per vehicle, Hz (PX4 needs > 2; 20–50 usual).
    pub stream_rate_hz: f64,
    /// Vehicle control loop rate (setpoint shaping, procedure checks), Hz.
    pub control_rate_hz: f64,
    /// Formation loop rate (slot targets), Hz.
    pub formation_rate_hz: f64,
    /// Anchor of the swarm frame; `None` = the home of the first vehicle heard.
    pub swarm_origin: Option<GeoPoint>,
    /// The geofence at start (the one in force is the context's,
    /// [`crate::SwarmContext::geofence`]: an operator may replace it).
    pub geofence: Geofence,
    /// Minimum distance between any two vehicles, metres: what skein guarantees.
    pub min_separation_m: f64,
    /// Extra distance kept between setpoints on top of `min_separation_m`, for the
    /// vehicles' tracking error (a position controller lags and cuts corners), metres.
    /// Formations need `spacing_m >= √2 · (min_separation_m + separation_margin_m)`
    /// (see [`crate::formation`]).
    pub separation_margin_m: f64,
    /// How many standard deviations of the members' position uncertainty a formation's
    /// spacing must allow for on top of separation and margin (each member's `eph_m`,
    /// its receiver's horizontal accuracy; the two largest combined). 1 by default; 0
    /// ignores the uncertainty. See [`crate::coordinator::validation`].
    pub position_uncertainty_sigmas: f64,
    /// Takeoff altitude when a command gives none, metres above home.
    pub default_takeoff_altitude_m: f64,
    /// Vehicle models by name.
    pub models: BTreeMap<String, VehicleModel>,
    /// What every vehicle's link configures at connect (telemetry rates, parameters).
    pub link_setup: skein_link::LinkSetup,
    /// Restart policies, escalation and the watchdog.
    pub supervision: SupervisionConfig,
    /// `POST /api/v1/faults` works only when this is set (`--enable-fault-injection`).
    pub fault_injection: bool,
    /// How lost vehicles are planned around (drift, radius cap, age-out, replan time).
    pub hazards: crate::formation::HazardConfig,
    /// Where mission plans are stored (`<dir>/<id>.json`); none: in memory only.
    pub missions_dir: Option<std::path::PathBuf>,
}

impl Default for SwarmConfig {
    fn default() -> Self {
        let mut models = BTreeMap::new();
        models.insert("generic".to_string(), VehicleModel::generic());
        models.insert("observation".to_string(), VehicleModel::observation());
        SwarmConfig {
            stream_rate_hz: 50.0,
            control_rate_hz: 50.0,
            formation_rate_hz: 10.0,
            swarm_origin: None,
            geofence: Geofence::default(),
            min_separation_m: 3.0,
            separation_margin_m: 0.5,
            position_uncertainty_sigmas: 1.0,
            default_takeoff_altitude_m: 10.0,
            models,
            link_setup: skein_link::LinkSetup::default(),
            supervision: SupervisionConfig::default(),
            fault_injection: false,
            hazards: crate::formation::HazardConfig::default(),
            missions_dir: None,
        }
    }
}

impl SwarmConfig {
    /// The distance setpoints keep from each other: separation plus tracking margin.
    pub fn setpoint_separation_m(&self) -> f64 {
        self.min_separation_m + self.separation_margin_m
    }

    /// The inner limit a member's setpoint keeps from the other members while the
    /// formation's transition plan separates them: separation plus half the margin.
    pub fn planned_separation_m(&self) -> f64 {
        self.min_separation_m + 0.5 * self.separation_margin_m
    }

    /// The smallest slot distance a formation may have: the transition plan keeps
    /// members `1/√2` of it apart, which must be the setpoint separation.
    pub fn min_slot_distance_m(&self) -> f64 {
        std::f64::consts::SQRT_2 * self.setpoint_separation_m()
    }

    /// The model called `name`, or `generic`.
    pub fn model(&self, name: &str) -> VehicleModel {
        self.models
            .get(name)
            .cloned()
            .unwrap_or_else(VehicleModel::generic)
    }
}
