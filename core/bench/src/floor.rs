//! `skein bench swarm --peer floor`: the least any controller could spend holding the
//! same swarm, measured in the same run (issue 47).
//!
//! The floor is a minimal controller on a thread of this process (`skein-floor`) against
//! a fresh simulator process of the same profile, with the run's `--vehicles-per-port`
//! (one `udpin` socket per group of vehicles on a free block of ports, as skein's
//! endpoints; vehicles of a port are told apart by sysid). It does nothing but the
//! datagrams:
//!
//! - **Setup** (not measured): it decodes telemetry with `skein_mavlink`, heartbeats as a
//!   ground station at 1 Hz, asks each vehicle for skein's telemetry of the run (the
//!   `swarm` profile's `MAV_CMD_SET_MESSAGE_INTERVAL`s, as skein's link does on first
//!   contact, so that both drain the same telemetry), streams
//!   `SET_POSITION_TARGET_LOCAL_NED` (type_mask 2552, position + yaw) to each vehicle's
//!   hold point (where it stands, `--altitude-m` up), then sends `MAV_CMD_DO_SET_MODE` to
//!   offboard (PX4 main mode 6) and arms, as the pymavlink loop does, until every vehicle
//!   is armed, in offboard and within 0.5 m of its hold altitude. Every vehicle locks
//!   onto the socket of its own port then.
//! - **Window** (`--seconds`, measured): the setpoint frame of every vehicle is encoded
//!   once beforehand (its MAVLink sequence number stays fixed: the simulator takes the
//!   repeats, every one counted in `setpoints_received`); every period (1 / `--rate-hz`)
//!   one `sendmmsg(2)` from the first port's socket hands every vehicle's frame to the kernel
//!   (one call per 1024 vehicles, the kernel's `UIO_MAXIOV`), once a second a second call
//!   sends the heartbeats, and `recvmmsg(2)` drains every socket's telemetry, counting
//!   datagrams and bytes without decoding them.
//!
//! Its CPU is the `skein-floor` thread's time on a CPU over the window, from its
//! `/proc/thread-self/schedstat` (nanoseconds, as skein's per-thread figures); the
//! simulator's summary gives lateness and offboard state the same way as for skein and
//! the pymavlink loop (`crate::peer`).

use crate::SwarmBenchArgs;
use crate::sim_process::SimProcess;
use crate::stack::candidate_base;
use nix::sys::socket::{MsgFlags, MultiHeaders, SockaddrStorage, recvmmsg, sendmmsg};
use serde_json::{Value, json};
use skein_link::TelemetryProfile;
use skein_mavlink::dialect::{
    HEARTBEAT_DATA, MavAutopilot, MavCmd, MavFrame, MavModeFlag, MavState, MavType,
    PositionTargetTypemask, SET_POSITION_TARGET_LOCAL_NED_DATA,
};
use skein_mavlink::{CommandTarget, Decoder, Encoder, MavMessage, command_long};
use std::collections::HashMap;
use std::io::{IoSlice, IoSliceMut};
use std::net::{SocketAddr, UdpSocket};
use std::os::fd::AsRawFd;
use std::sync::mpsc;
use std::time::{Duration, Instant};
use tokio::sync::oneshot;

/// PX4's offboard main mode (`custom_mode >> 16`).
const PX4_OFFBOARD_MAIN_MODE: u32 = 6;
/// Most datagrams one `sendmmsg(2)` takes (the kernel's `UIO_MAXIOV`).
const MAX_SEND_BATCH: usize = 1024;
/// Datagrams one `recvmmsg(2)` call takes.
const RECV_BATCH: usize = 16;
/// Largest telemetry datagram read, bytes (the simulator stays below 1472).
const MAX_DATAGRAM: usize = 2048;
/// Altitude error within which a vehicle counts as hovering at its hold point, m.
const HOVER_TOLERANCE_M: f32 = 0.5;

