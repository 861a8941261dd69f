//! The contract between a vehicle and its payloads.
//!
//! A payload (gimbal, camera, radio, a team's own device) is a [`PayloadDriver`] that a
//! [`PayloadFactory`] creates per vehicle and slot. skein runs each driver inside a
//! supervised payload actor under its Vehicle actor: the actor calls
//! [`PayloadDriver::tick`] at the driver's rate, forwards operator commands (JSON from the
//! API) to [`PayloadDriver::handle`] and MAVLink from the vehicle's other components to
//! [`PayloadDriver::on_mavlink`]. The driver reaches the world only through the
//! [`PayloadHost`] it was given: its vehicle's state, the swarm, MAVLink to its vehicle,
//! events, its published state and video frames.
//!
//! Drivers come from the plugin host (a `cdylib` loaded in-process or in a child
//! process) or are built in (the fault fixture used by supervision tests). Nothing here
//! knows which.
#![warn(missing_docs)]

use serde::{Deserialize, Serialize};
use skein_mavlink::MavMessage;
pub use skein_model::payload::{Isolation, PayloadSpec};
use skein_model::vehicle::VehicleSnapshot;
use std::sync::Arc;

/// A payload's own state as it publishes it (JSON object, shown by the API and dashboard).
pub type PayloadState = serde_json::Value;

/// A simulated non-cooperative aircraft (an intruder of the simulator) as a simulated
/// vehicle's payloads may see it: what a simulated camera renders besides the swarm.
/// Serialised as the plugin SDK's `SimAircraft`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SimAircraft {
    /// Truth id (`"intruder-1"`), for evaluation only.
    pub id: String,
    /// North of the swarm origin, metres.
    pub north_m: f64,
    /// East of the swarm origin, metres.
    pub east_m: f64,
    /// Down from the swarm origin, metres.
    pub down_m: f64,
    /// Velocity, NED, m/s.
    pub velocity: skein_model::vehicle::Velocity,
    /// Rotor-tip to rotor-tip span, metres.
    pub span_m: f64,
}

/// What a vehicle offers its payloads. Every method is cheap and never blocks (they may
/// be called from the payload's tick at tens of Hz).
pub trait PayloadHost: Send + Sync {
    /// The vehicle's id (`"uav-1"`).
    fn vehicle_id(&self) -> &str;
    /// The vehicle's latest snapshot (position in the swarm frame, attitude, state).
    fn vehicle(&self) -> VehicleSnapshot;
    /// Every vehicle of the swarm (for cameras that render or gimbals that track others).
    fn swarm(&self) -> Vec<VehicleSnapshot>;
    /// True when the vehicle is simulated (payloads then simulate their device too).
    fn simulated(&self) -> bool;
    /// Sends a MAVLink message to the vehicle's system (target fields are the caller's
    /// business), from skein's identity on the vehicle's link.
    ///
    /// # Errors
    /// When the link cannot send (no address yet, socket full).
    fn send_mavlink(&self, msg: &MavMessage) -> Result<(), String>;
    /// Raises an event on the stream (`{"type": "payload_event", "kind": ..., "data": ...}`).
    fn emit_event(&self, kind: &str, data: serde_json::Value);
    /// Publishes the payload's state (replaces the previous one).
    fn publish_state(&self, state: PayloadState);
    /// The state another payload of the same vehicle published (a camera reads the
    /// gimbal's angles), if any.
    fn payload_state(&self, slot: &str) -> Option<PayloadState>;
    /// Publishes a video frame (JPEG bytes) for the vehicle's camera stream.
    fn publish_frame(&self, jpeg: Vec<u8>);
    /// Degrades (or restores) the simulated radio link of this vehicle: the fraction of
    /// datagrams lost (0..1) and the one-way latency added, ms. Only meaningful when
    /// [`PayloadHost::simulated`]; returns false when there is no simulator to tell.
    fn set_simulated_link(&self, loss_fraction: f64, latency_ms: f64) -> bool;
    /// The simulator's non-cooperative aircraft (swarm frame), when the vehicle is
    /// simulated and the simulator flies intruders; empty otherwise.
    fn sim_aircraft(&self) -> Vec<SimAircraft> {
        Vec::new()
    }
    /// The latest video frame (JPEG) the payload in `slot` of the same vehicle published,
    /// if any (a detector reads its camera's frames).
    fn payload_frame(&self, _slot: &str) -> Option<Arc<Vec<u8>>> {
        None
    }
}

/// A payload instance. Errors are strings shown to the operator as they are.
pub trait PayloadDriver: Send {
    /// Ticks per second the driver wants (0 = no ticks).
    fn tick_rate_hz(&self) -> f64;
    /// Periodic work (move the simulated gimbal, render a frame …); `dt_s` since the last
    /// tick.
    fn tick(&mut self, dt_s: f64) -> Result<(), String>;
    /// An operator command (the JSON body of `POST /api/v1/vehicles/{id}/payloads/{slot}`);
    /// the answer is returned to the caller.
    fn handle(&mut self, command: serde_json::Value) -> Result<serde_json::Value, String>;
    /// A MAVLink message from the vehicle's system (any component), e.g.
    /// `GIMBAL_DEVICE_ATTITUDE_STATUS`.
    fn on_mavlink(&mut self, _compid: u8, _msg: &MavMessage) -> Result<(), String> {
        Ok(())
    }
    /// Which library (and which build of it) runs this instance, for the payload listings;
    /// `None` when the factory does not say.
    fn served_by(&self) -> Option<ServedBy> {
        None
    }
}

/// The provider running a payload instance, as `GET /api/v1/vehicles/{id}/payloads` names
/// it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ServedBy {
    /// Plugin (library) name, or `"builtin"`.
    pub plugin: String,
    /// Its version.
    pub version: String,
    /// The library's generation the instance was created under (1 at the first load, +1
    /// per reload); 0 for a built-in payload.
    pub generation: u64,
}

/// What a factory knows about the payloads it can create (for `GET /api/v1/plugins`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProviderInfo {
    /// Plugin (or built-in) name.
    pub name: String,
    /// Its version.
    pub version: String,
    /// Payload kinds it provides.
    pub kinds: Vec<String>,
}

/// Creates payload drivers.
pub trait PayloadFactory: Send + Sync {
    /// Creates the driver for `spec` on a vehicle.
    ///
    /// # Errors
    /// No provider for the kind/plugin, or the plugin refused to create the instance; the
    /// message names which.
    fn create(
        &self,
        spec: &PayloadSpec,
        host: Arc<dyn PayloadHost>,
    ) -> Result<Box<dyn PayloadDriver>, String>;

    /// The providers this factory knows.
    fn providers(&self) -> Vec<ProviderInfo>;
}

/// A factory that creates nothing (no plugins configured).
pub struct NoPayloads;

impl PayloadFactory for NoPayloads {
    fn create(
        &self,
        spec: &PayloadSpec,
        _host: Arc<dyn PayloadHost>,
    ) -> Result<Box<dyn PayloadDriver>, String> {
        Err(format!(
            "no plugin provides payload kind `{}` (slot `{}`)",
            spec.kind, spec.slot
        ))
    }

    fn providers(&self) -> Vec<ProviderInfo> {
        Vec::new()
    }
}
