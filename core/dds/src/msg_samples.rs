//! One sample of every message type skein writes or reads on DDS, every field set to a
//! value of its own (no zeros where a swapped field would hide, a non-empty sequence,
//! non-ASCII text): what the checks of the Rust types against the `.msg` files use
//! (the unit test `msg_files`, and `tests/e2e_ros2.rs`, which compares [`crate::msgs::to_cdr`]
//! with the bytes of the rosidl-generated Python types). No NaN, so that every sample
//! has a JSON form.

use crate::msgs::*;
use ros2_client::builtin_interfaces::Time;

/// Receives each sample in turn ([`visit_all`]).
pub trait SampleVisitor {
    /// One sample of message type `M` (`M::TYPE` names it).
    fn sample<M: RosMessage>(&mut self, m: &M);
}

fn header(frame_id: &str) -> Header {
    Header {
        stamp: Time::from_nanos(1_764_000_123_456_789_012),
        frame_id: frame_id.into(),
    }
}

fn point(x: f64, y: f64, z: f64) -> Point {
    Point { x, y, z }
}

fn track() -> Track {
    Track {
        id: "track-7".into(),
        status: "confirmed".into(),
        position: point(-12.5, 40.25, 31.0),
        velocity: Vector3 {
            x: 1.5,
            y: -2.25,
            z: 0.125,
        },
        position_sigma_m: 0.75,
        covariance_en_m2: [0.5, 0.0625, 0.0625, 0.25],
        hits: 42,
        age_s: 12.5,
        unseen_s: 0.1,
    }
}

/// Hands `v` one sample of every type: skein's own (`skein_msgs/*`, every one of
/// `ros2/skein_msgs/msg/`) and the standard ones skein publishes or reads.
pub fn visit_all(v: &mut impl SampleVisitor) {
    v.sample(&VehicleState {
        header: header("skein_swarm"),
        id: "uav-1".into(),
        sysid: 1,
        model: "observation".into(),
        state: "InFormation".into(),
        px4_mode: "OFFBOARD".into(),
        armed: true,
        link_connected: true,
        slot: 2,
        leader: false,
    });
    v.sample(&Command {
        source: "rclpy node ü".into(),
        request_id: 0x0102_0304_0506_0708,
        command: "goto".into(),
        altitude_m: 8.0,
        force: true,
        target: point(5.0, 20.0, 10.0),
    });
    v.sample(&CommandResult {
        request_id: 7,
        command_id: 1_000_003,
        accepted: false,
        reason: "state: takeoff is not allowed in Landing".into(),
    });
    v.sample(&track());
    v.sample(&Tracks {
        header: header("skein_swarm"),
        tracks: vec![
            track(),
            Track {
                id: "track-8".into(),
                status: "tentative".into(),
                hits: 3,
                ..track()
            },
        ],
    });
    v.sample(&CoordinatorLease {
        header: header(""),
        coordinator_id: "ground-4242".into(),
        priority: 2,
        epoch: 5,
        active: true,
        api_url: "http://10.0.0.2:8080".into(),
    });
    v.sample(&SwarmMessage {
        header: header("skein_swarm"),
        vehicle_id: "uav-3".into(),
        sender_id: "agent-3".into(),
        epoch: 9,
        origin_lat_deg: 47.397742,
        origin_lon_deg: 8.545594,
        origin_alt_m: 488.0,
        body: r#"{"type":"slot","north_m":1.5}"#.into(),
    });
    v.sample(&PoseStamped {
        header: header("skein_swarm"),
        pose: Pose {
            position: point(3.0, 10.0, 7.5),
            orientation: Quaternion {
                x: 0.0,
                y: 0.0,
                z: 0.3826834323650898,
                w: 0.9238795325112867,
            },
        },
    });
    v.sample(&NavSatFix {
        header: header("uav-1"),
        status: NavSatStatus {
            status: -1,
            service: 1,
        },
        latitude: 47.3977,
        longitude: 8.5456,
        altitude: 498.25,
        position_covariance: [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0],
        position_covariance_type: 2,
    });
    v.sample(&BatteryState {
        header: header("uav-1"),
        voltage: 15.9,
        temperature: 21.5,
        current: -12.25,
        charge: 3.5,
        capacity: 5.0,
        design_capacity: 5.2,
        percentage: 0.87,
        power_supply_status: 2,
        power_supply_health: 1,
        power_supply_technology: 3,
        present: true,
        cell_voltage: vec![3.95, 3.975, 4.0, 3.975],
        cell_temperature: vec![21.0],
        location: "bay".into(),
        serial_number: "SN-1".into(),
    });
    v.sample(&TfMessage {
        transforms: vec![TransformStamped {
            header: header("skein_swarm"),
            child_frame_id: "uav_1/base_link".into(),
            transform: Transform {
                translation: Vector3 {
                    x: 3.0,
                    y: 10.0,
                    z: 7.5,
                },
                rotation: Quaternion {
                    x: 0.0,
                    y: 0.0,
                    z: std::f64::consts::FRAC_1_SQRT_2,
                    w: std::f64::consts::FRAC_1_SQRT_2,
                },
            },
        }],
    });
    v.sample(&RtcmMessage {
        header: header(""),
        // An RTCM3 frame's head (preamble, length 19, message 1005) and a made-up tail:
        // the bytes are data to the message type.
        message: vec![0xD3, 0x00, 0x13, 0x3E, 0xD0, 0x07, 0xFF, 0x80, 0x01, 0x02],
    });
}
