//! Topic names and their QoS.
//!
//! | topic | type | QoS | rate |
//! |---|---|---|---|
//! | `/skein/<vehicle>/pose` | `geometry_msgs/PoseStamped` | reliable, volatile, keep-last 1 | publish rate |
//! | `/skein/<vehicle>/navsat` | `sensor_msgs/NavSatFix` | reliable, volatile, keep-last 1 | publish rate |
//! | `/skein/<vehicle>/battery` | `sensor_msgs/BatteryState` | reliable, volatile, keep-last 1 | publish rate / 10 |
//! | `/skein/<vehicle>/state` | `skein_msgs/VehicleState` | reliable, volatile, keep-last 1 | publish rate |
//! | `/skein/<vehicle>/command` | `skein_msgs/Command` | reliable, volatile, keep-last 16 | on demand |
//! | `/skein/<vehicle>/command_result` | `skein_msgs/CommandResult` | reliable, volatile, keep-last 16 | per command |
//! | `/skein/tracks` | `skein_msgs/Tracks` | reliable, volatile, keep-last 1 | publish rate / 2 |
//! | `/skein/coordinator` | `skein_msgs/CoordinatorLease` | best-effort, volatile, keep-last 32 | 5 Hz per candidate |
//! | `/skein/swarm/report` | `skein_msgs/SwarmMessage` | best-effort, volatile, keep-last 64 | 20 Hz per agent vehicle |
//! | `/skein/swarm/target` | `skein_msgs/SwarmMessage` | best-effort, volatile, keep-last 64 | formation rate per member |
//! | `/skein/swarm/command` | `skein_msgs/SwarmMessage` | reliable, volatile, keep-last 64 | on demand |
//! | `/skein/swarm/command_result` | `skein_msgs/SwarmMessage` | reliable, volatile, keep-last 64 | per command, state change |
//! | `/skein/swarm/events` | `skein_msgs/SwarmMessage` | reliable, volatile, keep-last 64 | per vehicle event |
//! | `/skein/formation` | `skein_msgs/SwarmMessage` | reliable, transient-local, keep-last 1 | 5 Hz from the active coordinator |
//! | `/skein/mission` | `skein_msgs/SwarmMessage` | reliable, transient-local, keep-last 1 | 2 Hz from the active coordinator |
//! | `/skein/swarm/clock` | `skein_msgs/SwarmMessage` | best-effort, volatile, keep-last 64 | 2 Hz per coordinator and agent |
//! | `/skein/rtcm` | `rtcm_msgs/Message` | reliable, volatile, keep-last 16 | every RTCM frame of the active coordinator's source (a base: 5–15 a second) |
//! | `/tf` | `tf2_msgs/TFMessage` | reliable, volatile, keep-last 1 | publish rate |
//! | `/tf_static` | `tf2_msgs/TFMessage` | reliable, transient-local, keep-last 1 | once the swarm frame is anchored |
//!
//! Poses, fixes and batteries are sensor data, published as REP 2003 asks of a sensor
//! driver: reliable (ROS 2's system default), so that every subscriber matches, a
//! default `rclpy`/`rclcpp` one, RViz's displays and `ros2 topic echo` as much as one
//! with `qos_profile_sensor_data` (best-effort, the profile REP 2003 asks consumers to
//! use; a reliable writer serves a best-effort reader, never the other way round).
//! Keep-last 1 keeps what reliability costs small: the writer holds only the newest
//! sample, so a lost one is replaced by the next, never queued behind. State is reliable
//! keep-last 1 likewise: a reader always ends with the newest state, but never waits
//! for an old one. `/tf` and `/tf_static` have the QoS of tf2's broadcasters (reliable;
//! static transforms transient-local, so RViz started later still gets them). Commands and their
//! results are reliable with a queue, so a burst of commands is neither lost nor merged.
//! Leases are liveness: a lost one is replaced 200 ms later, and a retransmitted old one
//! would only make a dead candidate look alive longer; every candidate writes the one
//! topic, so readers keep 32 samples, not 1 (a keyless topic has one instance, and depth 1
//! would keep only the last writer's).
//!
//! The `/skein/swarm/*` topics carry the swarm protocol between coordinators and agents
//! ([`crate::envelope`]). They are swarm-wide, the vehicle named in each sample, so that a
//! coordinator finds every agent's vehicles on one topic; each has many writers, hence
//! depth 64. Reports and targets are like poses (the next one replaces a lost one: a
//! target carries its time and velocity, the agent moves it on by its age); commands and
//! their results are reliable, so none is lost or merged. `/skein/formation` is the
//! active coordinator's formation for the standbys to resume: transient-local, so a
//! standby that starts late gets the last one at once; the agents read it too, to ride
//! through a silence of their coordinator. `/skein/swarm/clock` carries the clock
//! exchanges between processes ([`crate::clocks`]): like a report, the next one replaces
//! a lost one.
//!
//! Those skein-to-skein topics, and the leases, stay best-effort: a ROS 2 tool reads them
//! with a best-effort subscriber (`ros2 topic echo` picks one by itself), a default
//! reliable one gets nothing.
//!
//! `/skein/rtcm` carries RTK corrections from the active coordinator to the agents
//! ([`crate::rtcm`]), one RTCM3 frame a sample. Reliable, so that a frame lost on a WLAN
//! is repaired (a lost observation frame costs every receiver that epoch of one
//! constellation), and so that it interoperates both ways with ROS 2's own tools: a
//! default `rclpy`/`rclcpp` subscriber (reliable) reads it, and ROS 2's `ntrip_client`
//! (a default reliable publisher, keep-last 10) feeds the agents when remapped onto it
//! (a best-effort writer would match neither default readers nor skein's). Keep-last 16,
//! about one second of a four-constellation base (1005, four MSM, 1230, 1033 …): a frame
//! is repaired while it is among the newest 16 and given up after, for corrections are
//! stale after seconds and a frame of the next epoch supersedes it; a queue of older
//! frames would only delay the fresh ones. Volatile: an agent that joins late wants the
//! next epoch, not the last ones.
//!
//! Each row is a [`TopicSpec`] made by one function here ([`pose`], [`swarm_report`] …);
//! the roles open their topics from these, on DDS or on the in-memory carrier of the
//! unit tests ([`crate::carrier`]).
//!
//! Names: a ROS 2 name holds letters, digits and underscores only, so a vehicle id is
//! written with every other character as `_` ([`ros_name`]): `uav-1` publishes on
//! `/skein/uav_1/pose`, the DDS topic `rt/skein/uav_1/pose`.

