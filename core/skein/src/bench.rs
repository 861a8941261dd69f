//! `skein bench <what>`: benchmarks that print one JSON object on stdout (progress goes to
//! stderr).
//!
//! `skein bench formation [--vehicles 8,32]`: formation flight in virtual time, see
//! [`formation`].
//!
//! `skein bench swarm --vehicles N --rate-hz R --seconds S` (issue 3's benchmark):
//!
//! 1. opens one `udpin` endpoint per vehicle on a free block of N consecutive local UDP
//!    ports and starts skein's real stack on them in this process ([`Swarm::start`]: the
//!    Coordinator, one Vehicle and one Px4Link actor per vehicle, setpoint streams at R Hz,
//!    the reduced `swarm` telemetry profile);
//! 2. starts the simulator **in its own process** (this binary, `skein sim --profile swarm
//!    --per-vehicle-targets --stats 127.0.0.1:0`), vehicle i sending to port base + i with
//!    sysid `i % 250 + 1` beyond 255 vehicles (identity is (endpoint, sysid));
//! 3. waits until every vehicle has joined with a position, sends the swarm `takeoff`
//!    command to a low altitude (retrying vehicles that are not ready yet) and waits until
//!    every vehicle is `Hovering` under offboard control;
//! 4. resets the simulator's counters and measures for S seconds: nothing else runs in
//!    this process meanwhile but skein's stack;
//! 5. prints `vehicles`, `rate_hz`, `seconds`, `setpoints_sent` (skein side),
//!    `setpoints_received` (simulator side), `late_fraction` (intervals between
//!    consecutive setpoints of a vehicle, as received by the simulator, longer than
//!    1.25 × the period, over all intervals), `interval_ms` (`p50`, `p99`, `p999`, `max`,
//!    `mean`), `coordinator_cpu_s` (user + system CPU of this process over the window),
//!    `coordinator_peak_rss_mb` (`VmHWM`), `sim_cpu_s` (the simulator process's user +
//!    system CPU over the window), `offboard_loss_failsafes`, `all_offboard` (every
//!    simulated vehicle in OFFBOARD at the end of the window), and a few diagnostics.
//!
//! Interval percentiles come from the simulator's histogram (0.1 ms buckets below 100 ms):
//! each is the upper edge of its bucket, and a bucket straddling the lateness threshold
//! counts as late, so both err on the pessimistic side by at most 0.1 ms.
//!
//! `setpoints_sent` is the sum of every vehicle's `SetpointStream::counts().sent` over the
//! window, read through the coordinator's metrics (`skein_setpoints_sent`); the window's
//! ends on the two sides are a few milliseconds apart, so sent and received may differ by
//! about one setpoint per vehicle without any loss.
//!
//! CPU figures come from `/proc/<pid>/stat` (Linux; `null` elsewhere) in units of
//! `USER_HZ` = 100 ticks/s, so they are good to 10 ms. Diagnostics: `host_other_cpu_s` is
//! the CPU the rest of the host used during the window (anything large means the run
//! competed with other work for the cores: rerun on a quiet host), and `runtime_probe` is a
//! task ticking at the setpoint period on this process's runtime, whose lateness is the
//! runtime's own scheduling latency.

use serde_json::{Value, json};
use skein_link::{Identity, LinkSetup, TelemetryProfile};
use skein_model::fsm::VehicleState;
use skein_model::vehicle::VehicleSnapshot;
use skein_swarm::{
    CoordinatorMsg, EndpointSpec, Swarm, SwarmConfig, SwarmServices, VehicleCommand, VehicleSpec,
};
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::process::Stdio;
use std::time::{Duration, Instant};
use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader, Lines};
use tokio::net::TcpStream;
use tokio::net::tcp::{OwnedReadHalf, OwnedWriteHalf};
use tokio::process::{Child, Command};

/// `skein bench`.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// The benchmark to run.
    #[command(subcommand)]
    pub what: BenchWhat,
}

/// The benchmarks.
#[derive(clap::Subcommand, Debug)]
pub enum BenchWhat {
    /// N simulated vehicles (simulator in its own process) in offboard through skein's
    /// full stack: setpoint timing as the simulator receives it, coordinator CPU and memory.
    Swarm(SwarmBenchArgs),
    /// Formation flight in virtual time (the real formation engine and setpoint shapers,
    /// point-mass PX4-like vehicles): every shape behind a virtual leader at 5 m/s.
    Formation(FormationBenchArgs),
    /// Injected panics of a payload actor under hovering vehicles: restart latency and
    /// the largest gap in the offboard setpoint stream.
    Restart(RestartBenchArgs),
    /// Payload plugins: message round trips in-process and process-isolated, load and
    /// reload times, restart times after a panic and after an abort.
    Plugins(PluginsBenchArgs),
}

/// `skein bench plugins`.
#[derive(clap::Args, Debug, Clone)]
pub struct PluginsBenchArgs {
    /// Directory holding `libskein_plugin_example.so` and, for the restart figures,
    /// `libskein_plugin_fault.so` (default: the directory of this executable, where
    /// `cargo build --release` puts them).
    #[arg(long, value_name = "DIR")]
    pub plugin_dir: Option<std::path::PathBuf>,
    /// In-process round trips measured.
    #[arg(long, default_value_t = 20_000)]
    pub round_trips: usize,
    /// Process-isolated round trips measured.
    #[arg(long, default_value_t = 2_000)]
    pub isolated_round_trips: usize,
    /// Loads and reloads measured.
    #[arg(long, default_value_t = 30)]
    pub loads: usize,
    /// Restarts after a panic measured (and a fifth as many after an abort).
    #[arg(long, default_value_t = 50)]
    pub restarts: usize,
}

