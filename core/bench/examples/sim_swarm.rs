//! Load benchmark: N simulated vehicles (swarm telemetry profile) in one process, and a
//! client that streams setpoints to all of them.
//!
//! `cargo run --release -p skein-bench --example sim_swarm -- --vehicles 1000 --rate-hz 50`
//!
//! The simulator runs on its own 2-worker tokio runtime (threads `sim-w`), the client on a
//! separate single-threaded runtime (thread `client`); CPU time is read per thread from
//! `/proc/self/task/*/stat` (Linux), so the two are reported separately. Phases:
//! 1. idle: vehicles on the ground, telemetry flowing to the client, no input;
//! 2. streaming: the client sends a GCS heartbeat at 1 Hz and a position setpoint at
//!    `--rate-hz` to every vehicle, switches them all to OFFBOARD, arms them, and they
//!    climb and hold; the simulator's setpoint-gap counters are reported.
#![allow(deprecated)]

use clap::Parser;
use skein_mavlink::dialect::*;
use skein_mavlink::{Decoder, Encoder, MavMessage};
use skein_model::px4::{Px4Mode, type_mask};
use skein_sim::{SimConfig, SimVehicleConfig, Simulator, TelemetryProfile};
use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

#[derive(Parser, Debug)]
struct Args {
    /// Number of vehicles.
    #[arg(long, default_value_t = 1000)]
    vehicles: usize,
    /// Setpoint rate per vehicle, Hz.
    #[arg(long, default_value_t = 50.0)]
    rate_hz: f64,
    /// Length of each measurement window, s.
    #[arg(long, default_value_t = 10.0)]
    seconds: f64,
    /// Use PX4's full onboard telemetry instead of the swarm profile.
    #[arg(long)]
    full_telemetry: bool,
}

/// CPU seconds (user + system) of this process's threads whose name starts with `prefix`.
fn thread_cpu_s(prefix: &str) -> f64 {
    let mut ticks = 0u64;
    let Ok(dir) = std::fs::read_dir("/proc/self/task") else {
        return f64::NAN;
    };
    for entry in dir.flatten() {
        let Ok(stat) = std::fs::read_to_string(entry.path().join("stat")) else {
            continue;
        };
        let (Some(open), Some(close)) = (stat.find('('), stat.rfind(')')) else {
            continue;
        };
        if !stat[open + 1..close].starts_with(prefix) {
            continue;
        }
        let fields: Vec<&str> = stat[close + 2..].split(' ').collect();
        // After "pid (comm) ": state is field 0; utime is 11, stime 12.
        let utime: u64 = fields.get(11).and_then(|f| f.parse().ok()).unwrap_or(0);
        let stime: u64 = fields.get(12).and_then(|f| f.parse().ok()).unwrap_or(0);
        ticks += utime + stime;
    }
    ticks as f64 / 100.0 // USER_HZ is 100 on Linux
}

struct Window {
    start: Instant,
    sim_cpu: f64,
    client_cpu: f64,
}

impl Window {
    fn begin() -> Window {
        Window {
            start: Instant::now(),
            sim_cpu: thread_cpu_s("sim-w"),
            client_cpu: thread_cpu_s("client"),
        }
    }

    /// (sim %, client %) of one core.
    fn end(&self) -> (f64, f64) {
        let wall = self.start.elapsed().as_secs_f64();
        (
            100.0 * (thread_cpu_s("sim-w") - self.sim_cpu) / wall,
            100.0 * (thread_cpu_s("client") - self.client_cpu) / wall,
        )
    }
}

#[derive(Default)]
struct ClientCounters {
    datagrams: AtomicU64,
    frames: AtomicU64,
    decode_errors: AtomicU64,
    setpoints_sent: AtomicU64,
}

/// The client's shared state: its counters, the switches the main thread flips, and the
/// commands it sends to every vehicle with the next setpoints.
#[derive(Default)]
struct ClientControl {
    counters: ClientCounters,
    streaming: AtomicBool,
    stop: AtomicBool,
    commands: std::sync::Mutex<Vec<MavMessage>>,
}

