//! What the process provides the swarm beyond its configuration: where payload drivers
//! come from, and the in-process simulator's controls when vehicles are simulated (the
//! binary implements [`SimulatorControl`]). Without a plugin host, [`SwarmServices`]'
//! default offers the built-in payloads ([`crate::payload::BuiltinPayloads`]).

use serde_json::Value;
use skein_model::geo::NedFrame;
use skein_payload::{PayloadFactory, SimAircraft};
use std::sync::Arc;

/// The in-process simulator as the swarm reaches it (implemented by the binary): the
/// simulated radio link's quality, the non-cooperative aircraft the simulated cameras
/// render, and the ground truth for evaluation.
pub trait SimulatorControl: Send + Sync {
    /// Sets the fraction of datagrams lost (0..1) and the one-way latency (ms) of the
    /// simulated vehicle `sysid`. Returns false when there is no such vehicle.
    fn set_link_quality(&self, sysid: u8, loss_fraction: f64, latency_ms: f64) -> bool;
    /// The simulator's intruders now, positions in `frame` (the swarm frame).
    fn intruders(&self, _frame: &NedFrame) -> Vec<SimAircraft> {
        Vec::new()
    }
    /// Ground truth of every simulated vehicle and intruder now, with swarm-frame
    /// positions when `frame` is known (`GET /api/v1/sim/truth`).
    fn truth(&self, _frame: Option<&NedFrame>) -> Value {
        Value::Null
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