use ros2_client::QosProfile;
use ros2_client::qos::{Durability, History, WhenFull};

/// Namespace of every topic.
pub const NAMESPACE: &str = "/skein";

/// Namespace of the swarm protocol's topics.
pub const SWARM_NAMESPACE: &str = "/skein/swarm";

/// One topic: its ROS 2 namespace and name, and its QoS (a row of the table above).
#[derive(Debug, Clone, PartialEq)]
pub struct TopicSpec {
    /// ROS 2 namespace (`/skein`, `/skein/swarm`, `/skein/uav_1`).
    pub namespace: String,
    /// Name within it (`pose`, `report`).
    pub name: &'static str,
    /// Its QoS.
    pub qos: QosProfile,
}

impl TopicSpec {
    fn new(namespace: impl Into<String>, name: &'static str, qos: QosProfile) -> Self {
        TopicSpec {
            namespace: namespace.into(),
            name,
            qos,
        }
    }
}

impl std::fmt::Display for TopicSpec {
    /// The full ROS 2 name (`/skein/swarm/report`, `/tf`).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.namespace.trim_end_matches('/'), self.name)
    }
}

/// `/skein/<vehicle>/pose`.
pub fn pose(vehicle_id: &str) -> TopicSpec {
    TopicSpec::new(vehicle_namespace(vehicle_id), "pose", sensor())
}

