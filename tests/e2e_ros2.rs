//! The swarm as a ROS 2 user meets it: real ROS 2 nodes (rclpy on `rmw_fastrtps_cpp`, Fast
//! DDS 2.14, ROS 2 Jazzy's default middleware, from the `ros-jazzy-*` wheels) with
//! `skein_msgs` built from `ros2/skein_msgs` by ROS 2's own generators
//! (`tests/peers/ros2/setup.sh`), against `skein up --sim N --dds`
//! (`tests/peers/ros2_peer.py`):
//!
//! - the ROS graph lists skein's node and every topic with its type; a subscriber with
//!   ROS 2's default QoS (as RViz's displays) reads pose, navsat, battery, state and
//!   tracks at the rates docs/ros2.md names, and so does one with
//!   `qos_profile_sensor_data`; the values match skein's HTTP API; `/tf` has one frame
//!   per vehicle on its pose, and `/tf_static` anchors the swarm frame at the swarm
//!   origin; without `--dds-commands` nothing reads commands and the vehicles stay on the
//!   ground;
//! - with `--dds-commands` a node flies a vehicle through `skein_msgs/Command`: refusals
//!   name their reason; arm, takeoff to 8 m, goto and land are obeyed; `/tf` looked up at
//!   a pose's stamp is the pose; `--dds-tf-parent map` makes `/tf_static` the identity
//!   `map → skein_swarm`;
//! - a node sees the vehicles of every agent of a distributed swarm, and the RTK
//!   corrections its coordinator relays on `/skein/rtcm` (`rtcm_msgs/Message`, built
//!   from `tests/peers/ros2/rtcm_msgs`), every frame whole with a good CRC; Kilted's
//!   rclpy (Fast DDS 3.2) reads the standard topics as Jazzy's does;
//! - every message type serialises to the same bytes in skein (Rust) and with the
//!   rosidl-generated Python type.
//!
//! skein stays on loopback (`--dds-network 127.0.0.1`), the nodes too
//! (`ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`), each test on a DDS domain of its own.

mod support;

use serde_json::{Value, json};
use std::time::{Duration, Instant};
use support::ros2::{Distro, ros2_peer, ros2_peer_on};
use support::rtk::UdpBase;
use support::{Skein, eventually};

/// DDS domain `k` (0 to 2) of this test process's own: 180–218, apart from
/// `e2e_distributed`'s 20–97, `e2e_dds`' 100–179 and `e2e_failover`'s 220–231.
fn domain(k: u32) -> String {
    (180 + (std::process::id() % 13) * 3 + k).to_string()
}

/// DDS publishing rounds `skein` has shed so far (`load.shed.dds` of its health): a
/// process short of CPU publishes at a fifth of the rate (`skein_swarm::load`), which a
/// test on a busy machine must allow.
fn dds_shed(skein: &Skein) -> u64 {
    skein.get("/api/v1/health").1["load"]["shed"]["dds"]
        .as_u64()
        .unwrap_or(0)
}

/// The nominal rate `hz` as a range a measured one must fall in: ±30 %, down to a fifth
/// of it when the publisher shed rounds meanwhile.
fn rate_range(hz: f64, shed: bool) -> std::ops::RangeInclusive<f64> {
    let low = if shed { hz / 5.0 } else { hz };
    0.7 * low..=1.3 * hz
}

/// Every rate of a `read` report that docs/ros2.md names: pose (for a default-QoS and a
/// sensor-data subscriber), navsat and state at the publish rate (10 Hz), battery at a
/// tenth of it, for each of `vehicles` (ROS names); `standard_only`: no state; `shed`:
/// the publisher shed rounds meanwhile.
fn assert_vehicle_rates(r: &Value, vehicles: &[&str], standard_only: bool, shed: bool) {
    let rates = &r["rates_hz"];
    for v in vehicles {
        for (topic, want) in [
            ("pose", 10.0),
            ("pose sensor_data", 10.0),
            ("navsat", 10.0),
            ("state", 10.0),
            ("battery", 1.0),
        ] {
            if standard_only && topic == "state" {
                continue;
            }
            let hz = f(rates, &format!("/skein/{v}/{topic}"));
            assert!(
                rate_range(want, shed).contains(&hz),
                "{v}/{topic}: {hz} Hz: {r}"
            );
        }
    }
}