/// `skein bench restart`.
#[derive(clap::Args, Debug, Clone)]
pub struct RestartBenchArgs {
    /// Panics to inject (spread round-robin over the vehicles' payloads).
    #[arg(long, default_value_t = 1000)]
    pub panics: usize,
    /// Hovering vehicles, each with one payload actor (the built-in fault fixture).
    #[arg(long, default_value_t = 4)]
    pub vehicles: usize,
    /// Offboard setpoint rate per vehicle, Hz.
    #[arg(long, default_value_t = 50.0)]
    pub rate_hz: f64,
    /// One panic every this many milliseconds (at most: the next waits for the previous
    /// restart), so that the setpoint streams are watched over panics × period.
    #[arg(long, default_value_t = 10)]
    pub period_ms: u64,
    /// Simulator seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

/// `skein bench formation`.
#[derive(clap::Args, Debug, Clone)]
pub struct FormationBenchArgs {
    /// Swarm sizes to fly, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "8,32")]
    pub vehicles: Vec<usize>,
    /// Distance between neighbouring slots, m.
    #[arg(long, default_value_t = 6.0)]
    pub spacing_m: f64,
    /// Speed of the virtual leader on each leg and orbit, m/s.
    #[arg(long, default_value_t = 5.0)]
    pub speed_m_s: f64,
    /// What flies: `px4` (skein's PX4-faithful simulated multicopter, the default) or
    /// `point-mass` (the kinder model of the seeded transition sweeps).
    #[arg(long, default_value = "px4", value_parser = ["px4", "point-mass"])]
    pub airframe: String,
    /// PX4's hover wander on the simulated vehicles (seeded estimator noise).
    #[arg(long)]
    pub estimator_noise: bool,
}

/// `skein bench swarm`.
#[derive(clap::Args, Debug, Clone)]
pub struct SwarmBenchArgs {
    /// Number of vehicles.
    #[arg(long, default_value_t = 10)]
    pub vehicles: usize,
    /// Offboard setpoint rate per vehicle, Hz.
    #[arg(long, default_value_t = 50.0)]
    pub rate_hz: f64,
    /// Length of the measurement window, s.
    #[arg(long, default_value_t = 20.0)]
    pub seconds: f64,
    /// Takeoff altitude above home, m.
    #[arg(long, default_value_t = 2.0)]
    pub altitude_m: f64,
    /// Distance between the simulated vehicles' spawn points, m (above the swarm's 3 m
    /// minimum separation, so that the separation check never moves anyone).
    #[arg(long, default_value_t = 5.0)]
    pub spacing_m: f64,
    /// Longest time to get every vehicle hovering before measuring anyway, s (default
    /// 60 + 0.1 × N).
    #[arg(long)]
    pub setup_timeout_s: Option<f64>,
    /// Simulator seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

/// Runs `skein bench <what>`.
pub async fn run(args: BenchArgs) -> Result<(), String> {
    match args.what {
        BenchWhat::Swarm(a) => {
            let report = swarm(a).await?;
            println!("{report}");
            Ok(())
        }
        BenchWhat::Formation(a) => {
            let report = tokio::task::spawn_blocking(move || formation(&a))
                .await
                .map_err(|e| e.to_string())??;
            println!("{report}");
            Ok(())
        }
        BenchWhat::Restart(a) => {
            let report = restart(a).await?;
            println!("{report}");
            Ok(())
        }
        BenchWhat::Plugins(a) => {
            let report = tokio::task::spawn_blocking(move || plugins(&a))
                .await
                .map_err(|e| e.to_string())??;
            println!("{report}");
            Ok(())
        }
    }
}

/// `skein bench formation`: for each swarm size, every shape in turn behind a virtual
/// leader (set while it holds: time to converge, until no transition is in flight and the
/// RMS slot error is under 0.2 m; 0.3 m with estimator noise), then a 60 m leg at
/// `speed_m_s` (RMS slot error while cruising, after the first quarter of the cruise
/// samples), then half an orbit of 30 m radius at `speed_m_s` (RMS slot error while
/// orbiting, likewise), with the smallest distance between two vehicles over the whole
/// run. Virtual time (see `skein_swarm::rehearsal`), on the PX4-faithful simulated
/// multicopter by default: deterministic, and `wall_s` says how long the CPU took.
///
/// # Errors
/// When a shape does not converge within 300 s of virtual time.
pub fn formation(args: &FormationBenchArgs) -> Result<Value, String> {
    use skein_model::formation::Shape;
    use skein_model::geo::Ned;
    use skein_swarm::formation::{FormationFrame, FormationSpec, VIRTUAL};
    use skein_swarm::rehearsal::{AirframeKind, Rehearsal, RehearsalConfig};
    let airframe = match args.airframe.as_str() {
        "point-mass" => AirframeKind::PointMass,
        _ => AirframeKind::Px4 {
            estimator_noise: args.estimator_noise,
        },
    };
    let settled_rms = if args.estimator_noise { 0.3 } else { 0.2 };
    let mut runs = Vec::new();
    for &n in &args.vehicles {
        let started = Instant::now();
        let mut config = RehearsalConfig::new(n);
        config.airframe = airframe;
        let mut r = Rehearsal::new(config);
        let mut converge_s = Vec::new();
        let mut moving_rms = Vec::new();
        let mut orbit_rms = Vec::new();
        let mut north = 0.0;
        for shape in Shape::ALL
            .into_iter()
            .filter(|s| *s != Shape::Custom && s.min_vehicles() <= n)
        {
            r.set_formation(FormationSpec {
                shape,
                spacing_m: args.spacing_m,
                leader: Some(VIRTUAL.into()),
                heading_deg: 0.0,
                altitude_m: Some(12.0),
                frame: FormationFrame::World,
                offsets: vec![],
            });
            let t0 = r.time_s();
            let settled = r.run_until(300.0, |r| {
                let s = r.status();
                s.transition_progress.is_none()
                    && s.pending.is_none()
                    && s.rms_error_m.is_some_and(|e| e < settled_rms)
            });
            if !settled {
                return Err(format!("{n} vehicles: {} did not converge", shape.name()));
            }
            converge_s.push(r.time_s() - t0);
            north = if north == 0.0 { 60.0 } else { 0.0 };
            moving_rms.extend(r.cruise_to(Ned::new(north, 0.0, -12.0), args.speed_m_s)?);
            // Half an orbit around a point 30 m east of where the leg ended.
            let half_s = std::f64::consts::PI * 30.0 / args.speed_m_s;
            orbit_rms.extend(r.orbit(
                Ned::new(north, 30.0, -12.0),
                30.0,
                args.speed_m_s,
                half_s,
            )?);
        }
        converge_s.sort_by(f64::total_cmp);
        let stats = r.stats();
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
        let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
        runs.push(json!({
            "vehicles": n,
            "rms_slot_error_moving_m": {
                "mean": round(mean(&moving_rms), 3),
                "max": round(max(&moving_rms), 3),
            },
            "rms_slot_error_orbit_m": {
                "mean": round(mean(&orbit_rms), 3),
                "max": round(max(&orbit_rms), 3),
            },
            "converge_s": {
                "p50": round(converge_s[converge_s.len() / 2], 1),
                "max": round(converge_s.last().copied().unwrap_or(0.0), 1),
            },
            "min_separation_m": round(stats.min_separation_m, 3),
            "separation_violations": stats.separation_violations,
            "fence_violations": stats.fence_violations,
            "virtual_s": round(r.time_s(), 1),
            "wall_s": round(started.elapsed().as_secs_f64(), 2),
        }));
    }
    Ok(json!({
        "bench": "formation",
        "spacing_m": args.spacing_m,
        "speed_m_s": args.speed_m_s,
        "airframe": args.airframe,
        "estimator_noise": args.estimator_noise,
        "runs": runs,
    }))
}

/// Clock ticks per second of `/proc/<pid>/stat` (`USER_HZ`, 100 on Linux).
const USER_HZ: f64 = 100.0;
const LOCALHOST: IpAddr = IpAddr::V4(Ipv4Addr::LOCALHOST);
/// Longest wait for the simulator's stats socket to answer one command.
const STATS_TIMEOUT: Duration = Duration::from_secs(30);
/// Longest wait for the coordinator to answer (a swarm command visits every vehicle).
const COORDINATOR_TIMEOUT: Duration = Duration::from_secs(120);

/// User + system CPU seconds of process `pid` (this process for `None`), from
/// `/proc/<pid>/stat`; `None` where that does not exist.
pub fn cpu_seconds(pid: Option<u32>) -> Option<f64> {
    let path = pid.map_or_else(|| "/proc/self/stat".into(), |p| format!("/proc/{p}/stat"));
    let stat = std::fs::read_to_string(path).ok()?;
    // Fields after the command name (which may contain spaces) start at field 3.
    let rest = stat.get(stat.rfind(')')? + 1..)?;
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let utime: u64 = fields.get(11)?.parse().ok()?;
    let stime: u64 = fields.get(12)?.parse().ok()?;
    Some((utime + stime) as f64 / USER_HZ)
}

/// Busy CPU seconds of the whole host since boot (every core: user, nice, system, irq,
/// softirq, steal), from `/proc/stat`.
pub fn host_busy_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/stat").ok()?;
    let line = stat.lines().find(|l| l.starts_with("cpu "))?;
    let v: Vec<u64> = line
        .split_whitespace()
        .skip(1)
        .filter_map(|x| x.parse().ok())
        .collect();
    // user nice system idle iowait irq softirq steal
    let busy = v.first()? + v.get(1)? + v.get(2)? + v.get(5)? + v.get(6)? + v.get(7)?;
    Some(busy as f64 / USER_HZ)
}

/// Peak resident set size of this process, MB (`VmHWM` in `/proc/self/status`).
pub fn peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// The simulator child process and its stats socket.
struct SimProcess {
    child: Child,
    pid: Option<u32>,
    lines: Lines<BufReader<OwnedReadHalf>>,
    write: OwnedWriteHalf,
}

impl SimProcess {
    /// Starts `skein sim` with vehicle i sending to `target_base + i`; returns once the
    /// simulator is ready and its stats socket is connected.
    async fn start(args: &SwarmBenchArgs, target_base: u16) -> Result<SimProcess, String> {
        let exe = std::env::current_exe().map_err(|e| format!("own executable: {e}"))?;
        let mut child = Command::new(exe)
            .args(["sim", "--profile", "swarm", "--per-vehicle-targets"])
            .args(["--vehicles", &args.vehicles.to_string()])
            .args(["--listen-base-port", "0"])
            .args(["--target-base-port", &target_base.to_string()])
            .args(["--spacing-m", &args.spacing_m.to_string()])
            .args(["--seed", &args.seed.to_string()])
            .args(["--stats", "127.0.0.1:0"])
            .env("SKEIN_LOG", "warn")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .kill_on_drop(true)
            .spawn()
            .map_err(|e| format!("cannot start the simulator: {e}"))?;
        let pid = child.id();
        let stdout = child.stdout.take().ok_or("simulator stdout")?;
        let mut out = BufReader::new(stdout).lines();
        let mut stats_addr: Option<SocketAddr> = None;
        let deadline = tokio::time::Instant::now() + Duration::from_secs(60);
        loop {
            let line = tokio::time::timeout_at(deadline, out.next_line())
                .await
                .map_err(|_| "the simulator did not get ready within 60 s".to_string())?
                .map_err(|e| format!("simulator stdout: {e}"))?
                .ok_or("the simulator exited before it was ready")?;
            if let Some(addr) = line.strip_prefix("stats ") {
                stats_addr = addr.trim().parse().ok();
            } else if line.trim() == "ready" {
                break;
            }
        }
        // Keep draining its stdout so that it never writes into a closed pipe.
        tokio::spawn(async move { while let Ok(Some(_)) = out.next_line().await {} });
        let addr = stats_addr.ok_or("the simulator printed no stats address")?;
        let stream = TcpStream::connect(addr)
            .await
            .map_err(|e| format!("simulator stats socket {addr}: {e}"))?;
        let (read, write) = stream.into_split();
        Ok(SimProcess {
            child,
            pid,
            lines: BufReader::new(read).lines(),
            write,
        })
    }

