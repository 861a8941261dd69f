//! `Px4Link`: how skein talks to PX4 autopilots over MAVLink 2.
//!
//! - [`address`]: connection strings (`udpin:`, `udpout:`, `tcpout:`, `serial:`).
//! - [`endpoint`]: one fixed socket per endpoint, frames demultiplexed by sysid, vehicles
//!   discovered from their first heartbeat, malformed input counted and dropped.
//! - [`telemetry`]: the latest state of a vehicle folded from PX4's streams.
//! - [`command`]: the command protocol's operations and errors.
//! - [`param_client`]: the parameter protocol (PX4's bytewise integers, duplicate answers).
//! - [`log_transfer`]: the log protocol (a vehicle's flight logs listed and downloaded);
//!   [`log_bandwidth`]: one byte-rate cap shared by every download.
//! - [`events`]: PX4's events decoded with the metadata the vehicle serves, its health
//!   and arming check report.
//! - [`ftp_client`]: MAVLink FTP, reading a file from the vehicle (its component
//!   metadata).
//! - [`mission`]: the mission protocol (upload and download of fence and rally plans).
//! - [`fence`], [`fence_sync`]: skein's geofence as PX4 mission items, and keeping every
//!   autopilot on it (uploaded, read back, `GF_ACTION` and `GF_MAX_VER_DIST` set).
//! - [`statustext`]: PX4's chunked `STATUSTEXT`s joined into whole texts.
//! - [`setup`]: what is configured at connect: telemetry rates, parameters.
//! - [`setpoint`]: the offboard setpoint streams, one clock per rate on a thread of their
//!   own, outliving actor restarts; [`priority`]: that thread's scheduling priority.
//! - [`corrections`]: GNSS corrections (RTCM3 as `GPS_RTCM_DATA`) to a vehicle under a
//!   rate cap.
//! - [`remote_id`]: the operator's part of each vehicle's Remote ID broadcast.
//! - [`px4link`]: the `Px4Link` actor tying these together per vehicle.
//! - [`fault`]: fault injection shared by every supervised actor.
//! - [`gcs`]: forwarding to a ground station (QGroundControl) and back, setpoints refused.
//!
//! PX4 facts honoured here (see the project's `px4.md`): PX4 locks onto the first sender,
//! so an endpoint never changes its socket; OFFBOARD needs a setpoint stream running for
//! more than a second; mode changes are confirmed from `HEARTBEAT.custom_mode`, not from
//! PX4's first ACK.
#![warn(missing_docs)]

pub mod address;
pub mod command;
pub mod corrections;
pub mod endpoint;
pub mod events;
pub mod fault;
pub mod fence;
pub mod fence_sync;
pub mod ftp_client;
pub mod gcs;
pub mod log_bandwidth;
pub mod log_transfer;
pub mod mission;
pub mod param_client;
pub mod priority;
pub mod px4link;
pub mod remote_id;
pub mod setpoint;
pub mod setup;
pub mod statustext;
pub mod telemetry;

pub use address::ConnectionAddress;
pub use command::{LinkCommand, LinkError};
pub use endpoint::{Discovery, Endpoint, Identity, SigningSpec};
pub use gcs::GcsForwarder;
pub use px4link::{EventSink, LinkEvent, Px4Link, Px4LinkArgs, Px4LinkMsg, VehicleLink};
pub use setpoint::{LocalSetpoint, SetpointStream};
pub use setup::{LinkSetup, TelemetryProfile};
pub use telemetry::Telemetry;
