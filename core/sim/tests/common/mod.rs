//! A small MAVLink client over real UDP for the simulator's integration tests, written
//! with `skein_mavlink::{Encoder, Decoder}` only: it is what a ground station or skein's
//! link would do, without sharing code with the simulator.
#![allow(dead_code, deprecated)]

use skein_mavlink::dialect::*;
use skein_mavlink::{DecodeStats, Decoder, Encoder, Frame, MavMessage};
use skein_model::px4::{Px4Mode, type_mask};
use skein_sim::{SimConfig, SimVehicleConfig, Simulator};
use std::collections::VecDeque;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::net::UdpSocket;

/// Client system id / component id (a GCS-like sender).
pub const CLIENT_SYSID: u8 = 245;
pub const CLIENT_COMPID: u8 = 190;

pub struct Client {
    pub sock: Arc<UdpSocket>,
    pub enc: Encoder,
    pub dec: Decoder,
    pub peer: SocketAddr,
    pub sysid: u8,
    queue: VecDeque<Frame>,
    buf: Vec<u8>,
}

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

impl Client {
    pub fn from_socket(sock: UdpSocket, peer: SocketAddr, sysid: u8, compid: u8) -> Client {
        Client {
            sock: Arc::new(sock),
            enc: Encoder::new(CLIENT_SYSID, compid),
            dec: Decoder::new(Arc::new(DecodeStats::default())),
            peer,
            sysid,
            queue: VecDeque::new(),
            buf: vec![0; 65536],
        }
    }

    /// A second client (own socket) talking to the same vehicle.
    pub async fn bind(peer: SocketAddr, sysid: u8, compid: u8) -> Client {
        let sock = UdpSocket::bind("127.0.0.1:0").await.expect("bind client");
        Client::from_socket(sock, peer, sysid, compid)
    }

    pub async fn send(&mut self, msg: &MavMessage) {
        let frame = self.enc.encode(msg);
        self.sock
            .send_to(frame.as_bytes(), self.peer)
            .await
            .expect("send");
    }

    pub async fn send_raw(&self, bytes: &[u8]) {
        self.sock.send_to(bytes, self.peer).await.expect("send raw");
    }

    /// Next frame from the vehicle, or None at the deadline.
    pub async fn next(&mut self, deadline: Instant) -> Option<Frame> {
        loop {
            if let Some(f) = self.queue.pop_front() {
                return Some(f);
            }
            let left = deadline.checked_duration_since(Instant::now())?;
            let (n, _) = tokio::time::timeout(left, self.sock.recv_from(&mut self.buf))
                .await
                .ok()?
                .expect("recv");
            let queue = &mut self.queue;
            self.dec
                .decode_datagram(&self.buf[..n], |f| queue.push_back(f));
        }
    }

    /// The bytes of the next datagram from the vehicle, or None after `timeout`.
    pub async fn next_raw(&mut self, timeout: Duration) -> Option<Vec<u8>> {
        let (n, _) = tokio::time::timeout(timeout, self.sock.recv_from(&mut self.buf))
            .await
            .ok()?
            .expect("recv");
        Some(self.buf[..n].to_vec())
    }

    /// Waits for a frame matching `pred`; frames that do not match are dropped.
    pub async fn wait_for<T>(
        &mut self,
        timeout: Duration,
        mut pred: impl FnMut(&Frame) -> Option<T>,
    ) -> Option<T> {
        let deadline = Instant::now() + timeout;
        while let Some(f) = self.next(deadline).await {
            if let Some(t) = pred(&f) {
                return Some(t);
            }
        }
        None
    }

    /// Drops everything received so far.
    pub fn clear(&mut self) {
        self.queue.clear();
        while let Ok((n, _)) = self.sock.try_recv_from(&mut self.buf) {
            let _ = n;
        }
    }