    /// One stats-socket command; its JSON answer (an `{"error"}` answer is an error).
    async fn ask(&mut self, cmd: &str) -> Result<Value, String> {
        self.write
            .write_all(format!("{cmd}\n").as_bytes())
            .await
            .map_err(|e| format!("simulator stats socket: {e}"))?;
        let line = tokio::time::timeout(STATS_TIMEOUT, self.lines.next_line())
            .await
            .map_err(|_| format!("the simulator did not answer `{cmd}` in time"))?
            .map_err(|e| format!("simulator stats socket: {e}"))?
            .ok_or("the simulator closed its stats socket")?;
        let v: Value =
            serde_json::from_str(&line).map_err(|e| format!("simulator answer to `{cmd}`: {e}"))?;
        match v.get("error") {
            Some(e) => Err(format!("simulator refused `{cmd}`: {e}")),
            None => Ok(v),
        }
    }

    async fn stop(mut self) {
        let _ = self.child.start_kill();
        let _ = self.child.wait().await;
    }
}

/// A pseudo-random first port for a block of `n` (from the clock and pid; no generator
/// needed), below Linux's ephemeral range (32768…) so the simulator's own ports never
/// collide with it.
fn candidate_base(n: usize, attempt: u32) -> Option<u16> {
    let low = 20_000usize;
    let high = 32_768usize.checked_sub(n)?;
    if high <= low {
        return None;
    }
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.subsec_nanos());
    let mix =
        u64::from(nanos) ^ (u64::from(std::process::id()) << 16) ^ (u64::from(attempt) * 7919);
    u16::try_from(low + (mix as usize % (high - low))).ok()
}