/// Flies the swarm of `args` with the floor controller and returns its figures, shaped
/// as the pymavlink loop's (`cpu_s` over the window, `cpu_ms_per_vehicle_second`,
/// `late_fraction`, `offboard_loss_failsafes`, `all_offboard`, …) plus the floor's own
/// counts.
///
/// # Errors
/// No free block of ports, the simulator failing, or the vehicles not hovering in time.
pub(crate) async fn floor(args: &SwarmBenchArgs) -> Result<Value, String> {
    let setup_s = args
        .setup_timeout_s
        .unwrap_or(60.0 + 0.1 * args.vehicles as f64);
    let ports = args.vehicles.div_ceil(args.vehicles_per_port.max(1));
    let mut last = String::new();
    for attempt in 0..20 {
        let base = candidate_base(ports, 200 + attempt)
            .ok_or("no block of free UDP ports for the floor controller")?;
        match bind(base, ports) {
            Ok(sockets) => return fly(args, sockets, base, setup_s).await,
            // A port of the block is taken: another block.
            Err(e) => last = format!("floor controller: port block {base}: {e}"),
        }
    }
    Err(last)
}

/// Binds `ports` non-blocking UDP sockets on 127.0.0.1 from `base` on.
fn bind(base: u16, ports: usize) -> std::io::Result<Vec<UdpSocket>> {
    (0..ports)
        .map(|p| {
            let s = UdpSocket::bind(SocketAddr::new(crate::stack::LOCALHOST, base + p as u16))?;
            s.set_nonblocking(true)?;
            Ok(s)
        })
        .collect()
}

/// Starts the simulator on the ports from `base`, the floor thread on `sockets`, and
/// measures the window once every vehicle hovers.
async fn fly(
    args: &SwarmBenchArgs,
    sockets: Vec<UdpSocket>,
    base: u16,
    setup_s: f64,
) -> Result<Value, String> {
    let mut sim = SimProcess::start(args, base).await?;
    let (ready_tx, ready_rx) = oneshot::channel();
    let (go_tx, go_rx) = mpsc::channel();
    let (done_tx, done_rx) = oneshot::channel();
    let plan = Plan::new(args, setup_s);
    let spawned = std::thread::Builder::new()
        .name("skein-floor".into())
        .spawn(move || {
            let result = match hover(&plan, &sockets, ready_tx, &go_rx) {
                Ok(fleet) => Ok(measure(&plan, &sockets, &fleet)),
                Err(e) => Err(e),
            };
            let _ = done_tx.send(result);
        });
    if let Err(e) = spawned {
        sim.stop().await;
        return Err(format!("cannot start the floor thread: {e}"));
    }
    // Dropping `go_tx` (an error below) stops the thread.
    let ready = tokio::time::timeout(Duration::from_secs_f64(setup_s + 30.0), ready_rx).await;
    let ready = match ready {
        Ok(Ok(Ok(()))) => Ok(()),
        Ok(Ok(Err(e))) => Err(e),
        Ok(Err(_)) => Err("the floor controller ended before it was ready".into()),
        Err(_) => Err("the floor controller did not get ready in time".into()),
    };
    if let Err(e) = ready {
        sim.stop().await;
        return Err(e);
    }
    let window = window(args, &mut sim, go_tx, done_rx).await;
    sim.stop().await;
    window
}

/// The measured window, once the floor hovers: resets the simulator, lets the thread go,
/// and reads the simulator's summary and CPU when it is done.
async fn window(
    args: &SwarmBenchArgs,
    sim: &mut SimProcess,
    go: mpsc::Sender<()>,
    done: oneshot::Receiver<Result<Window, String>>,
) -> Result<Value, String> {
    sim.ask("reset").await?;
    let sim_cpu0 = sim.pid.and_then(|p| crate::cpu_seconds(Some(p)));
    go.send(())
        .map_err(|_| "the floor controller ended before the window")?;
    let wait = Duration::from_secs_f64(args.seconds + 30.0);
    let floor = match tokio::time::timeout(wait, done).await {
        Ok(Ok(Ok(w))) => w,
        Ok(Ok(Err(e))) => return Err(e),
        _ => return Err("the floor controller did not report".into()),
    };
    let summary = sim.ask("summary").await?;
    let sim_cpu1 = sim.pid.and_then(|p| crate::cpu_seconds(Some(p)));
    let sim_cpu_s = match (sim_cpu0, sim_cpu1) {
        (Some(a), Some(b)) => json!(crate::round(b - a, 2)),
        _ => Value::Null,
    };
    let own = json!({
        "cpu_s": floor.cpu_s.map(|c| crate::round(c, 4)),
        "setpoints_sent": floor.setpoints_sent,
    });
    let pid = Some(std::process::id());
    let mut report = crate::peer::peer_report("floor", args, pid, &own, &summary, sim_cpu_s);
    report["cpu_source"] = json!("schedstat of the skein-floor thread");
    report["vehicles_per_port"] = json!(args.vehicles_per_port);
    report["window_s"] = json!(crate::round(floor.seconds, 3));
    report["sendmmsg_calls"] = json!(floor.send_calls);
    report["send_drops"] = json!(floor.send_drops);
    report["heartbeats_sent"] = json!(floor.heartbeats_sent);
    report["telemetry_datagrams"] = json!(floor.telemetry_datagrams);
    report["telemetry_bytes"] = json!(floor.telemetry_bytes);
    report["late_ticks"] = json!(floor.late_ticks);
    report["sim_datagrams_sent"] = summary["datagrams_sent"].clone();
    Ok(report)
}