fn main() {
    let args = Args::parse();
    assert!(
        args.vehicles <= 255 * 4,
        "at most 1020 vehicles (system ids wrap per 255)"
    );
    let sim_rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name("sim-w")
        .enable_all()
        .build()
        .expect("sim runtime");

    // The client socket: every vehicle sends to it (shared endpoint, demultiplexed by
    // system id), and it sends to every vehicle (so they all lock onto it).
    let client_std = std::net::UdpSocket::bind("127.0.0.1:0").expect("client socket");
    client_std.set_nonblocking(true).expect("nonblocking");
    let client_addr = client_std.local_addr().expect("addr");
    let (sims, vehicles) = start_simulators(&args, &sim_rt, client_addr);
    let control = Arc::new(ClientControl::default());
    let client_thread = spawn_client(client_std, vehicles, args.rate_hz, control.clone());

    settle("warm-up", Duration::from_secs(3));
    measure_idle(&args, &control.counters);
    // Streaming phase: setpoints to everyone, then OFFBOARD + arm.
    control.streaming.store(true, Ordering::Relaxed);
    settle("pre-stream", Duration::from_millis(1500));
    switch_to_offboard_and_arm(&control);
    settle("climb", Duration::from_secs(4));
    measure_streaming(&args, &sims, &control.counters);

    control.stop.store(true, Ordering::Relaxed);
    let _ = client_thread.join();
    for sim in sims {
        sim_rt.block_on(sim.shutdown());
    }
}

/// Waits `d`, saying what for.
fn settle(what: &str, d: Duration) {
    println!("{what} ({:.0} s)…", d.as_secs_f64());
    std::thread::sleep(d);
}

/// Starts the simulators on `sim_rt`, 255 vehicles each at most, every vehicle sending to
/// `client_addr`; returns them and each vehicle's (sysid, bound address).
fn start_simulators(
    args: &Args,
    sim_rt: &tokio::runtime::Runtime,
    client_addr: SocketAddr,
) -> (Vec<Simulator>, Vec<(u8, SocketAddr)>) {
    // MAVLink system ids are one byte: above 255 vehicles, several simulators would be
    // needed in real life; the benchmark reuses ids across 255-vehicle simulators.
    let n = args.vehicles;
    let mut sims = Vec::new();
    let mut vehicles: Vec<(u8, SocketAddr)> = Vec::new();
    for chunk_start in (0..n).step_by(255) {
        let count = (n - chunk_start).min(255);
        let mut cfg = SimConfig::with_vehicles(
            (0..count)
                .map(|i| SimVehicleConfig {
                    sysid: (i + 1) as u8,
                    bind: "127.0.0.1:0".parse().expect("addr"),
                    target: client_addr,
                })
                .collect(),
        );
        cfg.telemetry = if args.full_telemetry {
            TelemetryProfile::Px4Onboard
        } else {
            TelemetryProfile::Swarm
        };
        cfg.ekf_fix_delay_s = 0.5;
        cfg.params = vec![("COM_DISARM_PRFLT".into(), 0.0)];
        let sim = sim_rt.block_on(Simulator::start(cfg)).expect("simulator");
        vehicles.extend(sim.vehicles().iter().map(|v| (v.sysid, v.bound)));
        sims.push(sim);
    }
    println!(
        "{} vehicles in {} simulator(s), profile {}",
        n,
        sims.len(),
        if args.full_telemetry { "px4" } else { "swarm" }
    );
    (sims, vehicles)
}

/// Runs the client on a thread of its own (`client`, a single-threaded runtime): it
/// counts the telemetry it receives and, while streaming, sends every vehicle its frames
/// at `rate_hz` until told to stop.
fn spawn_client(
    client_std: std::net::UdpSocket,
    vehicles: Vec<(u8, SocketAddr)>,
    rate_hz: f64,
    control: Arc<ClientControl>,
) -> std::thread::JoinHandle<()> {
    std::thread::Builder::new()
        .name("client".into())
        .spawn(move || {
            let rt = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .expect("client runtime");
            rt.block_on(async move {
                let sock = Arc::new(tokio::net::UdpSocket::from_std(client_std).expect("socket"));
                let rx = tokio::spawn(receive(sock.clone(), control.clone()));
                stream(&sock, &vehicles, rate_hz, &control).await;
                rx.abort();
            });
        })
        .expect("client thread")
}