/// The swarm configuration of the benches: setpoints at `rate_hz`, the `swarm` telemetry
/// profile, takeoff to `args.altitude_m`.
fn bench_config(args: &SwarmBenchArgs) -> SwarmConfig {
    let mut config = SwarmConfig {
        stream_rate_hz: args.rate_hz,
        link_setup: LinkSetup {
            telemetry: TelemetryProfile::Swarm,
            params: Vec::new(),
        },
        ..SwarmConfig::default()
    };
    config.default_takeoff_altitude_m = args.altitude_m;
    config
}

/// Starts skein's stack with one `udpin` endpoint per vehicle on a free block of
/// consecutive ports, every vehicle of `model` (`None`: generic); returns the swarm and
/// the first port.
async fn start_swarm(
    args: &SwarmBenchArgs,
    config: SwarmConfig,
    services: SwarmServices,
    model: Option<&str>,
) -> Result<(Swarm, u16), String> {
    let n = args.vehicles;
    let mut last_error = String::new();
    for attempt in 0..20 {
        let base = candidate_base(n, attempt)
            .ok_or_else(|| format!("{n} vehicles need more local UDP ports than available"))?;
        let endpoints = (0..n)
            .map(|i| EndpointSpec {
                connection: skein_link::ConnectionAddress::UdpIn(SocketAddr::new(
                    LOCALHOST,
                    base + i as u16,
                )),
                vehicles: vec![VehicleSpec {
                    id: Some(format!("uav-{}", i + 1)),
                    sysid: Some(skein_sim::instance_sysid(i, n)),
                    model: model.map(str::to_string),
                }],
                // The simulator runs in its own process: nothing in-process to drive.
                simulated: false,
            })
            .collect();
        match Swarm::start(
            config.clone(),
            services.clone(),
            Identity::default(),
            endpoints,
        )
        .await
        {
            Ok(swarm) => return Ok((swarm, base)),
            Err(e) => last_error = e.to_string(), // a port of the block is taken: retry
        }
    }
    Err(format!("no free block of {n} UDP ports: {last_error}"))
}

async fn list_vehicles(swarm: &Swarm) -> Result<Vec<VehicleSnapshot>, String> {
    match swarm
        .coordinator
        .call(CoordinatorMsg::ListVehicles, Some(COORDINATOR_TIMEOUT))
        .await
    {
        Ok(ractor::rpc::CallResult::Success(v)) => Ok(v),
        Ok(_) => Err("the coordinator did not answer in time".into()),
        Err(e) => Err(format!("the coordinator is not running: {e}")),
    }
}

/// Sends `cmd` to every vehicle (`None`) or to the listed ones; returns the ids that
/// refused it.
async fn command(
    swarm: &Swarm,
    cmd: &VehicleCommand,
    only: Option<&[String]>,
) -> Result<Vec<String>, String> {
    let Some(ids) = only else {
        let c = cmd.clone();
        return match swarm
            .coordinator
            .call(
                move |r| CoordinatorMsg::SwarmCommand(c, r),
                Some(COORDINATOR_TIMEOUT),
            )
            .await
        {
            Ok(ractor::rpc::CallResult::Success(o)) => {
                Ok(o.refused.into_iter().map(|r| r.id).collect())
            }
            Ok(_) => Err("the coordinator did not answer the swarm command in time".into()),
            Err(e) => Err(format!("the coordinator is not running: {e}")),
        };
    };
    let mut refused = Vec::new();
    for id in ids {
        let (c, i) = (cmd.clone(), id.clone());
        match swarm
            .coordinator
            .call(
                move |r| CoordinatorMsg::VehicleCommand(i, c, r),
                Some(COORDINATOR_TIMEOUT),
            )
            .await
        {
            Ok(ractor::rpc::CallResult::Success(Ok(_))) => {}
            Ok(_) => refused.push(id.clone()),
            Err(e) => return Err(format!("the coordinator is not running: {e}")),
        }
    }
    Ok(refused)
}