/// What the floor thread needs from the arguments.
struct Plan {
    /// Vehicles.
    vehicles: usize,
    /// Vehicles per port.
    per_port: usize,
    /// Setpoint period.
    period: Duration,
    /// Measurement window.
    seconds: Duration,
    /// Climb above where each vehicle stands, m.
    altitude_m: f32,
    /// Longest setup.
    setup: Duration,
}

impl Plan {
    fn new(args: &SwarmBenchArgs, setup_s: f64) -> Plan {
        Plan {
            vehicles: args.vehicles,
            per_port: args.vehicles_per_port.max(1),
            period: Duration::from_secs_f64(1.0 / args.rate_hz),
            seconds: Duration::from_secs_f64(args.seconds),
            altitude_m: args.altitude_m as f32,
            setup: Duration::from_secs_f64(setup_s),
        }
    }
}

/// One simulated vehicle as the floor knows it.
#[derive(Debug, Clone, Default)]
struct Known {
    /// The vehicle's own socket in the simulator (where its datagrams come from).
    addr: Option<SocketAddr>,
    /// Its system id.
    sysid: u8,
    /// Its last `LOCAL_POSITION_NED`, m (north, east, down).
    position: Option<[f32; 3]>,
    /// Where it is held, m (north, east, down).
    hold: Option<[f32; 3]>,
    /// Armed, by its last heartbeat.
    armed: bool,
    /// In offboard, by its last heartbeat.
    offboard: bool,
    /// Asked for the telemetry profile.
    configured: bool,
}

impl Known {
    fn hovering(&self) -> bool {
        let (Some(p), Some(h)) = (self.position, self.hold) else {
            return false;
        };
        self.armed && self.offboard && (p[2] - h[2]).abs() < HOVER_TOLERANCE_M
    }
}

/// Setpoint message holding vehicle `sysid` at `hold` (north, east, down, m).
fn setpoint(sysid: u8, hold: [f32; 3]) -> MavMessage {
    MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
        time_boot_ms: 0,
        x: hold[0],
        y: hold[1],
        z: hold[2],
        vx: 0.0,
        vy: 0.0,
        vz: 0.0,
        afx: 0.0,
        afy: 0.0,
        afz: 0.0,
        yaw: 0.0,
        yaw_rate: 0.0,
        type_mask: PositionTargetTypemask::from_bits_truncate(
            skein_model::px4::type_mask::POSITION_YAW,
        ),
        target_system: sysid,
        target_component: 1,
        coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
    })
}

/// A ground station's heartbeat.
fn heartbeat() -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_GCS,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    })
}

