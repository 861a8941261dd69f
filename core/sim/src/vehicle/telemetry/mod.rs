//! PX4's onboard-link telemetry: [`scheduler`] holds the stream table (rates per profile)
//! and the per-vehicle scheduler that `MAV_CMD_SET_MESSAGE_INTERVAL` changes at run time;
//! [`messages`] builds every message from the vehicle state, the sensors' in [`sensors`].

mod messages;
mod scheduler;
mod sensors;

pub(crate) use messages::quaternion;
pub use scheduler::{STREAMS, Stream, Streams, is_known_message};

/// `AUTOPILOT_VERSION` message id.
pub const AUTOPILOT_VERSION_ID: u32 = 148;
/// `HOME_POSITION` message id.
pub const HOME_POSITION_ID: u32 = 242;
/// `COMPONENT_METADATA` message id (sent on request only).
pub const COMPONENT_METADATA_ID: u32 = 397;
/// `PROTOCOL_VERSION` message id.
pub const PROTOCOL_VERSION_ID: u32 = 300;
/// `flight_sw_version` of PX4 v1.16.0 (major, minor, patch, FIRMWARE_VERSION_TYPE_OFFICIAL).
pub const PX4_FLIGHT_SW_VERSION: u32 = (1 << 24) | (16 << 16) | 0xFF;
