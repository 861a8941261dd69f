//! Swarm-wide configuration and the shared view every vehicle reads: the swarm frame and
//! where the other vehicles are (for the separation check).

use crate::payload::{BuiltinPayloads, SimulatorControl};
use crate::supervision::SupervisionConfig;
use crate::vehicle::VehicleShared;
use serde::{Deserialize, Serialize};
use skein_model::geo::{GeoPoint, Ned, NedFrame};
use skein_model::safety::{Geofence, MotionLimits, Obstacle};
use skein_model::vehicle::VehicleSnapshot;
use skein_payload::{PayloadFactory, PayloadSpec};
use std::collections::{BTreeMap, HashMap};
use std::sync::{Arc, OnceLock, PoisonError, RwLock};

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
    /// Geofence every setpoint is clamped into.
    pub geofence: Geofence,
    /// Minimum distance between any two vehicles, metres: what skein guarantees.
    pub min_separation_m: f64,
    /// Extra distance kept between setpoints on top of `min_separation_m`, for the
    /// vehicles' tracking error (a position controller lags and cuts corners), metres.
    /// Formations need `spacing_m >= √2 · (min_separation_m + separation_margin_m)`
    /// (see [`crate::formation`]).
    pub separation_margin_m: f64,
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
            default_takeoff_altitude_m: 10.0,
            models,
            link_setup: skein_link::LinkSetup::default(),
            supervision: SupervisionConfig::default(),
            fault_injection: false,
            hazards: crate::formation::HazardConfig::default(),
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

/// What the process provides the swarm beyond its configuration.
#[derive(Clone)]
pub struct SwarmServices {
    /// Where payload drivers come from (plugins, built-ins).
    pub payloads: Arc<dyn PayloadFactory>,
    /// The in-process simulator, when vehicles are simulated.
    pub simulator: Option<Arc<dyn SimulatorControl>>,
}

impl Default for SwarmServices {
    fn default() -> Self {
        SwarmServices {
            payloads: Arc::new(BuiltinPayloads),
            simulator: None,
        }
    }
}

/// The places one vehicle takes up.
#[derive(Debug, Clone, Copy)]
struct Occupied {
    measured: Option<(Ned, Ned)>,
    setpoint: Option<(Ned, Ned)>,
    /// Flies a slot of the formation (on the transition plan).
    planned: bool,
}

/// What every vehicle and the coordinator share.
pub struct SwarmView {
    frame: OnceLock<NedFrame>,
    positions: RwLock<HashMap<String, Occupied>>,
    vehicles: RwLock<BTreeMap<String, Arc<VehicleShared>>>,
    /// The configuration the swarm runs with.
    pub config: SwarmConfig,
    /// Payload factory and simulator hooks.
    pub services: SwarmServices,
}

impl std::fmt::Debug for SwarmView {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SwarmView")
            .field("frame", &self.frame)
            .finish_non_exhaustive()
    }
}

impl SwarmView {
    /// A view with the configured origin (if any).
    pub fn new(config: SwarmConfig, services: SwarmServices) -> Self {
        let frame = OnceLock::new();
        if let Some(origin) = config.swarm_origin {
            let _ = frame.set(NedFrame::new(origin));
        }
        SwarmView {
            frame,
            positions: RwLock::new(HashMap::new()),
            vehicles: RwLock::new(BTreeMap::new()),
            config,
            services,
        }
    }

    /// Registers a vehicle (payloads read every vehicle's snapshot through the view).
    pub fn add_vehicle(&self, v: Arc<VehicleShared>) {
        self.vehicles
            .write()
            .unwrap_or_else(PoisonError::into_inner)
            .insert(v.id.clone(), v);
    }

    /// Every vehicle's latest snapshot, by id.
    pub fn snapshots(&self) -> Vec<VehicleSnapshot> {
        self.vehicles
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .values()
            .map(|v| v.snapshot())
            .collect()
    }

    /// The last published state of every payload of `kind` (e.g. `"detector"`), as
    /// `(vehicle id, slot, state)`, by vehicle then slot; payloads that published nothing
    /// yet are left out.
    pub fn payload_states(&self, kind: &str) -> Vec<(String, String, serde_json::Value)> {
        let vehicles: Vec<Arc<VehicleShared>> = self
            .vehicles
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .values()
            .cloned()
            .collect();
        let mut out = Vec::new();
        for v in vehicles {
            for (slot, p) in v.payloads().iter() {
                if p.spec.kind == kind
                    && let Some(state) = p.state()
                {
                    out.push((v.id.clone(), slot.clone(), state));
                }
            }
        }
        out
    }

    /// The in-process simulator's controls, if any.
    pub fn simulator(&self) -> Option<&Arc<dyn SimulatorControl>> {
        self.services.simulator.as_ref()
    }

    /// The swarm frame, once anchored.
    pub fn frame(&self) -> Option<NedFrame> {
        self.frame.get().copied()
    }

    /// Anchors the swarm frame at `origin` unless it is already anchored; returns the
    /// frame in force.
    pub fn anchor(&self, origin: GeoPoint) -> NedFrame {
        *self.frame.get_or_init(|| NedFrame::new(origin))
    }

    /// Records where vehicle `id` is (measured position and velocity) and where it is
    /// being sent (its setpoint position and velocity, when skein steers it), swarm frame;
    /// `planned` when it flies a slot of the formation (on its transition plan).
    pub fn set_position(
        &self,
        id: &str,
        measured: Option<(Ned, Ned)>,
        setpoint: Option<(Ned, Ned)>,
        planned: bool,
    ) {
        let mut positions = self
            .positions
            .write()
            .unwrap_or_else(PoisonError::into_inner);
        let occupied = Occupied {
            measured,
            setpoint,
            planned,
        };
        if measured.is_none() && setpoint.is_none() {
            positions.remove(id);
        } else if let Some(o) = positions.get_mut(id) {
            // The usual case, every control tick: no allocation for the key.
            *o = occupied;
        } else {
            positions.insert(id.to_string(), occupied);
        }
    }

    /// The points every vehicle except `id` occupies: its measured position and its
    /// setpoint. Separation is kept from both: setpoints against setpoints is what skein
    /// controls, positions cover vehicles it does not steer and controllers that lag.
    /// With `planned` (vehicle `id` flies a slot), the other members are marked
    /// [`Obstacle::planned`]: the formation's transition plan keeps them apart.
    pub fn others(&self, id: &str, planned: bool, out: &mut Vec<Obstacle>) {
        out.clear();
        let positions = self
            .positions
            .read()
            .unwrap_or_else(PoisonError::into_inner);
        for (_, o) in positions.iter().filter(|(k, _)| *k != id) {
            // A vehicle skein steers avoids too: each side takes half.
            let reciprocal = o.setpoint.is_some();
            for (position, velocity) in o.measured.into_iter().chain(o.setpoint) {
                out.push(Obstacle {
                    position,
                    velocity,
                    reciprocal,
                    planned: planned && o.planned,
                });
            }
        }
    }
}
