//! The swarm protocol: everything a coordinator and a vehicle say to each other, as plain
//! serde types, and the counter-UAS tracks and hostile swarms as everyone sees them.
//!
//! The coordinator never holds a vehicle's actor: it sends [`ToVehicle`] through a
//! [`VehiclePort`] and hears [`FromVehicle`] through an [`Uplink`], plus the latest
//! [`VehicleReport`] (keep-last, like a best-effort DDS topic of depth 1). Two carriers
//! carry the same types: in-process messages (`skein_swarm::carrier`) in `skein up`, and
//! DDS between an agent and its coordinators (`skein_dds`).
//!
//! One file per direction or concept:
//! - `to_vehicle`: coordinator → vehicle ([`ToVehicle`], its formation [`SlotTarget`]);
//! - `from_vehicle`: vehicle → coordinator, events and answers ([`FromVehicle`],
//!   [`PayloadCommandError`]);
//! - `report`: the vehicle's keep-last state for the formation engine ([`VehicleReport`]);
//! - `ports`: how either side hands a message to its carrier ([`VehiclePort`], [`Uplink`]);
//! - `stamp`: time on the wire ([`wall_us`], [`age_of`]) and how far a stamped position
//!   is moved on by its age;
//! - [`tracks`]: the counter-UAS tracks and hostile swarms as the API, the stream, the
//!   metrics and DDS show them (the tracker, `skein_tracking`, makes them).
//!
//! Time on the wire is wall-clock microseconds since the Unix epoch ([`wall_us`]): a slot
//! target carries the instant it was computed and its velocity, so the vehicle side moves
//! it on by its age. Between hosts, the receiving carrier first converts a stamp into its
//! own clock (`skein_swarm::clocks`: offsets estimated from clock exchanges); a negative
//! age counts as zero, and the extrapolation is capped.
//!
//! Nothing here runs: no actor, no task, no socket (the crate depends on `skein-model`
//! only, besides serde), so both carriers and the pure crates below the runtime
//! (`skein-formation`, `skein-tracking`) share it.
#![warn(missing_docs)]

mod from_vehicle;
mod ports;
mod report;
mod stamp;
mod to_vehicle;
pub mod tracks;

pub use from_vehicle::{FromVehicle, PayloadCommandError};
pub use ports::{Uplink, VehiclePort};
pub use report::VehicleReport;
pub use skein_model::command::{Command, CommandKind};
pub use stamp::{
    REPORT_EXTRAPOLATION, TARGET_EXTRAPOLATION, age_of, extrapolate_target, skew_wall_clock,
    wall_us,
};
pub use to_vehicle::{SlotTarget, ToVehicle};
