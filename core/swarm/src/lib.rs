//! The swarm at run time: the actor tree of the design.
//!
//! ```text
//! Coordinator                root; registry; formation engine
//!  ├─ Api                    HTTP server (skein-api), supervised like the others
//!  ├─ Vehicle uav-1          FSM; owns what its setpoint stream carries
//!  │   ├─ Px4Link            MAVLink adapter (skein-link)
//!  │   └─ Payload <slot> …   plugin instances (gimbal, camera, radio)
//!  └─ Vehicle uav-2 …
//! ```
//!
//! - [`protocol`]: the swarm protocol between coordinator and vehicles (serde types; the
//!   `skein-protocol` crate, re-exported).
//! - [`carrier`]: the in-process carrier of the protocol.
//! - [`coordinator`]: the root actor, vehicle discovery, commands, formation loop.
//! - [`election`]: which coordinator candidate of a DDS domain is active (lease, failover).
//! - [`clocks`]: this process's clock against its peers', so that stamps from another
//!   host are aged right.
//! - [`link_security`]: who the swarm link proves is speaking (DDS Security), for the API.
//! - [`vehicle`]: the per-vehicle actor, its control loop and procedures.
//! - [`formation`]: the formation engine's state between ticks (the pure
//!   `skein-formation` crate, re-exported; the coordinator's formation loop ticks it).
//! - [`payload`]: payload actors (children of their Vehicle), built-in payloads.
//! - [`supervision`]: restart policies, failure records, the supervision tree.
//! - [`tracking`]: the task that runs the counter-UAS tracker (the pure `skein-tracking`
//!   crate, re-exported there) fusing the detectors' bearings into 3D tracks;
//!   [`tracks`]: the tracks as everyone else sees them (`skein_protocol::tracks`).
//! - [`metrics`]: Prometheus metrics.
//! - [`load`]: how late the process runs, what the watchdog forgives and what optional
//!   work yields when it is short of CPU.
//! - [`config`], [`services`], [`context`]: configuration, the process's services, and
//!   the swarm frame, given to every actor;
//! - [`neighbours`]: where every vehicle is, for the separation check (the coordinator
//!   owns the board, each vehicle writes its slot and reads the others').
//! - [`events`]: what the stream and dashboard are told.
//! - [`ticker`]: one clock per period for every actor's periodic messages, which never
//!   queue up behind an actor that is late.
//!
//! Actors never block in `handle`: link I/O runs in tasks that post results back as
//! messages; queries use `call` with a timeout.
#![warn(missing_docs)]

pub mod carrier;
pub mod clocks;
pub mod config;
pub mod context;
pub mod coordinator;
pub mod election;
pub mod events;
pub mod link_security;
pub mod load;
pub mod metrics;
pub mod neighbours;
pub mod payload;
pub mod services;
pub mod supervision;
pub mod ticker;
pub mod tracking;
pub mod vehicle;

pub use skein_formation as formation;
pub use skein_protocol as protocol;
pub use skein_protocol::tracks;

pub use config::{SwarmConfig, VehicleModel};
pub use context::SwarmContext;
pub use coordinator::{
    AdminMsg, CommandMsg, CommandOutcome, Coordinator, CoordinatorMsg, DistributedMsg,
    EndpointSpec, FaultError, FieldError, FleetMsg, FormationMsg, GeofenceMsg, PayloadMsg,
    RemoteVehicle, ServiceMsg, ServiceSpawner, ServiceSpec, Swarm, SwarmReads, TrackingMsg,
    VehicleSpec,
};
pub use events::SwarmEvent;
pub use formation::{FormationSpec, FormationStatus};
pub use protocol::{Command, CommandKind};
pub use services::{SimulatorControl, SwarmServices};
pub use vehicle::VehicleMsg;
