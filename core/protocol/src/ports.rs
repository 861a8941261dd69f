//! How either side hands a protocol message to whatever carries it: the coordinator
//! sends through a vehicle's [`VehiclePort`], a vehicle reports through its [`Uplink`].
//! The carriers (in-process, DDS) implement them in the runtime crates.

use crate::from_vehicle::FromVehicle;
use crate::to_vehicle::ToVehicle;
use std::sync::Arc;

/// Sends [`ToVehicle`] to one vehicle, whatever carries it.
pub trait VehiclePort: Send + Sync {
    /// Sends; `Err` names why the vehicle cannot be reached (not running, link down).
    fn send(&self, msg: ToVehicle) -> Result<(), String>;
}

/// Where a vehicle's [`FromVehicle`] messages go (a closure, so the vehicle does not
/// know who listens).
pub type Uplink = Arc<dyn Fn(FromVehicle) + Send + Sync>;
