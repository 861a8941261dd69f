//! The messages on skein's DDS topics, as serde types in field order: RustDDS writes
//! them as CDR (XCDR1, little-endian) exactly as a ROS 2 node generated from the `.msg`
//! files would.
//!
//! - ROS 2 standard messages skein publishes: `std_msgs/Header`,
//!   `geometry_msgs/{Point, Vector3, Quaternion, Pose, PoseStamped, Transform,
//!   TransformStamped}`, `sensor_msgs/{NavSatStatus, NavSatFix, BatteryState}`,
//!   `tf2_msgs/TFMessage` (Jazzy definitions), and `rtcm_msgs/Message` (RTK corrections,
//!   the type ROS 2's `ntrip_client` publishes; its definition is carried in
//!   `tests/peers/ros2/rtcm_msgs/`).
//! - skein's own messages (`skein_msgs/*`), defined by the `.msg` files of the ROS 2
//!   interface package `ros2/skein_msgs/msg/`: [`VehicleState`], [`Command`],
//!   [`CommandResult`], [`Track`], [`Tracks`], [`CoordinatorLease`], [`SwarmMessage`]. A
//!   field added there is added here at the same place: a unit test reads those files
//!   and checks every type here against them (`msg_files`), and `tests/e2e_ros2.rs`
//!   compares [`to_cdr`]'s bytes with the rosidl-generated Python types'.
//!
//! Fixed-size arrays (`float64[9]`) are Rust arrays (CDR writes no length); sequences
//! (`float32[]`, `Track[]`) are `Vec`s (CDR writes a `u32` length first).

use ros2_client::MessageTypeName;
use ros2_client::builtin_interfaces::Time;
use ros2_client::dds::rustdds::no_key::{DeserializerAdapter, SerializerAdapter};
use ros2_client::dds::rustdds::{
    CDRDeserializerAdapter, CDRSerializerAdapter, RepresentationIdentifier,
};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

/// `m` as DDS puts it on the wire: CDR, little-endian (XCDR1), without the 4-byte
/// encapsulation header (`00 01 00 00`) that precedes it in a sample; padding is zeros.
///
/// # Errors
/// `m` cannot be written as CDR (a map or an enum with data: none of the messages here).
pub fn to_cdr<M: Serialize>(m: &M) -> Result<Vec<u8>, String> {
    <CDRSerializerAdapter<M> as SerializerAdapter<M>>::to_bytes(m)
        .map(|b| b.to_vec())
        .map_err(|e| e.to_string())
}

/// A sample's payload (CDR, little-endian, without the encapsulation header) as an `M`,
/// decoded as RustDDS decodes every sample for skein's readers (`CDRDeserializerAdapter`,
/// the adapter ros2-client's subscriptions read with). The inverse of [`to_cdr`].
///
/// # Errors
/// The bytes are no `M` (too short, a string that is not UTF-8 or not terminated, …).
pub fn from_cdr<M: DeserializeOwned>(bytes: &[u8]) -> Result<M, String> {
    <CDRDeserializerAdapter<M> as DeserializerAdapter<M>>::from_bytes(
        bytes,
        RepresentationIdentifier::CDR_LE,
    )
    .map_err(|e| e.to_string())
}

/// A ROS message type with its `package/Type` name.
pub trait RosMessage: Serialize + 'static {
    /// `(package, type)`, e.g. `("geometry_msgs", "PoseStamped")`; the DDS type name is
    /// `geometry_msgs::msg::dds_::PoseStamped_`.
    const TYPE: (&'static str, &'static str);

    /// The type name ros2-client puts on the topic.
    fn type_name() -> MessageTypeName {
        MessageTypeName::new(Self::TYPE.0, Self::TYPE.1)
    }
}

/// `std_msgs/Header`: stamp and coordinate frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// When the data was valid (wall clock, `builtin_interfaces/Time`).
    pub stamp: Time,
    /// Frame of the data: [`crate::FRAME_ID`] for skein's swarm frame.
    pub frame_id: String,
}

/// `geometry_msgs/Point`, metres.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Point {
    /// x (ENU: east), metres.
    pub x: f64,
    /// y (ENU: north), metres.
    pub y: f64,
    /// z (ENU: up), metres.
    pub z: f64,
}

/// `geometry_msgs/Vector3`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Vector3 {
    /// x (ENU: east).
    pub x: f64,
    /// y (ENU: north).
    pub y: f64,
    /// z (ENU: up).
    pub z: f64,
}

/// `geometry_msgs/Quaternion` (x, y, z, w).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

/// `geometry_msgs/Pose`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Position, metres.
    pub position: Point,
    /// Orientation of the body (FLU per REP 103) in the frame.
    pub orientation: Quaternion,
}