    pub async fn heartbeat(&mut self, mavtype: MavType) {
        self.send(&MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: 0,
            mavtype,
            autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
            base_mode: MavModeFlag::empty(),
            system_status: MavState::MAV_STATE_ACTIVE,
            mavlink_version: 3,
        }))
        .await;
    }

    pub fn command_long_msg(&self, command: MavCmd, p: [f32; 7], confirmation: u8) -> MavMessage {
        MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            param1: p[0],
            param2: p[1],
            param3: p[2],
            param4: p[3],
            param5: p[4],
            param6: p[5],
            param7: p[6],
            command,
            target_system: self.sysid,
            target_component: 1,
            confirmation,
        })
    }

    /// Sends a COMMAND_LONG and returns the first COMMAND_ACK for it.
    pub async fn command(&mut self, command: MavCmd, p: [f32; 7]) -> MavResult {
        let msg = self.command_long_msg(command, p, 0);
        self.send(&msg).await;
        self.wait_ack(command, Duration::from_secs(3))
            .await
            .unwrap_or_else(|| panic!("no COMMAND_ACK for {command:?}"))
    }

    pub async fn wait_ack(&mut self, command: MavCmd, timeout: Duration) -> Option<MavResult> {
        self.wait_for(timeout, |f| match &f.msg {
            MavMessage::COMMAND_ACK(a) if a.command == command => Some(a.result),
            _ => None,
        })
        .await
    }

    /// DO_SET_MODE; returns both ACKs PX4 sends.
    pub async fn set_mode(&mut self, mode: Px4Mode) -> (MavResult, MavResult) {
        let (main, sub) = mode.main_sub();
        let msg = self.command_long_msg(
            MavCmd::MAV_CMD_DO_SET_MODE,
            [1.0, f32::from(main), f32::from(sub), 0.0, 0.0, 0.0, 0.0],
            0,
        );
        self.send(&msg).await;
        let first = self
            .wait_ack(MavCmd::MAV_CMD_DO_SET_MODE, Duration::from_secs(3))
            .await
            .expect("first ACK");
        let second = self
            .wait_ack(MavCmd::MAV_CMD_DO_SET_MODE, Duration::from_secs(3))
            .await
            .expect("second ACK");
        (first, second)
    }

    pub async fn arm(&mut self, arm: bool) -> MavResult {
        self.command(
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            [if arm { 1.0 } else { 0.0 }, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        )
        .await
    }

    pub async fn param_set(
        &mut self,
        name: &str,
        value: f32,
        param_type: MavParamType,
    ) -> Vec<PARAM_VALUE_DATA> {
        self.send(&MavMessage::PARAM_SET(PARAM_SET_DATA {
            param_value: value,
            target_system: self.sysid,
            target_component: 1,
            param_id: name.into(),
            param_type,
        }))
        .await;
        let mut got = Vec::new();
        let deadline = Instant::now() + Duration::from_secs(2);
        while got.len() < 2 {
            let Some(f) = self.next(deadline).await else {
                break;
            };
            if let MavMessage::PARAM_VALUE(v) = f.msg
                && v.param_id.to_str().ok() == Some(name)
            {
                got.push(v);
            }
        }
        got
    }

    pub async fn param_set_f32(&mut self, name: &str, value: f32) {
        let got = self
            .param_set(name, value, MavParamType::MAV_PARAM_TYPE_REAL32)
            .await;
        assert!(!got.is_empty(), "no PARAM_VALUE for {name}");
        assert_eq!(got[0].param_value, value, "{name}");
    }

    pub async fn param_set_i32(&mut self, name: &str, value: i32) {
        let got = self
            .param_set(
                name,
                f32::from_bits(value as u32),
                MavParamType::MAV_PARAM_TYPE_INT32,
            )
            .await;
        assert!(!got.is_empty(), "no PARAM_VALUE for {name}");
        assert_eq!(got[0].param_value.to_bits() as i32, value, "{name}");
    }

    /// Waits for a HEARTBEAT satisfying `pred`.
    pub async fn wait_heartbeat(
        &mut self,
        timeout: Duration,
        mut pred: impl FnMut(&HEARTBEAT_DATA) -> bool,
    ) -> Option<HEARTBEAT_DATA> {
        self.wait_for(timeout, |f| match &f.msg {
            MavMessage::HEARTBEAT(h) if f.compid == 1 && pred(h) => Some(h.clone()),
            _ => None,
        })
        .await
    }

    pub async fn wait_mode(&mut self, mode: Px4Mode, timeout: Duration) -> bool {
        self.wait_heartbeat(timeout, |h| h.custom_mode == mode.custom_mode())
            .await
            .is_some()
    }

    pub async fn wait_armed(&mut self, armed: bool, timeout: Duration) -> bool {
        self.wait_heartbeat(timeout, |h| {
            h.base_mode
                .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED)
                == armed
        })
        .await
        .is_some()
    }

    /// Waits for LOCAL_POSITION_NED satisfying `pred`; returns it.
    pub async fn wait_local(
        &mut self,
        timeout: Duration,
        mut pred: impl FnMut(&LOCAL_POSITION_NED_DATA) -> bool,
    ) -> Option<LOCAL_POSITION_NED_DATA> {
        self.wait_for(timeout, |f| match &f.msg {
            MavMessage::LOCAL_POSITION_NED(p) if pred(p) => Some(p.clone()),
            _ => None,
        })
        .await
    }

    /// Waits until the vehicle reports a home position (EKF has a fix).
    pub async fn wait_home(&mut self) -> HOME_POSITION_DATA {
        self.wait_for(Duration::from_secs(5), |f| match &f.msg {
            MavMessage::HOME_POSITION(h) => Some(h.clone()),
            _ => None,
        })
        .await
        .expect("HOME_POSITION")
    }
}

