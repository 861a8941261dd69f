//! Counter-UAS tracking: the detections of every observation UAV fused into 3D tracks of
//! non-cooperative aircraft, their forecasts, the hostile swarms they fly in, and where
//! observers see a target best.
//!
//! - [`geometry`]: bearings and their least-squares fusion (triangulation);
//! - [`filter`]: the constant-velocity Kalman filter of each track (`nalgebra`);
//! - [`tracker`]: association (gated Hungarian) and update; `management`: track start,
//!   continuation through manoeuvres and blind spots, lifecycle, merging, stable ids;
//! - [`track`]: the tuning (the tracks as the API shows them, track events and counters
//!   are in the swarm protocol's [`skein_protocol::tracks`]);
//! - [`detection`]: the detector plugin's detections (its payload state) as bearings;
//! - [`forecast`]: where each track will be in 5, 10 and 20 s (constant velocity,
//!   constant turn, mean velocity; chosen by their recent residuals);
//! - [`swarms`]: confirmed tracks flying together grouped into hostile swarms (DBSCAN over
//!   position and velocity, stable `swarm-N` ids), their [`shape`]; [`picture`]: both
//!   over a tracker's tracks;
//! - [`target`]: a track or a swarm as a target to observe (its centre, its points now
//!   and ahead); [`stations`]: where observation UAVs see it best (triangulation
//!   geometry).
//!
//! A crate below the runtime, as `skein-model` is: no actor, no task, no I/O; every step
//! takes its time as an argument (wall-clock µs), so all of it is tested on made-up
//! clocks. The runtime (`skein_swarm::tracking::TrackingService`) steps a [`Tracker`] and
//! an [`AirPicture`] in a task of its own beside the coordinator, with the detector
//! payloads' frames and the swarm members' poses, and publishes what they return.
#![warn(missing_docs)]

pub mod detection;
pub mod filter;
pub mod forecast;
pub mod geometry;
mod management;
pub mod picture;
pub mod shape;
pub mod stations;
#[cfg(test)]
mod swarm_tests;
pub mod swarms;
pub mod target;
#[cfg(test)]
mod tests;
pub mod track;
pub mod tracker;

pub use picture::AirPicture;
pub use swarms::GroupingConfig;
pub use tracker::{MemberPose, Tracker, TrackerConfig};