/// Takes every vehicle off to its hold point (see the module docs), says so on `ready`,
/// and keeps holding them until `go` (not measured). Returns the vehicles, every one
/// with its address and hold point.
fn hover(
    plan: &Plan,
    sockets: &[UdpSocket],
    ready: oneshot::Sender<Result<(), String>>,
    go: &mpsc::Receiver<()>,
) -> Result<Vec<Known>, String> {
    let n = plan.vehicles;
    let mut fleet: Vec<Known> = (0..n)
        .map(|i| Known {
            sysid: skein_sim::instance_sysid(i, n),
            ..Known::default()
        })
        .collect();
    let index: HashMap<(usize, u8), usize> = (0..n)
        .map(|i| ((i / plan.per_port, fleet[i].sysid), i))
        .collect();
    let mut decoder = Decoder::new(Default::default());
    let mut encoder = Encoder::new(255, 190);
    let beat = encoder.encode(&heartbeat()).as_bytes().to_vec();
    let deadline = Instant::now() + plan.setup;
    let mut ready = Some(ready);
    let mut next_beat = Instant::now();
    loop {
        if Instant::now() >= next_beat {
            next_beat += Duration::from_secs(1);
            for (i, v) in fleet.iter().enumerate() {
                if let Some(a) = v.addr {
                    let _ = sockets[i / plan.per_port].send_to(&beat, a);
                }
            }
        }
        listen(sockets, &index, &mut fleet, &mut decoder, plan.altitude_m);
        for (i, v) in fleet.iter_mut().enumerate() {
            command(&sockets[i / plan.per_port], &mut encoder, v);
        }
        if ready.is_some()
            && fleet.iter().all(Known::hovering)
            && let Some(r) = ready.take()
        {
            let _ = r.send(Ok(()));
        }
        if ready.is_none() {
            match go.try_recv() {
                Ok(()) => return Ok(fleet),
                Err(mpsc::TryRecvError::Disconnected) => {
                    return Err("the benchmark stopped the floor controller".into());
                }
                Err(mpsc::TryRecvError::Empty) => {}
            }
        } else if Instant::now() > deadline {
            let e = not_hovering(plan, &fleet);
            if let Some(r) = ready.take() {
                let _ = r.send(Err(e.clone()));
            }
            return Err(e);
        }
        std::thread::sleep(plan.period);
    }
}

/// Why the setup failed: how far the vehicles got.
fn not_hovering(plan: &Plan, fleet: &[Known]) -> String {
    let count = |f: &dyn Fn(&Known) -> bool| fleet.iter().filter(|v| f(v)).count();
    let unheard: Vec<usize> = (0..fleet.len())
        .filter(|&i| fleet[i].addr.is_none())
        .take(10)
        .collect();
    format!(
        "floor controller: not all {} vehicles hovering in {:.0} s: {} heard, {} placed, \
         {} in offboard, {} armed, {} hovering (never heard: vehicles {:?})",
        plan.vehicles,
        plan.setup.as_secs_f64(),
        count(&|v| v.addr.is_some()),
        count(&|v| v.position.is_some()),
        count(&|v| v.offboard),
        count(&|v| v.armed),
        count(&|v| v.hovering()),
        unheard,
    )
}

/// Reads and decodes every socket's telemetry into `fleet`; a vehicle placed for the
/// first time gets its hold point, `altitude_m` above where it stands.
fn listen(
    sockets: &[UdpSocket],
    index: &HashMap<(usize, u8), usize>,
    fleet: &mut [Known],
    decoder: &mut Decoder,
    altitude_m: f32,
) {
    let mut buf = [0u8; MAX_DATAGRAM];
    for (port, socket) in sockets.iter().enumerate() {
        while let Ok((len, from)) = socket.recv_from(&mut buf) {
            decoder.decode_datagram(&buf[..len], |f| {
                let Some(v) = index.get(&(port, f.sysid)).map(|&i| &mut fleet[i]) else {
                    return;
                };
                match f.msg {
                    MavMessage::HEARTBEAT(h)
                        if h.autopilot != MavAutopilot::MAV_AUTOPILOT_INVALID =>
                    {
                        v.addr = Some(from);
                        v.armed = h
                            .base_mode
                            .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
                        v.offboard = (h.custom_mode >> 16) & 0xFF == PX4_OFFBOARD_MAIN_MODE;
                    }
                    MavMessage::LOCAL_POSITION_NED(p) => {
                        v.position = Some([p.x, p.y, p.z]);
                        v.hold.get_or_insert([p.x, p.y, p.z - altitude_m]);
                    }
                    _ => {}
                }
            });
        }
    }
}

/// One setup period's frames to vehicle `v` (once heard): skein's telemetry profile the
/// first time; once placed, its setpoint, then offboard until it is, then arm until it is
/// (PX4 v1.16 takes offboard after one setpoint).
fn command(socket: &UdpSocket, encoder: &mut Encoder, v: &mut Known) {
    let Some(addr) = v.addr else {
        return;
    };
    let target = CommandTarget::new(v.sysid, 1);
    if !v.configured {
        v.configured = true;
        for (id, rate_hz) in TelemetryProfile::Swarm.rates() {
            let us = skein_link::setup::interval_us(rate_hz) as f32;
            let params = [id as f32, us, 0.0, 0.0, 0.0, 0.0, 0.0];
            let m = command_long(target, MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL, params, 0);
            let _ = socket.send_to(encoder.encode(&m).as_bytes(), addr);
        }
    }
    let Some(hold) = v.hold else {
        return;
    };
    let custom = f32::from(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED.bits());
    let mut msgs = vec![setpoint(v.sysid, hold)];
    if !v.offboard {
        let params = [
            custom,
            PX4_OFFBOARD_MAIN_MODE as f32,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
        ];
        msgs.push(command_long(target, MavCmd::MAV_CMD_DO_SET_MODE, params, 0));
    } else if !v.armed {
        let params = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        msgs.push(command_long(
            target,
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            params,
            0,
        ));
    }
    for m in &msgs {
        let _ = socket.send_to(encoder.encode(m).as_bytes(), addr);
    }
}