/// A position-target message for `sysid`.
pub fn setpoint(sysid: u8, mask: u16, pos: [f32; 3], vel: [f32; 3], yaw: f32) -> MavMessage {
    MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
        time_boot_ms: 0,
        x: pos[0],
        y: pos[1],
        z: pos[2],
        vx: vel[0],
        vy: vel[1],
        vz: vel[2],
        afx: 0.0,
        afy: 0.0,
        afz: 0.0,
        yaw,
        yaw_rate: 0.0,
        type_mask: PositionTargetTypemask::from_bits_retain(mask),
        target_system: sysid,
        target_component: 1,
        coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
    })
}

pub fn position_setpoint(sysid: u8, n: f32, e: f32, d: f32) -> MavMessage {
    setpoint(sysid, type_mask::POSITION_YAW, [n, e, d], [0.0; 3], 0.0)
}

/// Streams setpoints at a fixed rate from the client's socket until stopped.
pub struct Streamer {
    current: Arc<Mutex<MavMessage>>,
    task: tokio::task::JoinHandle<()>,
    pub started: Instant,
}

impl Streamer {
    /// Streams `msg` (changeable with [`Streamer::set`]).
    pub fn start(client: &Client, msg: MavMessage, rate_hz: f64) -> Streamer {
        let current = Arc::new(Mutex::new(msg));
        let shared = current.clone();
        Self::spawn(client, rate_hz, current, move |_| {
            shared.lock().expect("lock").clone()
        })
    }

    /// Streams `f(seconds since start)`.
    pub fn start_fn(
        client: &Client,
        rate_hz: f64,
        f: impl Fn(f64) -> MavMessage + Send + 'static,
    ) -> Streamer {
        let current = Arc::new(Mutex::new(f(0.0)));
        Self::spawn(client, rate_hz, current, f)
    }

    fn spawn(
        client: &Client,
        rate_hz: f64,
        current: Arc<Mutex<MavMessage>>,
        f: impl Fn(f64) -> MavMessage + Send + 'static,
    ) -> Streamer {
        let sock = client.sock.clone();
        let peer = client.peer;
        let started = Instant::now();
        let task = tokio::spawn(async move {
            let mut enc = Encoder::new(CLIENT_SYSID, CLIENT_COMPID + 1);
            let mut iv = tokio::time::interval(Duration::from_secs_f64(1.0 / rate_hz));
            loop {
                iv.tick().await;
                let msg = f(started.elapsed().as_secs_f64());
                let frame = enc.encode(&msg);
                let _ = sock.send_to(frame.as_bytes(), peer).await;
            }
        });
        Streamer {
            current,
            task,
            started,
        }
    }

    pub fn set(&self, msg: MavMessage) {
        *self.current.lock().expect("lock") = msg;
    }

    pub fn stop(self) {
        self.task.abort();
    }
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
