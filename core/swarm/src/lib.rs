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
//! - [`protocol`]: the swarm protocol between coordinator and vehicles (serde types).
//! - [`carrier`]: the in-process carrier of the protocol.
//! - [`coordinator`]: the root actor, vehicle discovery, commands, formation loop.
//! - [`election`]: which coordinator candidate of a DDS domain is active (lease, failover).
//! - [`vehicle`]: the per-vehicle actor, its control loop and procedures.
//! - [`formation`]: the formation engine's state between ticks.
//! - [`payload`]: payload actors, the vehicle side of the payload contract, built-ins.
//! - [`supervision`]: restart policies, failure records, the supervision tree.
//! - [`tracking`]: counter-UAS tracker fusing the detectors' bearings into 3D tracks.
//! - [`metrics`]: Prometheus metrics.
//! - [`view`]: configuration and the swarm frame shared by all vehicles.
//! - [`events`]: what the stream and dashboard are told.
//!
//! Actors never block in `handle`: link I/O runs in tasks that post results back as
//! messages; queries use `call` with a timeout.
#![warn(missing_docs)]

pub mod carrier;
pub mod coordinator;
pub mod election;
pub mod events;
pub mod formation;
pub mod metrics;
pub mod payload;
pub mod protocol;
pub mod supervision;
pub mod tracking;
pub mod vehicle;
pub mod view;

pub use coordinator::{
    CommandOutcome, Coordinator, CoordinatorMsg, DistributedMsg, EndpointSpec, FaultError,
    FieldError, RemoteVehicle, ServiceMsg, ServiceSpawner, ServiceSpec, Swarm, VehicleSpec,
};
pub use events::SwarmEvent;
pub use formation::{FormationSpec, FormationStatus};
pub use protocol::VehicleCommand;
pub use vehicle::VehicleMsg;
pub use view::{SwarmConfig, SwarmServices, VehicleModel};