/// The floor's own figures over the window.
#[derive(Debug, Default)]
struct Window {
    /// CPU of the floor thread, s (`None` without `/proc`).
    cpu_s: Option<f64>,
    /// Length of the window, s.
    seconds: f64,
    /// Setpoint datagrams the kernel took.
    setpoints_sent: u64,
    /// Heartbeat datagrams the kernel took.
    heartbeats_sent: u64,
    /// `sendmmsg(2)` calls.
    send_calls: u64,
    /// Datagrams the kernel refused (full socket buffer), dropped.
    send_drops: u64,
    /// Telemetry datagrams read.
    telemetry_datagrams: u64,
    /// Telemetry bytes read.
    telemetry_bytes: u64,
    /// Periods that started later than the next one was due.
    late_ticks: u64,
}

/// The measured window (see the module docs): pre-encoded frames, one `sendmmsg(2)` per
/// period, `recvmmsg(2)` drains; the thread's CPU over it.
fn measure(plan: &Plan, sockets: &[UdpSocket], fleet: &[Known]) -> Window {
    let mut encoder = Encoder::new(255, 190);
    let frames: Vec<Vec<u8>> = fleet
        .iter()
        .map(|v| {
            let hold = v.hold.unwrap_or_default();
            encoder.encode(&setpoint(v.sysid, hold)).as_bytes().to_vec()
        })
        .collect();
    let beat = encoder.encode(&heartbeat()).as_bytes().to_vec();
    let setpoints: Vec<[IoSlice<'_>; 1]> = frames.iter().map(|f| [IoSlice::new(f)]).collect();
    let beats: Vec<[IoSlice<'_>; 1]> = fleet.iter().map(|_| [IoSlice::new(&beat)]).collect();
    let addrs: Vec<Option<SockaddrStorage>> = fleet
        .iter()
        .map(|v| v.addr.map(SockaddrStorage::from))
        .collect();
    let mut send =
        MultiHeaders::<SockaddrStorage>::preallocate(fleet.len().min(MAX_SEND_BATCH), None);
    let mut recv = MultiHeaders::<SockaddrStorage>::preallocate(RECV_BATCH, None);
    let mut bufs = [[0u8; MAX_DATAGRAM]; RECV_BATCH];
    let fd = sockets[0].as_raw_fd();
    let mut w = Window::default();
    let cpu0 = thread_cpu_s();
    let t0 = Instant::now();
    let (mut next_tick, mut next_beat) = (t0, t0);
    while t0.elapsed() < plan.seconds {
        w.setpoints_sent += send_all(fd, &mut send, &setpoints, &addrs, &mut w);
        if Instant::now() >= next_beat {
            next_beat += Duration::from_secs(1);
            w.heartbeats_sent += send_all(fd, &mut send, &beats, &addrs, &mut w);
        }
        for s in sockets {
            drain(s, &mut recv, &mut bufs, &mut w);
        }
        next_tick += plan.period;
        let now = Instant::now();
        if next_tick > now {
            std::thread::sleep(next_tick - now);
        } else {
            w.late_ticks += 1;
            if now - next_tick > plan.period {
                next_tick = now;
            }
        }
    }
    w.seconds = t0.elapsed().as_secs_f64();
    w.cpu_s = cpu0.zip(thread_cpu_s()).map(|(a, b)| b - a);
    w
}

/// Sends datagram `k` of `iov` to `addrs[k]` for every `k` from socket `fd`, in as few
/// `sendmmsg(2)` calls as the kernel takes (one per [`MAX_SEND_BATCH`]); a datagram the
/// kernel refuses is dropped and counted. Returns how many left.
fn send_all(
    fd: std::os::fd::RawFd,
    headers: &mut MultiHeaders<SockaddrStorage>,
    iov: &[[IoSlice<'_>; 1]],
    addrs: &[Option<SockaddrStorage>],
    w: &mut Window,
) -> u64 {
    let mut sent = 0;
    let mut at = 0;
    while at < iov.len() {
        let end = iov.len().min(at + MAX_SEND_BATCH);
        w.send_calls += 1;
        let taken = sendmmsg(
            fd,
            headers,
            &iov[at..end],
            &addrs[at..end],
            [],
            MsgFlags::MSG_DONTWAIT,
        )
        .map_or(0, |r| r.count());
        sent += taken as u64;
        at += taken;
        if at < end {
            // The first datagram the kernel refused: dropped, and on with the rest.
            w.send_drops += 1;
            at += 1;
        }
    }
    sent
}

/// Reads everything waiting on `socket`, [`RECV_BATCH`] datagrams a `recvmmsg(2)` call,
/// counting datagrams and bytes without decoding them.
fn drain(
    socket: &UdpSocket,
    headers: &mut MultiHeaders<SockaddrStorage>,
    bufs: &mut [[u8; MAX_DATAGRAM]; RECV_BATCH],
    w: &mut Window,
) {
    loop {
        let mut iov = bufs.each_mut().map(|b| [IoSliceMut::new(b)]);
        let Ok(got) = recvmmsg(
            socket.as_raw_fd(),
            headers,
            iov.iter_mut(),
            MsgFlags::MSG_DONTWAIT,
            None,
        ) else {
            return; // nothing waiting (EAGAIN)
        };
        let mut count = 0;
        for m in got {
            count += 1;
            w.telemetry_bytes += m.bytes as u64;
        }
        w.telemetry_datagrams += count;
        if count < RECV_BATCH as u64 {
            return;
        }
    }
}

/// This thread's time on a CPU so far, s, from `/proc/thread-self/schedstat` (exact, in
/// nanoseconds); `None` without `/proc`.
fn thread_cpu_s() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    let ns: u64 = s.split_whitespace().next()?.parse().ok()?;
    Some(ns as f64 / 1e9)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_sendmmsg_reaches_every_vehicle_and_drains_count_without_decoding() {
        let sockets = bind_any(4);
        let frames: Vec<Vec<u8>> = (0..3u8).map(|i| vec![i; 40 + usize::from(i)]).collect();
        let iov: Vec<[IoSlice<'_>; 1]> = frames.iter().map(|f| [IoSlice::new(f)]).collect();
        let addrs: Vec<Option<SockaddrStorage>> = sockets[1..]
            .iter()
            .map(|s| s.local_addr().ok().map(SockaddrStorage::from))
            .collect();
        let mut headers = MultiHeaders::<SockaddrStorage>::preallocate(3, None);
        let mut w = Window::default();
        let fd = sockets[0].as_raw_fd();
        assert_eq!(send_all(fd, &mut headers, &iov, &addrs, &mut w), 3);
        assert_eq!((w.send_calls, w.send_drops), (1, 0));
        let mut recv = MultiHeaders::<SockaddrStorage>::preallocate(RECV_BATCH, None);
        let mut bufs = [[0u8; MAX_DATAGRAM]; RECV_BATCH];
        let deadline = Instant::now() + Duration::from_secs(5);
        while w.telemetry_datagrams < 3 && Instant::now() < deadline {
            for s in &sockets[1..] {
                drain(s, &mut recv, &mut bufs, &mut w);
            }
        }
        assert_eq!(w.telemetry_datagrams, 3);
        assert_eq!(w.telemetry_bytes, 40 + 41 + 42);
    }

    fn bind_any(n: usize) -> Vec<UdpSocket> {
        (0..n)
            .map(|_| {
                let s = UdpSocket::bind("127.0.0.1:0").expect("bind");
                s.set_nonblocking(true).expect("non-blocking");
                s
            })
            .collect()
    }

    #[test]
    fn hovering_needs_armed_offboard_and_the_hold_altitude() {
        let mut v = Known {
            position: Some([0.0, 0.0, -1.8]),
            hold: Some([0.0, 0.0, -2.0]),
            armed: true,
            offboard: true,
            ..Known::default()
        };
        assert!(v.hovering());
        v.position = Some([0.0, 0.0, -1.0]);
        assert!(!v.hovering());
        v.position = Some([0.0, 0.0, -2.0]);
        v.offboard = false;
        assert!(!v.hovering());
    }
}
