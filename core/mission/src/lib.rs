//! Missions: what the swarm flies on its own. A [`plan::MissionPlan`] is ordered steps
//! (take off in turn, transit, survey a polygon in lanes, patrol a route, hold stations,
//! return, land in turn) for the whole swarm or named groups; it is checked against the
//! geofence and the separation the swarm keeps before it is stored ([`validate`]), its
//! groups resolved to vehicles and its energy checked at start ([`resolve`],
//! [`energy`]), and flown by a [`run::MissionRun`]: a state machine that, given the
//! vehicles' states on each tick, says what to command. Pure: no actor, no I/O; the
//! coordinator runs it on the live swarm.
//!
//! - [`plan`]: the plan's types (the API's body, a TOML file).
//! - [`geodetic`]: latitude/longitude points put into the swarm frame before a plan is read.
//! - [`lanes`]: a survey's lanes and their split among the vehicles.
//! - [`validate`]: the plan's checks, each refusal naming its step and field.
//! - [`resolve`]: groups to vehicle ids, at start.
//! - [`energy`]: the battery a plan takes per vehicle, against what each has.
//! - [`consumption`]: each vehicle's consumption, measured in flight.
//! - [`run`]: the run: steps, progress, pause, resume, abort, skip.
//! - [`swarm`]: the swarm a plan is rehearsed with.
#![warn(missing_docs)]

pub mod consumption;
pub mod energy;
pub mod geodetic;
pub mod lanes;
pub mod plan;
pub mod resolve;
pub mod run;
pub mod swarm;
pub mod validate;

pub use plan::MissionPlan;
pub use run::{Action, MissionRun, RunState, RunStatus, Tick, TrackSeen, VehicleView};
pub use validate::{Limits, PlanError};
