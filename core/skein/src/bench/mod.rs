//! `skein bench <what>`: benchmarks that print one JSON object on stdout (progress goes to
//! stderr).
//!
//! `skein bench formation [--vehicles 8,32]`: formation flight in virtual time, see
//! [`formation`].
//!
//! `skein bench tracking [--seconds 120 --intruders 3 --seed 1]`: the counter-UAS chain
//! (intruders, cameras, detectors, tracker) against the simulator's truth, see
//! [`tracking`].
//!
//! `skein bench dds [--vehicles 8 --seconds 20]`: CPU of the ROS 2 topics per vehicle and
//! pose latency to a subscriber, see [`dds`]; with `--distributed`, N agents and a
//! coordinator against one process: slot-target latency, CPU per vehicle, formation
//! error, see [`distributed`].
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

mod dds;
mod distributed;
mod formation;
mod restart;
mod swarm;
mod tracking;
mod up_process;

pub use dds::{DdsBenchArgs, dds};
pub use formation::{FormationBenchArgs, formation};
pub use restart::{RestartBenchArgs, restart};
pub use swarm::swarm;
pub use tracking::{TrackingBenchArgs, tracking};

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
    /// vehicles on the PX4-faithful simulated multicopter): every shape behind a virtual
    /// leader at 5 m/s.
    Formation(FormationBenchArgs),
    /// Injected panics of a payload actor under hovering vehicles: restart latency and
    /// the largest gap in the offboard setpoint stream.
    Restart(RestartBenchArgs),
    /// Payload plugins: message round trips in-process and process-isolated, load and
    /// reload times, restart times after a panic and after an abort.
    Plugins(PluginsBenchArgs),
    /// Counter-UAS: 4 observation UAVs, seeded intruders; detection precision/recall, track
    /// RMSE, time to confirm, identity switches, false tracks (see `bench/tracking.rs`).
    Tracking(TrackingBenchArgs),
    /// ROS 2 topics: CPU of the DDS link per vehicle and pose latency to a subscriber on
    /// this host (see `bench/dds.rs`).
    Dds(DdsBenchArgs),
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
        BenchWhat::Tracking(a) => {
            let report = tokio::task::spawn_blocking(move || tracking(&a))
                .await
                .map_err(|e| e.to_string())??;
            println!("{report}");
            Ok(())
        }
        BenchWhat::Dds(a) => {
            println!("{}", dds(a).await?);
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
                    signing: None,
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

/// Rounds to `digits` decimals for the report.
pub(crate) fn round(x: f64, digits: i32) -> f64 {
    let k = 10f64.powi(digits);
    (x * k).round() / k
}