/// `/skein/<vehicle>/navsat`.
pub fn navsat(vehicle_id: &str) -> TopicSpec {
    TopicSpec::new(vehicle_namespace(vehicle_id), "navsat", sensor())
}

/// `/skein/<vehicle>/battery`.
pub fn battery(vehicle_id: &str) -> TopicSpec {
    TopicSpec::new(vehicle_namespace(vehicle_id), "battery", sensor())
}

/// `/skein/<vehicle>/state`.
pub fn state(vehicle_id: &str) -> TopicSpec {
    TopicSpec::new(vehicle_namespace(vehicle_id), "state", latest_state())
}

/// `/skein/<vehicle>/command`.
pub fn command(vehicle_id: &str) -> TopicSpec {
    TopicSpec::new(vehicle_namespace(vehicle_id), "command", commands())
}

/// `/skein/<vehicle>/command_result`.
pub fn command_result(vehicle_id: &str) -> TopicSpec {
    TopicSpec::new(vehicle_namespace(vehicle_id), "command_result", commands())
}

/// `/skein/tracks`.
pub fn tracks() -> TopicSpec {
    TopicSpec::new(NAMESPACE, "tracks", latest_state())
}

/// `/skein/coordinator`: the candidates' leases.
pub fn coordinator() -> TopicSpec {
    TopicSpec::new(NAMESPACE, "coordinator", leases())
}

/// `/skein/swarm/report`: agent → coordinators, reports and snapshots.
pub fn swarm_report() -> TopicSpec {
    TopicSpec::new(SWARM_NAMESPACE, "report", protocol_stream())
}

/// `/skein/swarm/target`: coordinator → agents, slot targets.
pub fn swarm_target() -> TopicSpec {
    TopicSpec::new(SWARM_NAMESPACE, "target", protocol_stream())
}

/// `/skein/swarm/command`: coordinator → agents, every other `ToVehicle`.
pub fn swarm_command() -> TopicSpec {
    TopicSpec::new(SWARM_NAMESPACE, "command", protocol_commands())
}

/// `/skein/swarm/command_result`: agent → coordinators, `FromVehicle`.
pub fn swarm_command_result() -> TopicSpec {
    TopicSpec::new(SWARM_NAMESPACE, "command_result", protocol_commands())
}

/// `/skein/swarm/events`: agent → coordinators, its vehicles' events.
pub fn swarm_events() -> TopicSpec {
    TopicSpec::new(SWARM_NAMESPACE, "events", protocol_commands())
}

/// `/skein/swarm/clock`: every coordinator and agent, clock exchanges.
pub fn swarm_clock() -> TopicSpec {
    TopicSpec::new(SWARM_NAMESPACE, "clock", protocol_stream())
}

/// `/skein/formation`: the active coordinator's formation, for the standbys and agents.
pub fn formation() -> TopicSpec {
    TopicSpec::new(NAMESPACE, "formation", formation_mirror())
}

/// `/skein/mission`: the active coordinator's flying mission, for the standbys
/// ([`crate::mirror`]).
pub fn mission() -> TopicSpec {
    TopicSpec::new(NAMESPACE, "mission", formation_mirror())
}

/// `/skein/rtcm`: the active coordinator's RTK corrections, for the agents ([`crate::rtcm`]).
pub fn rtcm() -> TopicSpec {
    TopicSpec::new(NAMESPACE, "rtcm", corrections())
}

/// `/tf`: the vehicles' frames in the swarm frame ([`crate::tf`]).
pub fn tf() -> TopicSpec {
    TopicSpec::new("/", "tf", latest_state())
}

