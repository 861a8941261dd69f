//! The swarm on ROS 2 topics (`skein up --dds`), read and commanded by an independent
//! DDS implementation: CycloneDDS's Python binding (`tests/peers/dds_peer.py`), with type
//! definitions written from the `.msg` files and the ROS 2 standard messages alone.
//!
//! Besides: `skein bench dds` small (its report's shape; never its timing), and a link
//! held to loopback beside interfaces that come and go.
//!
//! Both sides are kept on loopback (`--dds-network 127.0.0.1`; the peer's
//! `CYCLONEDDS_URI` names 127.0.0.1 with unicast discovery), each test on its own
//! domain, so nothing leaves the host and parallel tests do not hear each other.

mod support;

use serde_json::Value;
use std::time::Duration;
use support::bench::bench_report;
use support::counter_uas::{OBSERVERS, build_plugins, up_with_intruder_pass_and};
use support::netns::Namespace;
use support::{Process, Skein, eventually, run_peer};

/// A DDS domain of this test process's own (`offset`, 0 to 3, tells the tests apart):
/// 100–179, apart from the other targets' (`e2e_ros2` has 180–218).
fn domain(offset: u32) -> String {
    (100 + (std::process::id() % 20) * 4 + offset).to_string()
}

/// Runs `dds_peer.py` on domain `d` against `skein`'s API for `vehicle`, on loopback,
/// with `extra` arguments; its one JSON line once it exits 0 (panics with its output
/// otherwise).
fn peer(skein: &Skein, d: &str, vehicle: &str, extra: &[&str], timeout: Duration) -> Value {
    let mut args = vec![
        "--domain",
        d,
        "--vehicle",
        vehicle,
        "--api",
        &skein.base,
        "--loopback",
    ];
    args.extend_from_slice(extra);
    let (code, out, err) = run_peer("dds_peer.py", &args, timeout);
    assert_eq!(code, Some(0), "peer failed:\n{out}\n{err}");
    serde_json::from_str(out.trim()).expect("one JSON line")
}

fn vehicle(skein: &Skein, id: &str) -> Value {
    skein.get(&format!("/api/v1/vehicles/{id}")).1
}

#[test]
fn a_cyclonedds_peer_reads_poses_and_commands_a_vehicle() {
    let d = domain(0);
    let mut skein = Skein::up_sim(
        2,
        &[
            "--dds",
            "--dds-commands",
            "--domain-id",
            &d,
            "--dds-network",
            "127.0.0.1",
        ],
    );
    skein
        .process
        .wait_line("ROS 2 topics under /skein", Duration::from_secs(30));
    skein.wait_all(
        "connected with positions",
        2,
        Duration::from_secs(60),
        |v| v["link"]["connected"] == true && v["position"].is_object(),
    );
    // The vehicle away from the swarm origin (the first home heard), so that a swapped or
    // unturned axis would show.
    let horizontal = |v: &Value| {
        let p = &v["position"];
        p["north_m"]
            .as_f64()
            .unwrap()
            .hypot(p["east_m"].as_f64().unwrap())
    };
    let mut vs = skein.vehicles();
    vs.sort_by(|a, b| horizontal(a).total_cmp(&horizontal(b)));
    let (other, target) = (vs[0]["id"].as_str().unwrap(), vs[1]["id"].as_str().unwrap());
    assert!(horizontal(&vs[1]) > 2.0, "{vs:?}");
    let report = peer(&skein, &d, target, &[], Duration::from_secs(120));
    assert!(
        report["worst_pose_error_m"].as_f64().unwrap() < 0.5,
        "{report}"
    );
    assert!(report["climbed_to_m"].as_f64().unwrap() >= 5.0, "{report}");
    let land = report["land_refused"].as_str().unwrap();
    assert!(
        land.contains("Landed"),
        "the refusal names the state: {land}"
    );
    assert!(
        report["in_flight_worst_pose_error_m"].as_f64().unwrap() < 0.5,
        "{report}"
    );
    // The takeoff went to that vehicle alone, through the same path as the API's.
    let flown = vehicle(&skein, target);
    assert!(
        ["TakingOff", "Hovering"].contains(&flown["state"].as_str().unwrap()),
        "{flown}"
    );
    assert_eq!(vehicle(&skein, other)["state"], "Landed");
    assert_eq!(skein.dds_samples("commands"), 3);
    // The unknown command was malformed; the land was well-formed and refused.
    assert_eq!(skein.dds_samples("malformed"), 1);
    eventually("samples counted", Duration::from_secs(5), || {
        match skein.dds_samples("published") {
            n if n > 20 => Ok(()),
            n => Err(format!("{n} published")),
        }
    });
    let (_, tree) = skein.get("/api/v1/supervision");
    assert!(tree.to_string().contains("coordinator/dds"), "{tree}");
}