/// Waits until every vehicle has joined with a position, takes them all off and waits
/// until every one hovers (or the deadline passes). Returns how many hover.
async fn take_off_all(
    swarm: &Swarm,
    args: &SwarmBenchArgs,
    deadline: Instant,
) -> Result<usize, String> {
    let n = args.vehicles;
    let takeoff = VehicleCommand::Takeoff {
        altitude_m: Some(args.altitude_m),
    };
    let ready = |v: &VehicleSnapshot| {
        v.state == VehicleState::Landed && v.position.is_some() && v.link.connected
    };
    // Everyone joined, with a position.
    let mut last_report = Instant::now();
    loop {
        let vs = list_vehicles(swarm).await?;
        let n_ready = vs.iter().filter(|v| ready(v)).count();
        if n_ready == n {
            break;
        }
        if Instant::now() > deadline {
            return Err(format!(
                "only {n_ready} of {n} vehicles joined with a position in time ({} joined)",
                vs.len()
            ));
        }
        if last_report.elapsed() > Duration::from_secs(5) {
            eprintln!("bench: {n_ready}/{n} vehicles ready ({} joined)", vs.len());
            last_report = Instant::now();
        }
        tokio::time::sleep(Duration::from_millis(250)).await;
    }
    eprintln!(
        "bench: {n} vehicles ready; taking off to {} m",
        args.altitude_m
    );
    let mut retry = command(swarm, &takeoff, None).await?;
    loop {
        tokio::time::sleep(Duration::from_millis(500)).await;
        let vs = list_vehicles(swarm).await?;
        let hovering = vs
            .iter()
            .filter(|v| v.state == VehicleState::Hovering)
            .count();
        if hovering == n {
            return Ok(n);
        }
        if Instant::now() > deadline {
            eprintln!("bench: setup deadline: {hovering}/{n} hovering; measuring anyway");
            return Ok(hovering);
        }
        if last_report.elapsed() > Duration::from_secs(5) {
            eprintln!("bench: {hovering}/{n} hovering");
            last_report = Instant::now();
        }
        // Vehicles that refused, or fell back to the ground (a takeoff that failed), try
        // again.
        retry.extend(
            vs.iter()
                .filter(|v| ready(v) || v.state == VehicleState::Armed)
                .map(|v| v.id.clone()),
        );
        retry.sort();
        retry.dedup();
        if !retry.is_empty() {
            retry = command(swarm, &takeoff, Some(&retry)).await?;
        }
    }
}

/// Frames skein's endpoints could not send (socket full, no address yet).
fn skein_send_errors(swarm: &Swarm) -> u64 {
    swarm
        .endpoints
        .iter()
        .map(|ep| {
            let c = ep.send_counts();
            c.send_errors + c.no_route
        })
        .sum()
}

/// Setpoints sent by every vehicle's stream (`SetpointStream::counts().sent`), summed from
/// the coordinator's `skein_setpoints_sent{vehicle=…}` metrics.
async fn skein_setpoints_sent(swarm: &Swarm) -> Result<u64, String> {
    let text = match swarm
        .coordinator
        .call(CoordinatorMsg::RenderMetrics, Some(COORDINATOR_TIMEOUT))
        .await
    {
        Ok(ractor::rpc::CallResult::Success(t)) => t,
        Ok(_) => return Err("the coordinator did not render its metrics in time".into()),
        Err(e) => return Err(format!("the coordinator is not running: {e}")),
    };
    Ok(sum_metric(&text, "skein_setpoints_sent"))
}

/// Sum of every sample of `name` (any labels) in Prometheus text exposition.
fn sum_metric(text: &str, name: &str) -> u64 {
    text.lines()
        .filter(|l| {
            l.strip_prefix(name)
                .is_some_and(|rest| rest.starts_with('{') || rest.starts_with(' '))
        })
        .filter_map(|l| l.rsplit(' ').next()?.parse::<f64>().ok())
        .map(|v| v.max(0.0) as u64)
        .sum()
}

fn f64_at(v: &Value, path: &[&str]) -> f64 {
    path.iter()
        .fold(v, |v, k| &v[*k])
        .as_f64()
        .unwrap_or(f64::NAN)
}

fn u64_at(v: &Value, key: &str) -> u64 {
    v[key].as_u64().unwrap_or(0)
}

/// Intervals longer than `threshold_ms` in the simulator's bucket list (a bucket whose
/// upper edge is above the threshold counts whole: pessimistic by one bucket).
fn late_intervals(buckets: &Value, threshold_ms: f64) -> u64 {
    buckets
        .as_array()
        .map(|bs| {
            bs.iter()
                .filter(|b| b["hi_ms"].as_f64().unwrap_or(0.0) > threshold_ms)
                .map(|b| b["count"].as_u64().unwrap_or(0))
                .sum()
        })
        .unwrap_or(0)
}

/// A task on this process's runtime ticking at the setpoint period for `window`; returns
/// its tick intervals, ms. Its lateness is the runtime's own scheduling latency (timer
/// and worker availability), to tell it apart from the link's.
async fn probe(period: Duration, window: Duration) -> Vec<f64> {
    let mut ticker = tokio::time::interval(period);
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let end = Instant::now() + window;
    let mut last: Option<Instant> = None;
    let mut intervals =
        Vec::with_capacity((window.as_secs_f64() / period.as_secs_f64()) as usize + 1);
    while Instant::now() < end {
        ticker.tick().await;
        let now = Instant::now();
        if let Some(l) = last {
            intervals.push(now.duration_since(l).as_secs_f64() * 1e3);
        }
        last = Some(now);
    }
    intervals
}