/// `/tf_static`: the swarm frame's anchor ([`crate::tf`]).
pub fn tf_static() -> TopicSpec {
    TopicSpec::new("/", "tf_static", static_transforms())
}

/// A vehicle id as a ROS 2 name token: letters, digits and `_` kept, anything else
/// becomes `_`, and a leading digit gets a `v` before it (`"uav-1"` → `"uav_1"`).
pub fn ros_name(id: &str) -> String {
    let mut s: String = id
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if s.is_empty() || s.starts_with(|c: char| c.is_ascii_digit()) {
        s.insert(0, 'v');
    }
    s
}

/// The first of `ids` (other than `id` itself) that has `id`'s ROS name: two such
/// vehicles cannot both publish.
pub fn same_ros_name<'a>(ids: impl IntoIterator<Item = &'a str>, id: &str) -> Option<&'a str> {
    let name = ros_name(id);
    ids.into_iter().find(|k| *k != id && ros_name(k) == name)
}

/// The namespace of a vehicle's topics (`/skein/uav_1`).
pub fn vehicle_namespace(id: &str) -> String {
    format!("{NAMESPACE}/{}", ros_name(id))
}

/// Sensor data (pose, navsat, battery): reliable, volatile, keep-last 1 (REP 2003's
/// system default for a driver; see the module docs).
pub fn sensor() -> QosProfile {
    latest_state()
}

/// Latest state (vehicle state, tracks): reliable, volatile, keep-last 1.
pub fn latest_state() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::Fail)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 1 })
}

/// Coordinator leases: best-effort, volatile, keep-last 32.
pub fn leases() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_best_effort()
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 32 })
}

/// Swarm-protocol reports and targets: best-effort, volatile, keep-last 64.
pub fn protocol_stream() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_best_effort()
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 64 })
}

/// Swarm-protocol commands and their results: reliable, volatile, keep-last 64.
pub fn protocol_commands() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::Wait(std::time::Duration::from_millis(20)))
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 64 })
}

/// Static transforms (`/tf_static`, as tf2's static broadcaster): reliable,
/// transient-local, keep-last 1.
pub fn static_transforms() -> QosProfile {
    formation_mirror()
}

/// The formation's and the mission's mirrors: reliable, transient-local, keep-last 1.
pub fn formation_mirror() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::Wait(std::time::Duration::from_millis(20)))
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 1 })
}

/// RTK corrections (`/skein/rtcm`): reliable, volatile, keep-last 16 (see the module
/// docs).
pub fn corrections() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::Wait(std::time::Duration::from_millis(20)))
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 16 })
}

/// Commands and their results: reliable, volatile, keep-last 16.
pub fn commands() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::Wait(std::time::Duration::from_millis(20)))
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 16 })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vehicle_ids_become_ros_names() {
        assert_eq!(ros_name("uav-1"), "uav_1");
        assert_eq!(ros_name("scout.7"), "scout_7");
        assert_eq!(ros_name("7"), "v7");
        assert_eq!(vehicle_namespace("uav-12"), "/skein/uav_12");
        assert_eq!(pose("uav-1").to_string(), "/skein/uav_1/pose");
        assert_eq!(swarm_report().to_string(), "/skein/swarm/report");
        assert_eq!(tf().to_string(), "/tf");
        assert_eq!(tf_static().to_string(), "/tf_static");
        assert_eq!(rtcm().to_string(), "/skein/rtcm");
        assert_eq!(same_ros_name(["uav-1", "uav-2"], "uav.1"), Some("uav-1"));
        assert_eq!(same_ros_name(["uav-1", "uav-2"], "uav-1"), None);
        assert_eq!(same_ros_name(["uav-1"], "uav-3"), None);
        for id in ["uav-1", "a b", "x/y", "ü"] {
            let n = ros_name(id);
            assert!(
                n.chars().all(|c| c.is_ascii_alphanumeric() || c == '_'),
                "{n}"
            );
        }
    }
}
