//! The ROS 2 peers (`tests/peers/ros2_peer.py`): rclpy on Fast DDS, Jazzy's in
//! `.venv-ros2` (with skein_msgs and tf2_msgs built) and Kilted's in `.venv-ros2-kilted`,
//! prepared by `tests/peers/ros2/setup.sh` (once per test process; the script itself
//! does nothing when all is built) and run with the environment it writes.

use super::python::run_to_end;
use super::workspace;
use serde_json::Value;
use std::path::PathBuf;
use std::process::Command;
use std::sync::OnceLock;
use std::time::Duration;

/// A ROS 2 distribution of the peers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Distro {
    /// Jazzy (Fast DDS 2.14), with skein_msgs and tf2_msgs built.
    Jazzy,
    /// Kilted (Fast DDS 3.2), the standard messages only.
    Kilted,
}

/// The Jazzy peers' environment (`.venv-ros2/skein.env`), everything prepared.
fn prepared() -> &'static Vec<(String, String)> {
    static ENV: OnceLock<Vec<(String, String)>> = OnceLock::new();
    ENV.get_or_init(|| {
        let root = workspace();
        let ok = Command::new(root.join("tests/peers/ros2/setup.sh"))
            .status()
            .expect("tests/peers/ros2/setup.sh")
            .success();
        assert!(ok, "tests/peers/ros2/setup.sh failed");
        let text = std::fs::read_to_string(root.join(".venv-ros2/skein.env"))
            .expect(".venv-ros2/skein.env");
        text.lines()
            .filter_map(|l| l.split_once('='))
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect()
    })
}

/// `distro`'s interpreter and environment.
fn ros2_env(distro: Distro) -> (PathBuf, Vec<(String, String)>) {
    let vars = prepared();
    match distro {
        Distro::Jazzy => (workspace().join(".venv-ros2/bin/python"), vars.clone()),
        Distro::Kilted => (
            workspace().join(".venv-ros2-kilted/bin/python"),
            vec![("RMW_IMPLEMENTATION".into(), "rmw_fastrtps_cpp".into())],
        ),
    }
}

/// Runs `ros2_peer.py` with `args` as a node on DDS domain `domain`, discovery kept on
/// this host (`ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`: Fast DDS then finds peers by
/// unicast on 127.0.0.1, as skein with `--dds-network 127.0.0.1` does); its one JSON
/// line once it exits 0, else panics with its output. `domain` `None`: no DDS needed.
pub fn ros2_peer(domain: Option<&str>, args: &[&str], timeout: Duration) -> Value {
    ros2_peer_on(Distro::Jazzy, domain, args, timeout)
}

/// [`ros2_peer`] on `distro`.
pub fn ros2_peer_on(
    distro: Distro,
    domain: Option<&str>,
    args: &[&str],
    timeout: Duration,
) -> Value {
    let (python, vars) = ros2_env(distro);
    let mut cmd = Command::new(python);
    cmd.arg(workspace().join("tests/peers/ros2_peer.py"))
        .args(args)
        .envs(vars.iter().map(|(k, v)| (k, v)))
        .env("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        // A peer's log goes to its stderr, not to ~/.ros.
        .env(
            "ROS_LOG_DIR",
            std::env::temp_dir().join("skein-ros2-peer-logs"),
        );
    if let Some(d) = domain {
        cmd.env("ROS_DOMAIN_ID", d);
    }
    let (code, out, err) = run_to_end(cmd, timeout);
    assert_eq!(
        code,
        Some(0),
        "ros2_peer.py ({distro:?}) {args:?} failed:\n{out}\n{err}"
    );
    let line = out.lines().last().unwrap_or_default();
    serde_json::from_str(line).unwrap_or_else(|e| panic!("{e}: {out}\n{err}"))
}