fn probe_report(mut intervals: Vec<f64>, late_threshold_ms: f64) -> Value {
    if intervals.is_empty() {
        return Value::Null;
    }
    intervals.sort_by(f64::total_cmp);
    let q = |p: f64| {
        round(
            intervals[((intervals.len() - 1) as f64 * p).round() as usize],
            3,
        )
    };
    let late = intervals.iter().filter(|x| **x > late_threshold_ms).count();
    json!({
        "intervals": intervals.len(),
        "late_fraction": late as f64 / intervals.len() as f64,
        "p50_ms": q(0.5),
        "p99_ms": q(0.99),
        "max_ms": q(1.0),
    })
}

/// Rounds to `digits` decimals for the report.
fn round(x: f64, digits: i32) -> f64 {
    let k = 10f64.powi(digits);
    (x * k).round() / k
}

/// `skein bench swarm` (see module docs); returns the report.
pub async fn swarm(args: SwarmBenchArgs) -> Result<Value, String> {
    let n = args.vehicles;
    if n == 0 {
        return Err("--vehicles must be at least 1".into());
    }
    if !(args.rate_hz.is_finite() && args.rate_hz > 2.0) {
        return Err(format!(
            "--rate-hz {}: PX4 needs more than 2 Hz",
            args.rate_hz
        ));
    }
    if !(args.seconds.is_finite() && args.seconds > 0.0) {
        return Err(format!("--seconds {} must be positive", args.seconds));
    }
    let started = Instant::now();
    let setup_timeout =
        Duration::from_secs_f64(args.setup_timeout_s.unwrap_or(60.0 + 0.1 * n as f64));
    let (swarm, base) =
        start_swarm(&args, bench_config(&args), SwarmServices::default(), None).await?;
    eprintln!(
        "bench: skein listening on udp 127.0.0.1:{base}..{}",
        usize::from(base) + n - 1
    );
    let mut sim = match SimProcess::start(&args, base).await {
        Ok(s) => s,
        Err(e) => {
            swarm.stop().await;
            return Err(e);
        }
    };
    let result = measure(&swarm, &mut sim, &args, started + setup_timeout).await;
    sim.stop().await;
    swarm.stop().await;
    let mut report = result?;
    report["setup_s"] = json!(round(report["setup_s"].as_f64().unwrap_or(0.0), 1));
    Ok(report)
}

async fn measure(
    swarm: &Swarm,
    sim: &mut SimProcess,
    args: &SwarmBenchArgs,
    deadline: Instant,
) -> Result<Value, String> {
    let n = args.vehicles;
    let setup_start = Instant::now();
    let hovering = take_off_all(swarm, args, deadline).await?;
    let setup_s = setup_start.elapsed().as_secs_f64();
    eprintln!(
        "bench: {hovering}/{n} hovering after {setup_s:.1} s; measuring for {} s",
        args.seconds
    );

    // The window.
    let sent0 = skein_setpoints_sent(swarm).await?;
    let errors0 = skein_send_errors(swarm);
    let cpu0 = cpu_seconds(None);
    let sim_cpu0 = sim.pid.and_then(|p| cpu_seconds(Some(p)));
    let host0 = host_busy_seconds();
    sim.ask("reset").await?;
    let t0 = Instant::now();
    let probe = tokio::spawn(probe(
        Duration::from_secs_f64(1.0 / args.rate_hz),
        Duration::from_secs_f64(args.seconds),
    ));
    tokio::time::sleep(Duration::from_secs_f64(args.seconds)).await;
    let summary = sim.ask("summary").await?;
    let probe = probe.await.unwrap_or_default();
    let window_s = t0.elapsed().as_secs_f64();
    let sent1 = skein_setpoints_sent(swarm).await?;
    let errors1 = skein_send_errors(swarm);
    let cpu1 = cpu_seconds(None);
    let sim_cpu1 = sim.pid.and_then(|p| cpu_seconds(Some(p)));
    let host1 = host_busy_seconds();
    // CPU the rest of the host used meanwhile: other work competing for the cores makes
    // the figures of this run unrepresentative.
    let other = match (host0, host1, cpu0, cpu1, sim_cpu0, sim_cpu1) {
        (Some(h0), Some(h1), Some(c0), Some(c1), Some(s0), Some(s1)) => {
            json!(round(((h1 - h0) - (c1 - c0) - (s1 - s0)).max(0.0), 2))
        }
        _ => Value::Null,
    };

    let period_ms = 1e3 / args.rate_hz;
    let late_threshold_ms = 1.25 * period_ms;
    let intervals = u64_at(&summary["setpoint_intervals"], "count");
    let late = late_intervals(&summary["setpoint_interval_buckets"], late_threshold_ms);
    let late_fraction = if intervals == 0 {
        1.0
    } else {
        late as f64 / intervals as f64
    };
    let setpoints_received = u64_at(&summary, "setpoints_received");
    let setpoints_sent = sent1.saturating_sub(sent0);
    let in_offboard = summary["modes"]["OFFBOARD"].as_u64().unwrap_or(0);
    let cpu = |a: Option<f64>, b: Option<f64>| match (a, b) {
        (Some(a), Some(b)) => json!(round(b - a, 2)),
        _ => Value::Null,
    };
    let iv = &summary["setpoint_intervals"];
    Ok(json!({
        "vehicles": n,
        "rate_hz": args.rate_hz,
        "seconds": round(window_s, 2),
        "setpoints_sent": setpoints_sent,
        "setpoints_received": setpoints_received,
        "late_fraction": late_fraction,
        "late_threshold_ms": late_threshold_ms,
        "intervals": intervals,
        "late_intervals": late,
        "interval_ms": {
            "p50": f64_at(iv, &["p50_ms"]),
            "p99": f64_at(iv, &["p99_ms"]),
            "p999": f64_at(iv, &["p999_ms"]),
            "max": f64_at(iv, &["max_ms"]),
            "mean": round(f64_at(iv, &["mean_ms"]), 3),
        },
        "coordinator_cpu_s": cpu(cpu0, cpu1),
        "coordinator_peak_rss_mb": peak_rss_mb().map(|m| round(m, 1)),
        "sim_cpu_s": cpu(sim_cpu0, sim_cpu1),
        "offboard_loss_failsafes": u64_at(&summary, "offboard_loss_failsafes"),
        "all_offboard": in_offboard == n as u64,
        "in_offboard": in_offboard,
        "hovering_at_start": hovering,
        "skein_send_errors": errors1 - errors0,
        "sim_send_drops": u64_at(&summary, "send_drops"),
        "sim_datagrams_sent": u64_at(&summary, "datagrams_sent"),
        "sim_datagrams_received": u64_at(&summary, "datagrams_received"),
        "setup_s": setup_s,
        "runtime_probe": probe_report(probe, late_threshold_ms),
        "host_other_cpu_s": other,
    }))
}