/// `geometry_msgs/PoseStamped`: `/skein/<vehicle>/pose`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoseStamped {
    /// Stamp and frame ([`crate::FRAME_ID`], ENU).
    pub header: Header,
    /// The pose.
    pub pose: Pose,
}

impl RosMessage for PoseStamped {
    const TYPE: (&'static str, &'static str) = ("geometry_msgs", "PoseStamped");
}

/// `sensor_msgs/NavSatStatus`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NavSatStatus {
    /// `STATUS_NO_FIX` (-1) or `STATUS_FIX` (0).
    pub status: i8,
    /// `SERVICE_GPS` (1).
    pub service: u16,
}

/// `sensor_msgs/NavSatFix`: `/skein/<vehicle>/navsat`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NavSatFix {
    /// Stamp; frame_id is the vehicle id.
    pub header: Header,
    /// Fix status.
    pub status: NavSatStatus,
    /// Latitude, degrees (WGS 84).
    pub latitude: f64,
    /// Longitude, degrees (WGS 84).
    pub longitude: f64,
    /// Altitude, metres above mean sea level (PX4's `GLOBAL_POSITION_INT.alt`).
    pub altitude: f64,
    /// Row-major ENU covariance, m² (unknown: zeros with type 0).
    pub position_covariance: [f64; 9],
    /// `COVARIANCE_TYPE_UNKNOWN` (0).
    pub position_covariance_type: u8,
}

impl RosMessage for NavSatFix {
    const TYPE: (&'static str, &'static str) = ("sensor_msgs", "NavSatFix");
}

/// `sensor_msgs/BatteryState` (Jazzy): `/skein/<vehicle>/battery`. Unmeasured
/// quantities are NaN, as the message's definition asks.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BatteryState {
    /// Stamp; frame_id is the vehicle id.
    pub header: Header,
    /// Pack voltage, volts.
    pub voltage: f32,
    /// Temperature, °C (NaN).
    pub temperature: f32,
    /// Current, A, negative when discharging (NaN).
    pub current: f32,
    /// Charge, Ah (NaN).
    pub charge: f32,
    /// Capacity, Ah (NaN).
    pub capacity: f32,
    /// Design capacity, Ah (NaN).
    pub design_capacity: f32,
    /// Charge remaining, 0 to 1.
    pub percentage: f32,
    /// `POWER_SUPPLY_STATUS_DISCHARGING` (2).
    pub power_supply_status: u8,
    /// `POWER_SUPPLY_HEALTH_UNKNOWN` (0).
    pub power_supply_health: u8,
    /// `POWER_SUPPLY_TECHNOLOGY_UNKNOWN` (0).
    pub power_supply_technology: u8,
    /// True: the battery is there.
    pub present: bool,
    /// Cell voltages, volts (empty: not reported).
    pub cell_voltage: Vec<f32>,
    /// Cell temperatures, °C (empty).
    pub cell_temperature: Vec<f32>,
    /// Where the battery is (empty).
    pub location: String,
    /// Serial number (empty).
    pub serial_number: String,
}

impl RosMessage for BatteryState {
    const TYPE: (&'static str, &'static str) = ("sensor_msgs", "BatteryState");
}

/// `skein_msgs/VehicleState` (`msg/VehicleState.msg`): `/skein/<vehicle>/state`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VehicleState {
    /// Stamp and frame.
    pub header: Header,
    /// Vehicle id (`"uav-1"`).
    pub id: String,
    /// MAVLink system id.
    pub sysid: u8,
    /// Model name.
    pub model: String,
    /// skein FSM state (`"Hovering"`).
    pub state: String,
    /// PX4 mode (`"OFFBOARD"`).
    pub px4_mode: String,
    /// Armed flag.
    pub armed: bool,
    /// MAVLink link up.
    pub link_connected: bool,
    /// Formation slot, -1 when none.
    pub slot: i32,
    /// Leader slot.
    pub leader: bool,
}

impl RosMessage for VehicleState {
    const TYPE: (&'static str, &'static str) = ("skein_msgs", "VehicleState");
}

/// `skein_msgs/Command` (`msg/Command.msg`): `/skein/<vehicle>/command`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Command {
    /// Who sends it (logged).
    pub source: String,
    /// The sender's id for it, echoed in the [`CommandResult`].
    pub request_id: u64,
    /// Command name as the API spells it (`"takeoff"`).
    pub command: String,
    /// Takeoff altitude above home, metres; NaN = the configured default.
    pub altitude_m: f64,
    /// Disarm: emergency.
    pub force: bool,
    /// Goto: swarm-frame ENU metres.
    pub target: Point,
}

impl RosMessage for Command {
    const TYPE: (&'static str, &'static str) = ("skein_msgs", "Command");
}