/// Counts the datagrams and frames arriving on `sock`, and the decoder's errors.
async fn receive(sock: Arc<tokio::net::UdpSocket>, control: Arc<ClientControl>) {
    let counters = &control.counters;
    let mut buf = vec![0u8; 65536];
    let mut dec = Decoder::default();
    loop {
        let Ok((len, _)) = sock.recv_from(&mut buf).await else {
            continue;
        };
        counters.datagrams.fetch_add(1, Ordering::Relaxed);
        let mut frames = 0;
        dec.decode_datagram(&buf[..len], |_| frames += 1);
        counters.frames.fetch_add(frames, Ordering::Relaxed);
        counters
            .decode_errors
            .store(dec.stats().snapshot().errors(), Ordering::Relaxed);
    }
}

/// Every `1 / rate_hz` while streaming, one datagram to each vehicle: a GCS heartbeat once
/// a second, a position setpoint, and the pending commands.
async fn stream(
    sock: &tokio::net::UdpSocket,
    vehicles: &[(u8, SocketAddr)],
    rate_hz: f64,
    control: &ClientControl,
) {
    let mut enc = Encoder::new(245, 190);
    let mut iv = tokio::time::interval(Duration::from_secs_f64(1.0 / rate_hz));
    iv.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut last_hb = Instant::now() - Duration::from_secs(2);
    let mut buf = Vec::with_capacity(512);
    while !control.stop.load(Ordering::Relaxed) {
        iv.tick().await;
        if !control.streaming.load(Ordering::Relaxed) {
            continue;
        }
        let hb = last_hb.elapsed() >= Duration::from_secs(1);
        if hb {
            last_hb = Instant::now();
        }
        let pending: Vec<MavMessage> = std::mem::take(&mut *control.commands.lock().expect("lock"));
        for &(sysid, addr) in vehicles {
            buf.clear();
            encode_frames(&mut enc, &mut buf, sysid, hb, &pending);
            if sock.try_send_to(&buf, addr).is_ok() {
                control
                    .counters
                    .setpoints_sent
                    .fetch_add(1, Ordering::Relaxed);
            }
        }
    }
}

/// Appends vehicle `sysid`'s frames to `buf`: a GCS heartbeat (with `hb`), a setpoint
/// 5 m up, and `pending`'s commands addressed to it.
fn encode_frames(
    enc: &mut Encoder,
    buf: &mut Vec<u8>,
    sysid: u8,
    hb: bool,
    pending: &[MavMessage],
) {
    if hb {
        enc.encode_into(
            &MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                custom_mode: 0,
                mavtype: MavType::MAV_TYPE_GCS,
                autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
                base_mode: MavModeFlag::empty(),
                system_status: MavState::MAV_STATE_ACTIVE,
                mavlink_version: 3,
            }),
            buf,
        );
    }
    enc.encode_into(
        &MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
            time_boot_ms: 0,
            x: 0.0,
            y: 0.0,
            z: -5.0,
            vx: 0.0,
            vy: 0.0,
            vz: 0.0,
            afx: 0.0,
            afy: 0.0,
            afz: 0.0,
            yaw: 0.0,
            yaw_rate: 0.0,
            type_mask: PositionTargetTypemask::from_bits_retain(type_mask::POSITION_YAW),
            target_system: sysid,
            target_component: 1,
            coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
        }),
        buf,
    );
    for cmd in pending {
        let mut cmd = cmd.clone();
        if let MavMessage::COMMAND_LONG(c) = &mut cmd {
            c.target_system = sysid;
        }
        enc.encode_into(&cmd, buf);
    }
}

/// Measures one window with the vehicles on the ground and prints the CPU and telemetry.
fn measure_idle(args: &Args, counters: &ClientCounters) {
    let window = Duration::from_secs_f64(args.seconds);
    let frames0 = counters.frames.load(Ordering::Relaxed);
    let dgrams0 = counters.datagrams.load(Ordering::Relaxed);
    let w = Window::begin();
    std::thread::sleep(window);
    let (sim_idle, client_idle) = w.end();
    let idle_frames = (counters.frames.load(Ordering::Relaxed) - frames0) as f64 / args.seconds;
    let idle_dgrams = (counters.datagrams.load(Ordering::Relaxed) - dgrams0) as f64 / args.seconds;
    println!(
        "idle:      simulator {sim_idle:5.1} % of one core, client {client_idle:5.1} %, \
         telemetry {idle_frames:.0} frames/s in {idle_dgrams:.0} datagrams/s"
    );
}

