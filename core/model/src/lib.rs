//! The pure model of a skein swarm: everything that can be decided without I/O.
//!
//! - [`geo`]: geodetic points, NED vectors and tangent-plane frames (the swarm frame and
//!   each vehicle's own local NED frame): the `skein-geo` crate, re-exported (it lives
//!   apart so the plugin SDK can share it without this crate's dependencies).
//! - [`px4`]: PX4 flight modes as carried in `HEARTBEAT.custom_mode`, landed states and
//!   `SET_POSITION_TARGET_LOCAL_NED` type masks.
//! - [`endpoint`]: `HOST:PORT` and serial `DEVICE:BAUD` in the operator's source strings.
//! - [`command`]: the operator's commands, one type for the API, the swarm protocol, DDS
//!   and (as [`command::CommandKind`]) the FSM.
//! - [`fsm`]: the vehicle state machine (GenericUAVModel) as a plain transition function.
//! - [`formation`]: formation shapes, slot offsets and optimal slot assignment.
//! - [`geofence`]: the cylinder (and optional polygon) every setpoint is clamped into.
//! - [`obstacles`]: the other vehicles as the separation check sees them, asked by
//!   distance.
//! - [`payload`]: a vehicle model's payload slot (slot, kind, plugin, hosting).
//! - [`preflight`]: a vehicle's pre-flight checks, from its snapshot.
//! - [`safety`]: the setpoint shaper: geofence clamp, speed and acceleration limiting and
//!   separation checks that every setpoint passes before it leaves skein.
//! - [`supervision`]: restart policies, child kinds and statuses, injectable faults.
//! - [`vehicle`]: the vehicle snapshot the API and dashboard show.
//!
//! Nothing in this crate blocks, allocates threads or touches a socket, so all of it is
//! unit- and property-tested directly.
#![warn(missing_docs)]

pub mod command;
pub mod endpoint;
pub mod formation;
pub mod fsm;
pub use skein_geo as geo;
pub mod geofence;
pub mod obstacles;
pub mod payload;
pub mod preflight;
pub mod px4;
pub mod safety;
pub mod supervision;
pub mod vehicle;
