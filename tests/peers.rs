//! Independent peers against skein: pymavlink flies a `skein sim` vehicle. The Python
//! scripts live in `tests/peers/`; their interpreter is the test venv (see
//! `support::python`).

mod support;

use std::time::Duration;
use support::{Process, free_udp_range, run_peer};

/// Starts `skein sim --vehicles n` with the PX4 SITL layout on free ports; returns the
/// process and the first target port (where vehicle 0 sends, where a client listens).
fn sim(n: u16) -> (Process, u16) {
    let targets = free_udp_range(n);
    let listens = free_udp_range(n);
    let mut p = Process::start(&[
        "sim",
        "--vehicles",
        &n.to_string(),
        "--target-base-port",
        &targets.to_string(),
        "--listen-base-port",
        &listens.to_string(),
    ]);
    p.wait_line("ready", Duration::from_secs(30));
    (p, targets)
}

fn assert_peer(script: &str, args: &[&str], timeout: Duration) {
    let (code, out, err) = run_peer(script, args, timeout);
    assert_eq!(
        code,
        Some(0),
        "{script} failed (exit {code:?})\n--- stdout\n{out}\n--- stderr\n{err}"
    );
}

#[test]
fn pymavlink_decodes_everything_and_flies_offboard() {
    let (_sim, port) = sim(1);
    assert_peer(
        "sim_pymavlink.py",
        &["--port", &port.to_string()],
        Duration::from_secs(180),
    );
}

#[test]
fn mavsdk_flies_a_simulated_vehicle_offboard() {
    let (_sim, port) = sim(1);
    assert_peer(
        "sim_mavsdk.py",
        &["--port", &port.to_string()],
        Duration::from_secs(180),
    );
}

/// MAVSDK's documented offboard start (arm, ONE setpoint, `offboard.start()`, fly) works
/// because the simulator, like PX4 v1.16, accepts OFFBOARD on one fresh setpoint.
#[test]
fn mavsdk_documented_offboard_start() {
    let (_sim, port) = sim(1);
    assert_peer(
        "sim_mavsdk.py",
        &["--port", &port.to_string(), "--documented-start"],
        Duration::from_secs(180),
    );
}

#[test]
fn the_dashboard_flies_three_vehicles_in_chromium() {
    let skein = support::Skein::sim(3);
    let url = format!("{}/", skein.base);
    let shot = std::env::temp_dir().join(format!("skein-dashboard-{}.png", std::process::id()));
    assert_peer(
        "dashboard_selenium.py",
        &["--url", &url, "--screenshot", shot.to_str().unwrap()],
        Duration::from_secs(240),
    );
}