/// Has the client broadcast OFFBOARD, then (300 ms later) arm, to every vehicle.
fn switch_to_offboard_and_arm(control: &ClientControl) {
    let (main, sub) = Px4Mode::Offboard.main_sub();
    // Broadcast (target system 0) to every simulated autopilot.
    let command = |command: MavCmd, p: [f32; 7]| {
        skein_mavlink::command_long(skein_mavlink::CommandTarget::new(0, 1), command, p, 0)
    };
    control.commands.lock().expect("lock").push(command(
        MavCmd::MAV_CMD_DO_SET_MODE,
        [1.0, f32::from(main), f32::from(sub), 0.0, 0.0, 0.0, 0.0],
    ));
    std::thread::sleep(Duration::from_millis(300));
    control.commands.lock().expect("lock").push(command(
        MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    ));
}

/// Measures one window of streaming and prints the CPU, the setpoints sent and
/// received, the largest setpoint gaps and the vehicles' states.
fn measure_streaming(args: &Args, sims: &[Simulator], counters: &ClientCounters) {
    for sim in sims {
        sim.reset_stats();
    }
    let frames0 = counters.frames.load(Ordering::Relaxed);
    let sent0 = counters.setpoints_sent.load(Ordering::Relaxed);
    let w = Window::begin();
    std::thread::sleep(Duration::from_secs_f64(args.seconds));
    let (sim_busy, client_busy) = w.end();
    let frames = (counters.frames.load(Ordering::Relaxed) - frames0) as f64 / args.seconds;
    let sent = counters.setpoints_sent.load(Ordering::Relaxed) - sent0;
    let stats: Vec<_> = sims.iter().flat_map(|s| s.stats()).collect();
    let received: u64 = stats.iter().map(|s| s.setpoints_received).sum();
    println!(
        "streaming: simulator {sim_busy:5.1} % of one core, client {client_busy:5.1} %, \
         telemetry {frames:.0} frames/s"
    );
    println!(
        "           setpoints sent {sent}, received {received} ({:.1} %), \
         {:.0} setpoints/s into the simulator",
        100.0 * received as f64 / sent.max(1) as f64,
        received as f64 / args.seconds
    );
    print_vehicle_report(args, &stats, counters);
}

/// Prints the largest setpoint gaps in OFFBOARD and how many vehicles are armed, at
/// altitude, in failsafe, in which mode.
fn print_vehicle_report(
    args: &Args,
    stats: &[skein_sim::SimVehicleStats],
    counters: &ClientCounters,
) {
    let n = args.vehicles;
    let mut gaps: Vec<f64> = stats
        .iter()
        .map(|s| s.setpoint_max_gap_offboard_ms)
        .collect();
    gaps.sort_by(|a, b| a.total_cmp(b));
    let offboard_armed = stats
        .iter()
        .filter(|s| s.truth.armed && s.truth.mode == Px4Mode::Offboard)
        .count();
    let at_altitude = stats
        .iter()
        .filter(|s| (s.truth.local_ned_m.down_m + 5.0).abs() < 0.5)
        .count();
    let failsafes: u64 = stats.iter().map(|s| s.offboard_loss_failsafes).sum();
    let drops: u64 = stats.iter().map(|s| s.send_drops).sum();
    let mut modes: HashMap<&str, usize> = HashMap::new();
    for s in stats {
        *modes.entry(s.truth.mode_name).or_default() += 1;
    }
    println!(
        "           per-vehicle largest setpoint gap in OFFBOARD: median {:.1} ms, \
         p99 {:.1} ms, max {:.1} ms (nominal {:.1} ms)",
        gaps[gaps.len() / 2],
        gaps[(gaps.len() * 99 / 100).min(gaps.len() - 1)],
        gaps[gaps.len() - 1],
        1000.0 / args.rate_hz
    );
    println!(
        "           {offboard_armed}/{n} armed in OFFBOARD, {at_altitude}/{n} at z = -5 ± 0.5 m, \
         offboard-loss failsafes {failsafes}, simulator send drops {drops}, modes {modes:?}, \
         client decode errors {}",
        counters.decode_errors.load(Ordering::Relaxed)
    );
}