/// `skein bench plugins`: [`skein_plugin_host::bench_plugins`] on the plugin directory,
/// the isolated instances in `skein plugin-host` children of this executable. JSON:
/// `round_trip_us` (`in_process`, `process`: `n`, `p50`, `p99`, `max`), `load_us`,
/// `reload_us`, `restart_after_panic_us`, `restart_after_abort_us`, and the plugin measured.
///
/// # Errors
/// No example plugin in the directory, or a measurement failed.
pub fn plugins(args: &PluginsBenchArgs) -> Result<Value, String> {
    let dir = match &args.plugin_dir {
        Some(d) => d.clone(),
        None => std::env::current_exe()
            .ok()
            .and_then(|e| e.parent().map(std::path::Path::to_path_buf))
            .ok_or("cannot find the skein executable's directory: give --plugin-dir")?,
    };
    let child = skein_plugin_host::ChildCommand::skein_subcommand()
        .map_err(|e| format!("cannot find the skein executable: {e}"))?;
    let mut cfg = skein_plugin_host::BenchConfig::new(&dir, child);
    cfg.round_trips = args.round_trips.max(1);
    cfg.isolated_round_trips = args.isolated_round_trips.max(1);
    cfg.loads = args.loads.max(1);
    cfg.restarts = args.restarts.max(1);
    let mut report = skein_plugin_host::bench_plugins(&cfg)?;
    report["bench"] = json!("plugins");
    report["plugin_dir"] = json!(dir.display().to_string());
    Ok(report)
}

/// Slot of the payload whose actor `skein bench restart` panics.
const RESTART_BENCH_SLOT: &str = "fixture";

/// `skein bench restart` (issue 4's benchmark):
///
/// 1. starts skein's stack in this process with N vehicles of a model carrying one payload
///    (the built-in `fault-fixture`, a payload-like actor under each Vehicle actor), a
///    payload restart policy without backoff or budget (so that every panic is restarted
///    at once), and fault injection on; the simulator runs in its own process;
/// 2. takes every vehicle off and waits until it hovers under offboard control at R Hz;
/// 3. resets the simulator's counters, then injects `panics` panics one after the other
///    through the coordinator (the path of `POST /api/v1/faults`), round-robin over the
///    vehicles, one every `period_ms` at most, each time waiting for the
///    `actor_restarted` event of that payload;
/// 4. prints `restart_latency_us` (`n`, `p50`, `p99`, `max`, `mean`: the supervisor's own
///    measure, from the failure being noticed to the replacement answering its first
///    message), `inject_to_running_us` (the same seen from outside: from the fault request
///    to the restart event), `restarts`, `largest_setpoint_gap_ms` (the longest interval
///    between two setpoints of any vehicle as the simulator received them during the
///    panics), `offboard_loss_failsafes` and `all_offboard` at the end.
///
/// # Errors
/// Invalid arguments, the swarm or simulator not starting, a restart not seen within 5 s.
pub async fn restart(args: RestartBenchArgs) -> Result<Value, String> {
    use skein_model::supervision::RestartPolicy;
    use skein_payload::{Isolation, PayloadSpec};
    use skein_swarm::supervision::PolicyConfig;
    if args.vehicles == 0 || args.panics == 0 {
        return Err("--vehicles and --panics must be at least 1".into());
    }
    if !(args.rate_hz.is_finite() && args.rate_hz > 2.0) {
        return Err(format!(
            "--rate-hz {}: PX4 needs more than 2 Hz",
            args.rate_hz
        ));
    }
    let swarm_args = SwarmBenchArgs {
        vehicles: args.vehicles,
        rate_hz: args.rate_hz,
        seconds: 0.0,
        altitude_m: 2.0,
        spacing_m: 5.0,
        setup_timeout_s: None,
        seed: args.seed,
    };
    let mut config = bench_config(&swarm_args);
    let mut model = skein_swarm::VehicleModel::generic();
    model.name = "restart-bench".into();
    model.payloads = vec![PayloadSpec {
        slot: RESTART_BENCH_SLOT.into(),
        kind: skein_swarm::payload::FAULT_FIXTURE.into(),
        plugin: None,
        isolation: Isolation::InProcess,
        config: json!({}),
    }];
    config.models.insert(model.name.clone(), model);
    config.supervision.payload = PolicyConfig {
        policy: RestartPolicy::OnFailure,
        max_restarts: u32::MAX,
        window_s: 1.0,
        backoff_initial_ms: 0,
        backoff_max_ms: 0,
    };
    config.fault_injection = true;
    let started = Instant::now();
    let (swarm, base) = start_swarm(
        &swarm_args,
        config,
        SwarmServices::default(),
        Some("restart-bench"),
    )
    .await?;
    let mut sim = match SimProcess::start(&swarm_args, base).await {
        Ok(s) => s,
        Err(e) => {
            swarm.stop().await;
            return Err(e);
        }
    };
    let setup_deadline = started + Duration::from_secs(60 + args.vehicles as u64 / 10);
    let result = panic_payloads(&swarm, &mut sim, &args, &swarm_args, setup_deadline).await;
    sim.stop().await;
    swarm.stop().await;
    result
}

