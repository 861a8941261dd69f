//! What the simulator's integration tests share: a ground station written once
//! ([`GroundStation`]) over real UDP ([`Client`], its own socket and `skein_mavlink`'s
//! encoder and decoder: what a ground station or skein's link would do, without sharing
//! code with the simulator) or on the virtual clock ([`VirtualClient`]), the simulator
//! started for `n` clients, setpoint messages, polling with a deadline, a ULog reader
//! ([`ULog`]) and RTK corrections as a caster sends them ([`Caster`]).
#![allow(dead_code, deprecated)]

mod rtcm;
mod station;
mod udp;
mod ulog;
mod virtual_station;

// Each test binary uses its own part of these.
#[allow(unused_imports)]
pub use rtcm::{Caster, base_position_1005, crc24q, frame_number, msm7_payload, rtcm_frame};
#[allow(unused_imports)]
pub use station::{GroundStation, set_mode_msg};
#[allow(unused_imports)]
pub use udp::{Client, Streamer, clear_through};
#[allow(unused_imports)]
pub use ulog::{ULog, ULogField};
#[allow(unused_imports)]
pub use virtual_station::{VirtualClient, start_virtual};

use skein_mavlink::MavMessage;
use skein_model::geo::Ned;
use skein_model::px4::type_mask;
use skein_sim::client;
use skein_sim::{SimConfig, SimVehicleConfig, Simulator};
use std::time::{Duration, Instant};
use tokio::net::UdpSocket;

/// The UDP clients' system id (a GCS-like sender).
pub const CLIENT_SYSID: u8 = 245;
/// The UDP clients' component id (`MAV_COMP_ID_MISSIONPLANNER`).
pub const CLIENT_COMPID: u8 = 190;

/// Starts a simulator with `n` vehicles whose targets are `n` fresh client sockets;
/// `tweak` edits the configuration first.
pub async fn start(n: usize, tweak: impl FnOnce(&mut SimConfig)) -> (Simulator, Vec<Client>) {
    let mut socks = Vec::new();
    for _ in 0..n {
        socks.push(UdpSocket::bind("127.0.0.1:0").await.expect("bind client"));
    }
    let vehicles = socks
        .iter()
        .enumerate()
        .map(|(i, s)| SimVehicleConfig {
            sysid: (i + 1) as u8,
            bind: "127.0.0.1:0".parse().expect("addr"),
            target: s.local_addr().expect("addr"),
        })
        .collect();
    let mut cfg = SimConfig::with_vehicles(vehicles);
    cfg.ekf_fix_delay_s = 0.2;
    tweak(&mut cfg);
    let sim = Simulator::start(cfg).await.expect("start simulator");
    let infos = sim.vehicles();
    let clients = socks
        .into_iter()
        .zip(infos)
        .map(|(s, info)| Client::from_socket(s, info.bound, info.sysid, CLIENT_COMPID))
        .collect();
    (sim, clients)
}

/// A position-target message for `sysid`: position (m) and velocity (m/s), local NED,
/// and yaw (rad) as `mask` selects.
pub fn setpoint(sysid: u8, mask: u16, pos: [f32; 3], vel: [f32; 3], yaw: f32) -> MavMessage {
    let ned = |v: [f32; 3]| Ned::new(v[0].into(), v[1].into(), v[2].into());
    let mut msg = client::setpoint(mask, ned(pos), ned(vel), Ned::ZERO, yaw.into());
    if let MavMessage::SET_POSITION_TARGET_LOCAL_NED(sp) = &mut msg {
        sp.target_system = sysid;
    }
    msg
}

/// A position + yaw setpoint for `sysid` at north `n`, east `e`, down `d` (m).
pub fn position_setpoint(sysid: u8, n: f32, e: f32, d: f32) -> MavMessage {
    setpoint(sysid, type_mask::POSITION_YAW, [n, e, d], [0.0; 3], 0.0)
}

/// Polls `cond` every 20 ms until it holds or `timeout` passes.
pub async fn eventually(timeout: Duration, mut cond: impl FnMut() -> bool) -> bool {
    let deadline = Instant::now() + timeout;
    loop {
        if cond() {
            return true;
        }
        if Instant::now() >= deadline {
            return false;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}