/// `skein_msgs/CommandResult` (`msg/CommandResult.msg`):
/// `/skein/<vehicle>/command_result`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CommandResult {
    /// The command's `request_id`.
    pub request_id: u64,
    /// skein's command id; 0 when refused before reaching the vehicle.
    pub command_id: u64,
    /// Taken by the vehicle's FSM.
    pub accepted: bool,
    /// Why not; empty when accepted.
    pub reason: String,
}

impl RosMessage for CommandResult {
    const TYPE: (&'static str, &'static str) = ("skein_msgs", "CommandResult");
}

/// `skein_msgs/Track` (`msg/Track.msg`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Track {
    /// `"track-7"`.
    pub id: String,
    /// `tentative` | `confirmed` | `lost`.
    pub status: String,
    /// Swarm-frame ENU metres.
    pub position: Point,
    /// ENU m/s.
    pub velocity: Vector3,
    /// Root of the position covariance's trace, metres.
    pub position_sigma_m: f64,
    /// Horizontal covariance `[ee, en, ne, nn]`, m².
    pub covariance_en_m2: [f64; 4],
    /// Updates so far.
    pub hits: u32,
    /// Seconds since the track started.
    pub age_s: f64,
    /// Seconds since its last update.
    pub unseen_s: f64,
}

impl RosMessage for Track {
    const TYPE: (&'static str, &'static str) = ("skein_msgs", "Track");
}

/// `skein_msgs/Tracks` (`msg/Tracks.msg`): `/skein/tracks`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Tracks {
    /// Stamp and frame.
    pub header: Header,
    /// Every track now.
    pub tracks: Vec<Track>,
}

impl RosMessage for Tracks {
    const TYPE: (&'static str, &'static str) = ("skein_msgs", "Tracks");
}

/// `skein_msgs/CoordinatorLease` (`msg/CoordinatorLease.msg`): `/skein/coordinator`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CoordinatorLease {
    /// When it was sent.
    pub header: Header,
    /// The candidate's id.
    pub coordinator_id: String,
    /// Its priority (the higher wins).
    pub priority: u32,
    /// The epoch it holds the role in (active), or the highest it has seen.
    pub epoch: u64,
    /// True while it holds the role.
    pub active: bool,
    /// Where its HTTP API listens.
    pub api_url: String,
}

impl RosMessage for CoordinatorLease {
    const TYPE: (&'static str, &'static str) = ("skein_msgs", "CoordinatorLease");
}

/// `skein_msgs/SwarmMessage` (`msg/SwarmMessage.msg`): one swarm-protocol message between
/// a coordinator and an agent on `/skein/swarm/*` (see [`crate::envelope`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SwarmMessage {
    /// When it was sent; frame [`crate::FRAME_ID`].
    pub header: Header,
    /// The vehicle it is about.
    pub vehicle_id: String,
    /// The agent's or the coordinator's id.
    pub sender_id: String,
    /// Coordinator to agent: the sender's epoch; agent to coordinator: 0.
    pub epoch: u64,
    /// The sender's swarm origin, latitude, degrees (NaN: not anchored yet).
    pub origin_lat_deg: f64,
    /// The sender's swarm origin, longitude, degrees.
    pub origin_lon_deg: f64,
    /// The sender's swarm origin, metres above mean sea level.
    pub origin_alt_m: f64,
    /// The `skein_swarm::protocol` message, JSON.
    pub body: String,
}

impl RosMessage for SwarmMessage {
    const TYPE: (&'static str, &'static str) = ("skein_msgs", "SwarmMessage");
}

/// `geometry_msgs/Transform`: a frame's pose in its parent.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    /// The child frame's origin in the parent frame, metres.
    pub translation: Vector3,
    /// The child frame's orientation in the parent frame.
    pub rotation: Quaternion,
}

/// `geometry_msgs/TransformStamped`: one edge of the TF tree.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TransformStamped {
    /// Stamp and the parent frame (`frame_id`).
    pub header: Header,
    /// The child frame (`uav_1/base_link`).
    pub child_frame_id: String,
    /// The child's pose in the parent.
    pub transform: Transform,
}

/// `tf2_msgs/TFMessage`: `/tf` and `/tf_static`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TfMessage {
    /// The transforms.
    pub transforms: Vec<TransformStamped>,
}

impl RosMessage for TfMessage {
    const TYPE: (&'static str, &'static str) = ("tf2_msgs", "TFMessage");
}

/// `rtcm_msgs/Message` (rtcm_msgs 1.1, `msg/Message.msg`): one RTCM3 message, on
/// `/skein/rtcm` ([`crate::rtcm`]); what ROS 2's `ntrip_client` publishes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RtcmMessage {
    /// When it left the source; frame_id empty (an RTCM message has no frame).
    pub header: Header,
    /// The whole RTCM3 frame: preamble `0xD3`, length, message, CRC-24Q.
    pub message: Vec<u8>,
}

impl RosMessage for RtcmMessage {
    const TYPE: (&'static str, &'static str) = ("rtcm_msgs", "Message");
}