async fn panic_payloads(
    swarm: &Swarm,
    sim: &mut SimProcess,
    args: &RestartBenchArgs,
    swarm_args: &SwarmBenchArgs,
    setup_deadline: Instant,
) -> Result<Value, String> {
    use skein_model::supervision::FaultKind;
    use skein_swarm::events::SwarmEvent;
    let n = args.vehicles;
    let hovering = take_off_all(swarm, swarm_args, setup_deadline).await?;
    if hovering < n {
        return Err(format!("only {hovering} of {n} vehicles hover"));
    }
    eprintln!(
        "bench: {n} vehicles hovering; injecting {} panics",
        args.panics
    );
    let mut events = swarm.events.subscribe();
    sim.ask("reset").await?;
    let mut latency_us: Vec<f64> = Vec::with_capacity(args.panics);
    let mut outside_us: Vec<f64> = Vec::with_capacity(args.panics);
    let t0 = Instant::now();
    let mut next = tokio::time::Instant::now();
    for i in 0..args.panics {
        tokio::time::sleep_until(next).await;
        next += Duration::from_millis(args.period_ms);
        let path = format!("coordinator/uav-{}/payload/{RESTART_BENCH_SLOT}", i % n + 1);
        let asked = Instant::now();
        let target = path.clone();
        match swarm
            .coordinator
            .call(
                move |r| CoordinatorMsg::InjectFault(target, FaultKind::Panic, r),
                Some(COORDINATOR_TIMEOUT),
            )
            .await
        {
            Ok(ractor::rpc::CallResult::Success(Ok(()))) => {}
            Ok(ractor::rpc::CallResult::Success(Err(e))) => {
                return Err(format!("panic {i}: {path}: {e:?}"));
            }
            Ok(_) => return Err(format!("panic {i}: the coordinator did not answer")),
            Err(e) => return Err(format!("the coordinator is not running: {e}")),
        }
        let deadline = tokio::time::Instant::now() + Duration::from_secs(5);
        loop {
            match tokio::time::timeout_at(deadline, events.recv()).await {
                Ok(Ok(SwarmEvent::ActorRestarted {
                    path: p,
                    latency_us: l,
                    ..
                })) if p == path => {
                    outside_us.push(asked.elapsed().as_secs_f64() * 1e6);
                    latency_us.push(l as f64);
                    break;
                }
                Ok(Ok(_)) | Ok(Err(tokio::sync::broadcast::error::RecvError::Lagged(_))) => {}
                Ok(Err(tokio::sync::broadcast::error::RecvError::Closed)) => {
                    return Err("the swarm's event bus closed".into());
                }
                Err(_) => return Err(format!("panic {i}: {path} was not restarted within 5 s")),
            }
        }
        if (i + 1) % 250 == 0 {
            eprintln!("bench: {} panics restarted", i + 1);
        }
    }
    let window_s = t0.elapsed().as_secs_f64();
    let summary = sim.ask("summary").await?;
    let in_offboard = summary["modes"]["OFFBOARD"].as_u64().unwrap_or(0);
    Ok(json!({
        "bench": "restart",
        "vehicles": n,
        "rate_hz": args.rate_hz,
        "period_ms": args.period_ms,
        "panics": args.panics,
        "restarts": latency_us.len(),
        "restart_latency_us": skein_plugin_host::latency_summary_us(latency_us),
        "inject_to_running_us": skein_plugin_host::latency_summary_us(outside_us),
        "largest_setpoint_gap_ms": f64_at(&summary["setpoint_intervals"], &["max_ms"]),
        "setpoint_interval_p99_ms": f64_at(&summary["setpoint_intervals"], &["p99_ms"]),
        "offboard_loss_failsafes": u64_at(&summary, "offboard_loss_failsafes"),
        "all_offboard": in_offboard == n as u64,
        "seconds": round(window_s, 2),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn own_cpu_and_memory_are_readable_on_linux() {
        if !cfg!(target_os = "linux") {
            return;
        }
        let cpu = cpu_seconds(None).expect("/proc/self/stat");
        assert!(cpu >= 0.0);
        assert!(peak_rss_mb().expect("VmHWM") > 0.0);
        assert!(cpu_seconds(Some(std::process::id())).is_some());
    }

    #[test]
    fn late_intervals_count_buckets_above_the_threshold() {
        let buckets = json!([
            {"lo_ms": 19.9, "hi_ms": 20.0, "count": 90},
            {"lo_ms": 24.9, "hi_ms": 25.0, "count": 3},
            {"lo_ms": 25.0, "hi_ms": 25.1, "count": 2},
            {"lo_ms": 1000.0, "hi_ms": 1500.0, "count": 1},
        ]);
        assert_eq!(late_intervals(&buckets, 25.0), 3);
        assert_eq!(late_intervals(&json!(null), 25.0), 0);
    }

    #[test]
    fn metric_samples_are_summed_over_labels() {
        let text = "# HELP skein_setpoints_sent Offboard setpoints sent, per vehicle.\n\
                    # TYPE skein_setpoints_sent gauge\n\
                    skein_setpoints_sent{vehicle=\"uav-1\"} 120\n\
                    skein_setpoints_sent{vehicle=\"uav-2\"} 80\n\
                    skein_setpoints_sent_other 5\n";
        assert_eq!(sum_metric(text, "skein_setpoints_sent"), 200);
    }

    #[test]
    fn port_blocks_stay_below_the_ephemeral_range() {
        for attempt in 0..50 {
            let base = candidate_base(1000, attempt).expect("room for 1000");
            assert!(
                base >= 20_000 && usize::from(base) + 1000 <= 32_768,
                "{base}"
            );
        }
        assert!(candidate_base(20_000, 0).is_none());
    }
}
