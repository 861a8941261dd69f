//! What the link's integration tests share: polling a condition with a deadline, and the
//! HEARTBEAT a vehicle (or a ground station) sends.
#![allow(dead_code)]

use skein_mavlink::MavMessage;
use skein_mavlink::dialect::*;
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
