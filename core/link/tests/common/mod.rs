//! What the link's integration tests share: polling a condition with a deadline, the
//! HEARTBEAT a vehicle (or a ground station) sends, and a serial endpoint on a
//! pseudo-terminal.
#![allow(dead_code)]

pub mod vehicle;

use skein_link::{ConnectionAddress, Endpoint, Identity};
use skein_mavlink::MavMessage;
use skein_mavlink::dialect::*;
use std::os::fd::OwnedFd;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Polls `f` every 10 ms until it gives a value; panics naming `what` after `timeout`.
pub async fn eventually<T>(what: &str, timeout: Duration, mut f: impl FnMut() -> Option<T>) -> T {
    let deadline = Instant::now() + timeout;
    loop {
        if let Some(v) = f() {
            return v;
        }
        assert!(
            Instant::now() < deadline,
            "timed out after {timeout:?} waiting for {what}"
        );
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
}

/// A quadrotor's HEARTBEAT from `autopilot` (`MAV_AUTOPILOT_PX4`: a vehicle the endpoint
/// discovers; `MAV_AUTOPILOT_INVALID`: a ground station's, which it does not).
pub fn heartbeat(autopilot: MavAutopilot) -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_STANDBY,
        mavlink_version: 3,
    })
}

/// A `serial:` endpoint (57600 baud) on the slave side of a new pseudo-terminal pair, and
/// the pair's master side, where the test plays the flight controller; and the slave's
/// descriptor, to close when the test is done (the master's reads then end).
pub async fn serial_endpoint() -> (Arc<Endpoint>, OwnedFd, OwnedFd) {
    let pty = nix::pty::openpty(None, None).unwrap();
    let path = nix::unistd::ttyname(&pty.slave).unwrap();
    let conn: ConnectionAddress = format!("serial:{}:57600", path.display()).parse().unwrap();
    let endpoint = Endpoint::open(conn, Identity::default()).await.unwrap();
    (endpoint, pty.master, pty.slave)
}