/// The values of a `read` report are skein's: the API's positions (ENU), fixes and
/// batteries.
fn assert_values_match_the_api(r: &Value) {
    assert!(f(r, "worst_pose_error_m") < 0.05, "{r}");
    assert!(f(r, "worst_navsat_error_deg") < 1e-6, "{r}");
    assert!(f(r, "worst_navsat_alt_error_m") < 0.05, "{r}");
    assert!(f(r, "worst_battery_error") < 0.02, "{r}");
}

fn up_on(d: &str, n: usize, extra: &[&str]) -> Skein {
    let mut args = vec!["--dds", "--domain-id", d, "--dds-network", "127.0.0.1"];
    args.extend_from_slice(extra);
    let mut skein = Skein::up_sim(n, &args);
    skein
        .process
        .wait_line("ROS 2 topics under /skein", Duration::from_secs(30));
    skein.wait_all(
        "connected with positions and batteries",
        n,
        Duration::from_secs(60),
        |v| v["link"]["connected"] == true && v["position"].is_object() && v["battery"].is_object(),
    );
    skein
}

fn f(v: &Value, key: &str) -> f64 {
    v[key]
        .as_f64()
        .unwrap_or_else(|| panic!("no number {key} in {v}"))
}

#[test]
fn rclpy_nodes_on_fast_dds_read_every_topic_of_a_swarm_they_cannot_command() {
    let d = domain(0);
    let skein = up_on(&d, 3, &["--intruders", "1"]);
    let node = format!("skein_up_{}", skein.process.pid());
    let shed_before = dds_shed(&skein);
    let started = Instant::now();
    let r = ros2_peer(
        Some(&d),
        &[
            "read",
            "--api",
            &skein.base,
            "--vehicles",
            "uav-1,uav-2,uav-3",
            "--node",
            &node,
            "--seconds",
            "4",
        ],
        Duration::from_secs(90),
    );
    eprintln!(
        "ros2_peer read ({:.1} s): {r}",
        started.elapsed().as_secs_f64()
    );
    // The rates docs/ros2.md names, for the default-QoS subscriber and the sensor-data
    // one alike; /tf at the publish rate, tracks at half of it.
    let shed = dds_shed(&skein) > shed_before;
    assert_vehicle_rates(&r, &["uav_1", "uav_2", "uav_3"], false, shed);
    for (topic, want) in [("/skein/tracks", 5.0), ("/tf", 10.0)] {
        let hz = f(&r["rates_hz"], topic);
        assert!(
            rate_range(want, shed).contains(&hz),
            "{topic}: {hz} Hz: {r}"
        );
    }
    // The values are skein's: the API's positions (ENU), fixes, batteries and states.
    assert_values_match_the_api(&r);
    for (id, s) in r["states"].as_object().expect("states") {
        let seen = json!([
            s["id"],
            s["sysid"],
            s["model"],
            s["state"],
            s["px4_mode"],
            s["armed"],
            s["link_connected"]
        ]);
        assert_eq!(seen, s["api"], "{id}");
        assert_eq!(s["slot"], -1, "{id}: no formation");
    }
    assert_eq!(r["tracks"]["frame_id"], "skein_swarm", "{r}");
    // TF: one frame per vehicle, child of the swarm frame, on its pose; the swarm frame
    // anchored at the swarm origin in ECEF.
    assert_eq!(
        r["tf_frames"],
        json!(["uav_1/base_link", "uav_2/base_link", "uav_3/base_link"]),
        "{r}"
    );
    assert_eq!(r["tf_parents"], json!(["skein_swarm"]), "{r}");
    assert!(f(&r, "worst_tf_vs_pose_m") < 0.05, "{r}");
    assert_eq!(r["tf_static"], json!([["earth", "skein_swarm"]]), "{r}");
    assert!(f(&r, "anchor_error_m") < 0.01, "{r}");
    // Kilted's rclpy on Fast DDS 3.2 reads the standard topics the same.
    let shed_before = dds_shed(&skein);
    let started = Instant::now();
    let k = ros2_peer_on(
        Distro::Kilted,
        Some(&d),
        &[
            "read",
            "--api",
            &skein.base,
            "--vehicles",
            "uav-1,uav-2,uav-3",
            "--node",
            &node,
            "--seconds",
            "3",
            "--standard-only",
        ],
        Duration::from_secs(90),
    );
    eprintln!(
        "ros2_peer read, Kilted ({:.1} s): {k}",
        started.elapsed().as_secs_f64()
    );
    let shed = dds_shed(&skein) > shed_before;
    assert_vehicle_rates(&k, &["uav_1", "uav_2", "uav_3"], true, shed);
    assert_values_match_the_api(&k);
    // Without --dds-commands: no command reader, and nothing moved.
    assert_eq!(r["command_readers"], 0, "{r}");
    assert_eq!(skein.dds_samples("commands"), 0);
    for v in skein.vehicles() {
        assert_eq!(v["state"], "Landed", "{v}");
    }
}