#[test]
fn without_dds_commands_nothing_can_command_and_a_panicked_link_restarts() {
    let d = domain(1);
    let mut skein = Skein::up_sim(
        1,
        &[
            "--dds",
            "--domain-id",
            &d,
            "--dds-network",
            "127.0.0.1",
            "--enable-fault-injection",
        ],
    );
    skein
        .process
        .wait_line("ROS 2 topics under /skein", Duration::from_secs(30));
    let report = peer(
        &skein,
        &d,
        "uav-1",
        &["--expect-no-command-reader"],
        Duration::from_secs(90),
    );
    assert_eq!(report["command_reader"], false, "{report}");
    assert_eq!(vehicle(&skein, "uav-1")["state"], "Landed");

    // The DDS link is supervised: a panic restarts it and it publishes on.
    let (status, body) = skein.post(
        "/api/v1/faults",
        serde_json::json!({"target": "coordinator/dds", "kind": "panic"}),
    );
    assert_eq!(status, 202, "{body}");
    eventually(
        "the DDS link restarted",
        Duration::from_secs(10),
        || match skein.restarts("coordinator/dds") {
            1 => Ok(()),
            n => Err(format!("{n} restarts")),
        },
    );
    let before = skein.dds_samples("published");
    eventually(
        "publishing after the restart",
        Duration::from_secs(10),
        || match skein.dds_samples("published") {
            n if n >= before + 10 => Ok(()),
            n => Err(format!("{n} published, {before} before")),
        },
    );
}

#[test]
fn counter_uas_tracks_reach_a_cyclonedds_peer() {
    let dir = build_plugins("dds-tracking-plugins");
    let d = domain(2);
    let skein = up_with_intruder_pass_and(
        &dir,
        5.0,
        &["--dds", "--domain-id", &d, "--dds-network", "127.0.0.1"],
    );
    skein.take_off(4, 10.0);
    skein.point_gimbals(&OBSERVERS, 90.0, 3.0);
    eventually("a confirmed track", Duration::from_secs(120), || {
        let (_, t) = skein.get("/api/v1/tracks");
        match t["tracks"].as_array() {
            Some(ts) if ts.iter().any(|t| t["status"] == "confirmed") => Ok(()),
            _ => Err(t.to_string()),
        }
    });
    let report = peer(&skein, &d, "uav-1", &["--tracks"], Duration::from_secs(60));
    assert!(
        report["worst_track_error_m"].as_f64().unwrap() < 3.0,
        "{report}"
    );
}

#[test]
fn bench_dds_reports_cpu_and_pose_latency() {
    let d = domain(3);
    let report = bench_report(
        &[
            "dds",
            "--vehicles",
            "2",
            "--seconds",
            "2",
            "--domain-id",
            &d,
        ],
        "vehicles",
        Duration::from_secs(180),
    );
    for key in [
        "cpu_cores_without_dds",
        "cpu_cores_with_dds",
        "dds_cpu_per_vehicle",
    ] {
        assert!(report[key].is_number(), "{key}: {report}");
    }
    // Keep-last 1 may drop a sample a busy reader has not taken yet; most arrive, each
    // with a latency.
    let expected = report["poses_expected"].as_f64().unwrap();
    assert_eq!(expected, 40.0, "{report}");
    assert!(
        report["poses_received"].as_f64().unwrap() >= 0.8 * expected,
        "{report}"
    );
    let lat = &report["pose_latency_ms"];
    assert!(
        lat["p50"].as_f64().unwrap() <= lat["max"].as_f64().unwrap(),
        "{report}"
    );
}

/// A link held to loopback (`--dds-network 127.0.0.1`) uses no other interface, so one
/// created or removed on the same computer (a Docker bridge, a VPN, another test's
/// network plumbing) costs it no rejoin of the domain, and so no lost sample; a link on
/// every interface joins again after each change. Both run in a network namespace of the
/// test's own, where the test adds and removes a pair of interfaces, one with an address.
#[test]
fn held_to_loopback_the_link_ignores_other_interfaces_coming_and_going() {
    let ns = Namespace::new('d');
    let d = domain(0);
    let start = |extra: &[&str]| {
        let mut args = vec![
            "--http",
            "127.0.0.1:0",
            "--sim",
            "1",
            "--sim-base-port",
            "0",
            "--dds",
            "--domain-id",
            &d,
        ];
        args.extend_from_slice(extra);
        Skein::launch_in(Some(&ns.name), "up", &args).process
    };
    let held = start(&["--dds-network", "127.0.0.1"]);
    let every = start(&[]);
    let rejoined = |p: &Process, n: usize| {
        let joined = p.stderr_text().matches("joined the domain again").count();
        if joined >= n {
            Ok(())
        } else {
            Err(format!("{joined} rejoins:\n{}", p.stderr_text()))
        }
    };
    // A veth pair inside the namespace (this kernel has no dummy interfaces).
    ns.ip(&[
        "link", "add", "skd0", "type", "veth", "peer", "name", "skd1",
    ]);
    ns.ip(&["addr", "add", "10.251.0.1/24", "dev", "skd0"]);
    ns.ip(&["link", "set", "skd0", "up"]);
    ns.ip(&["link", "set", "skd1", "up"]);
    eventually(
        "a rejoin for the new interface",
        Duration::from_secs(30),
        || rejoined(&every, 1),
    );
    ns.ip(&["link", "del", "skd0"]);
    eventually(
        "a rejoin for the removed interface",
        Duration::from_secs(30),
        || rejoined(&every, 2),
    );
    // The held link polls the interfaces as often: it has looked at both changes.
    let text = held.stderr_text();
    assert!(
        !text.contains("network interfaces changed"),
        "the link held to loopback joined again:\n{text}"
    );
}
