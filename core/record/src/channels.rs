//! The channels of a recording: topic, schema name and JSON Schema (MCAP `jsonschema`
//! schema encoding, `json` message encoding). Foxglove's own schemas
//! (`foxglove.CompressedImage`, `foxglove.LocationFix`) follow
//! <https://docs.foxglove.dev/docs/visualization/message-schemas>, so its Image and Map
//! panels show the frames and the tracks; skein's own are described here.

use serde_json::{Value, json};

/// MCAP schema encoding of every channel.
pub const SCHEMA_ENCODING: &str = "jsonschema";
/// MCAP message encoding of every channel.
pub const MESSAGE_ENCODING: &str = "json";

/// What a channel carries (and so its schema).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Kind {
    /// A vehicle snapshot as `GET /api/v1/vehicles/{id}` shows it.
    VehicleState,
    /// `foxglove.LocationFix`: a vehicle's WGS-84 position.
    LocationFix,
    /// A MAVLink message skein sent to a vehicle.
    Sent,
    /// A swarm event as the stream shows it.
    Event,
    /// A command the API accepted.
    Command,
    /// The formation as `GET /api/v1/formation` shows it.
    Formation,
    /// Every mission as `GET /api/v1/missions` lists it, state and progress included.
    Missions,
    /// `foxglove.CompressedImage`: a camera frame (JPEG).
    CompressedImage,
}

impl Kind {
    /// Schema name written to the file.
    pub fn schema_name(self) -> &'static str {
        match self {
            Kind::VehicleState => "skein.VehicleState",
            Kind::LocationFix => "foxglove.LocationFix",
            Kind::Sent => "skein.SentMessage",
            Kind::Event => "skein.SwarmEvent",
            Kind::Command => "skein.Command",
            Kind::Formation => "skein.Formation",
            Kind::Missions => "skein.Missions",
            Kind::CompressedImage => "foxglove.CompressedImage",
        }
    }

    /// The JSON Schema of the messages.
    pub fn schema(self) -> Value {
        let time = json!({
            "type": "object",
            "title": "time",
            "properties": {"sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer", "minimum": 0}},
        });
        match self {
            Kind::VehicleState => json!({
                "type": "object",
                "title": "skein.VehicleState",
                "description": "A vehicle as GET /api/v1/vehicles/{id} shows it: FSM state, PX4 mode, armed, position (swarm-frame NED m and WGS-84), velocity (NED m/s), battery, link, formation slot, payloads.",
                "properties": {
                    "id": {"type": "string"}, "sysid": {"type": "integer"},
                    "state": {"type": "string"}, "armed": {"type": "boolean"},
                    "px4_mode": {"type": "string"}
                },
                "required": ["id", "sysid", "state", "armed"],
            }),
            Kind::LocationFix => json!({
                "type": "object",
                "title": "foxglove.LocationFix",
                "description": "A navigation satellite fix for any Global Navigation Satellite System",
                "properties": {
                    "timestamp": time,
                    "frame_id": {"type": "string"},
                    "latitude": {"type": "number", "description": "Latitude in degrees"},
                    "longitude": {"type": "number", "description": "Longitude in degrees"},
                    "altitude": {"type": "number", "description": "Altitude in meters"},
                    "position_covariance": {"type": "array", "items": {"type": "number"}, "minItems": 9, "maxItems": 9},
                    "position_covariance_type": {"type": "integer", "minimum": 0, "maximum": 3},
                },
            }),
            Kind::Sent => json!({
                "type": "object",
                "title": "skein.SentMessage",
                "description": "A MAVLink message skein sent to the vehicle. SET_POSITION_TARGET_LOCAL_NED: type_mask and x/y/z (m), vx/vy/vz (m/s), afx/afy/afz (m/s²), yaw (rad), yaw_rate (rad/s), local NED; COMMAND_LONG / COMMAND_INT: command and params; others: the message name only.",
                "properties": {"message": {"type": "string"}, "sysid": {"type": "integer"}},
                "required": ["message", "sysid"],
            }),
            Kind::Event => json!({
                "type": "object",
                "title": "skein.SwarmEvent",
                "description": "A swarm event as GET /api/v1/stream shows it, tagged by `type` (state_changed, command_result, leader_changed, ...).",
                "properties": {"type": {"type": "string"}},
                "required": ["type"],
            }),
            Kind::Command => json!({
                "type": "object",
                "title": "skein.Command",
                "description": "A command the API accepted: command_id (as in the command_result event), target (a vehicle id or \"swarm\") and the request body.",
                "properties": {"command_id": {"type": "integer"}, "target": {"type": "string"}, "request": {}},
                "required": ["target", "request"],
            }),
            Kind::Formation => json!({
                "type": "object",
                "title": "skein.Formation",
                "description": "The formation as GET /api/v1/formation shows it.",
            }),
            Kind::Missions => json!({
                "type": "object",
                "title": "skein.Missions",
                "description": "Every mission the coordinator holds, as GET /api/v1/missions lists them: id, name, state (ready, running, paused, done, aborted), step, each step's kind and state, progress per group, and the plan.",
                "properties": {"missions": {"type": "array", "items": {
                    "type": "object",
                    "properties": {"id": {"type": "string"}, "name": {"type": "string"}, "state": {"type": "string"}},
                    "required": ["id", "state"],
                }}},
                "required": ["missions"],
            }),
            Kind::CompressedImage => json!({
                "type": "object",
                "title": "foxglove.CompressedImage",
                "description": "A compressed image",
                "properties": {
                    "timestamp": time,
                    "frame_id": {"type": "string"},
                    "data": {"type": "string", "contentEncoding": "base64", "description": "Compressed image data"},
                    "format": {"type": "string", "description": "Image format: jpeg, png, webp or avif"},
                },
            }),
        }
    }
}

/// Topic of a vehicle's channel, e.g. `/skein/uav-1/state`.
pub fn vehicle_topic(id: &str, leaf: &str) -> String {
    format!("/skein/{id}/{leaf}")
}

/// Topic of a payload's frames, e.g. `/skein/uav-2/camera/image`.
pub fn image_topic(id: &str, slot: &str) -> String {
    format!("/skein/{id}/{slot}/image")
}

/// Topic of the swarm events.
pub const EVENTS: &str = "/skein/events";
/// Topic of the accepted commands.
pub const COMMANDS: &str = "/skein/commands";
/// Topic of the formation.
pub const FORMATION: &str = "/skein/formation";
/// Topic of the missions.
pub const MISSIONS: &str = "/skein/missions";

/// A Foxglove `time` from ns since the Unix epoch.
pub fn foxglove_time(ns: u64) -> Value {
    json!({"sec": ns / 1_000_000_000, "nsec": ns % 1_000_000_000})
}