#[test]
fn an_rclpy_node_flies_a_vehicle_through_skein_msgs_commands() {
    let d = domain(1);
    let skein = up_on(&d, 2, &["--dds-commands", "--dds-tf-parent", "map"]);
    let started = Instant::now();
    let r = ros2_peer(
        Some(&d),
        &["command", "--api", &skein.base, "--vehicle", "uav-1"],
        Duration::from_secs(150),
    );
    eprintln!(
        "ros2_peer command ({:.1} s): {r}",
        started.elapsed().as_secs_f64()
    );
    let unknown = r["unknown_refused"].as_str().unwrap();
    assert!(
        unknown.contains("command") && unknown.contains("explode"),
        "{r}"
    );
    let land = r["land_refused"].as_str().unwrap();
    assert!(land.contains("Landed"), "the refusal names the state: {r}");
    assert!((f(&r, "hover_altitude_m") - 8.0).abs() < 0.2, "{r}");
    assert!(f(&r, "goal_error_m") < 0.2, "{r}");
    assert_eq!(r["tf_parent"], "skein_swarm", "{r}");
    assert!(f(&r, "tf_vs_pose_m") < 0.05, "{r}");
    // --dds-tf-parent map: the swarm frame is the identity of the user's map frame.
    assert_eq!(
        r["tf_static"],
        json!([["map", "skein_swarm", [0.0, 0.0, 0.0], 1.0]]),
        "{r}"
    );
    // The API saw the same flight: every accepted command has its id, and the vehicle is
    // back on the ground where the goto took it; the other vehicle never moved.
    let ids: Vec<u64> = r["command_ids"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect();
    assert!(ids.iter().all(|id| *id > 0), "{r}");
    let goal = r["goal_enu_m"].as_array().unwrap();
    let at = r["api_position_enu_m"].as_array().unwrap();
    for i in 0..2 {
        let (g, a) = (goal[i].as_f64().unwrap(), at[i].as_f64().unwrap());
        assert!((g - a).abs() < 1.0, "landed {at:?}, goal {goal:?}");
    }
    eventually("uav-1 landed", Duration::from_secs(30), || {
        let (_, v) = skein.get("/api/v1/vehicles/uav-1");
        match v["state"].as_str() {
            Some("Landed" | "Landing") => Ok(()),
            _ => Err(v.to_string()),
        }
    });
    assert_eq!(skein.get("/api/v1/vehicles/uav-2").1["state"], "Landed");
    // Six commands taken, the unknown one malformed.
    assert_eq!(skein.dds_samples("commands"), 6);
    assert_eq!(skein.dds_samples("malformed"), 1);
}

#[test]
fn an_rclpy_node_sees_every_agent_s_vehicles_of_a_distributed_swarm() {
    let d = domain(2);
    // Every process anchors its swarm frame at the same origin, so that `skein_swarm` is
    // one frame on the domain (docs/ros2.md: a distributed swarm on ROS 2).
    let dir = std::env::temp_dir().join(format!("skein-e2e-ros2-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("origin.toml");
    std::fs::write(
        &config,
        "[swarm]\norigin = { lat_deg = 47.397742, lon_deg = 8.545594, alt_amsl_m = 488.0 }\n",
    )
    .unwrap();
    let config = config.to_str().unwrap();
    let coordinator = Skein::coordinator(&[
        "--id",
        "ground",
        "--domain-id",
        &d,
        "--dds-network",
        "127.0.0.1",
        "--config",
        config,
    ]);
    let agents: Vec<Skein> = [1, 2]
        .iter()
        .map(|k: &u8| {
            let (sysid, id) = (k.to_string(), format!("agent-{k}"));
            Skein::launch_in(
                None,
                "agent",
                &[
                    "--sim",
                    "1",
                    "--first-sysid",
                    &sysid,
                    "--sim-base-port",
                    "0",
                    "--id",
                    &id,
                    "--domain-id",
                    &d,
                    "--dds-network",
                    "127.0.0.1",
                    "--config",
                    config,
                ],
            )
        })
        .collect();
    coordinator.wait_all(
        "both agents' vehicles joined, with positions and batteries",
        2,
        Duration::from_secs(60),
        |v| v["position"].is_object() && v["battery"].is_object(),
    );
    let nodes = format!(
        "skein_coordinator_{},skein_agent_{},skein_agent_{}",
        coordinator.process.pid(),
        agents[0].process.pid(),
        agents[1].process.pid()
    );
    // An RTK source at the coordinator (a base 600 m north-east of the home), relayed on
    // /skein/rtcm once the coordinator is active (a standby refuses the PUT).
    let base = UdpBase::start((47.4021, 8.5512, 535.0));
    eventually(
        "the coordinator takes the RTK source",
        Duration::from_secs(20),
        || match coordinator.put("/api/v1/rtk", json!({"source": base.source()})) {
            (200, _) => Ok(()),
            (_, r) => Err(r.to_string()),
        },
    );
    let shed_before: u64 = agents.iter().map(dds_shed).sum();
    let started = Instant::now();
    let r = ros2_peer(
        Some(&d),
        &[
            "read",
            "--api",
            &coordinator.base,
            "--vehicles",
            "uav-1,uav-2",
            "--node",
            &nodes,
            "--seconds",
            "3",
            "--rtcm",
        ],
        Duration::from_secs(90),
    );
    eprintln!(
        "ros2_peer read, distributed ({:.1} s): {r}",
        started.elapsed().as_secs_f64()
    );
    let shed = agents.iter().map(dds_shed).sum::<u64>() > shed_before;
    assert_vehicle_rates(&r, &["uav_1", "uav_2"], false, shed);
    // Each agent publishes its own vehicle; the coordinator's API shows the same.
    assert_values_match_the_api(&r);
    for (id, s) in r["states"].as_object().expect("states") {
        assert_eq!(s["id"], s["api"][0], "{id}");
        assert_eq!(s["state"], s["api"][3], "{id}");
    }
    assert_eq!(
        r["tf_frames"],
        json!(["uav_1/base_link", "uav_2/base_link"]),
        "{r}"
    );
    assert!(f(&r, "worst_tf_vs_pose_m") < 0.05, "{r}");
    assert!(f(&r, "anchor_error_m") < 0.01, "{r}");
    // The base's epochs (a 1005 and a 1074 a second), whole, as ROS 2 types them.
    let rtcm = &r["rtcm"];
    assert_eq!(rtcm["bad"], 0, "{r}");
    for t in ["1005", "1074"] {
        assert!(rtcm["types"][t].as_u64() >= Some(2), "{t}: {r}");
    }
    drop(base);
    drop(agents);
    drop(coordinator);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Collects every sample of `skein_dds::msg_samples` with its JSON form and skein's
/// CDR bytes.
#[derive(Default)]
struct Samples(Vec<Value>);

impl skein_dds::msg_samples::SampleVisitor for Samples {
    fn sample<M: skein_dds::msgs::RosMessage>(&mut self, m: &M) {
        let (pkg, name) = M::TYPE;
        self.0.push(json!({
            "type": format!("{pkg}/msg/{name}"),
            "value": serde_json::to_value(m).expect("JSON"),
            "cdr_hex": skein_dds::msgs::to_cdr(m)
                .expect("CDR")
                .iter()
                .map(|b| format!("{b:02x}"))
                .collect::<String>(),
        }));
    }
}

#[test]
fn every_message_type_serialises_to_the_same_bytes_in_skein_and_rclpy() {
    let mut samples = Samples::default();
    skein_dds::msg_samples::visit_all(&mut samples);
    let file = std::env::temp_dir().join(format!("skein-msg-samples-{}.json", std::process::id()));
    std::fs::write(&file, serde_json::to_vec(&samples.0).unwrap()).unwrap();
    let r = ros2_peer(
        None,
        &["serialise", "--samples", file.to_str().unwrap()],
        Duration::from_secs(60),
    );
    let _ = std::fs::remove_file(&file);
    let compared = r["compared"].as_object().expect("compared");
    for ty in [
        "skein_msgs/msg/VehicleState",
        "skein_msgs/msg/Command",
        "skein_msgs/msg/CommandResult",
        "skein_msgs/msg/Track",
        "skein_msgs/msg/Tracks",
        "skein_msgs/msg/CoordinatorLease",
        "skein_msgs/msg/SwarmMessage",
        "geometry_msgs/msg/PoseStamped",
        "sensor_msgs/msg/NavSatFix",
        "sensor_msgs/msg/BatteryState",
        "tf2_msgs/msg/TFMessage",
        "rtcm_msgs/msg/Message",
    ] {
        assert!(compared.contains_key(ty), "{ty} not compared: {r}");
    }
    eprintln!("{r}");
}
