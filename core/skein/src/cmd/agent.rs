//! `skein agent`: the vehicles wired to this computer (their PX4 links, FSMs, control
//! loops, setpoint streams and payloads, kept separated from the neighbours heard on
//! DDS), steered over DDS by the active coordinator of the domain (`skein coordinator`,
//! see `skein_dds::agent`). Several agents may share a machine: `--sim N --first-sysid K`
//! simulates vehicles K to K+N-1, laid out on a grid by sysid.
//!
//! The agent's own API listens on loopback (`127.0.0.1`, a free port unless `--http`
//! names one, printed at start): it is for looking at this computer's vehicles and for
//! the container's health check (`skein health`); the swarm is flown through the active
//! coordinator's API.
//!
//! Told to stop (SIGTERM, Ctrl-C), the agent first lands its airborne vehicles (or puts
//! them in PX4 Hold or RTL: `--shutdown-action`, `[agent] shutdown_action`), then exits 0
//! (see [`crate::shutdown`]).
//!
//! The composition of [`crate::compose`] in its [`Role::Agent`] role: `skein up`'s options at
//! their defaults, then this command's.

use crate::compose::{AgentRole, Role, UpArgs, hostname, run};
use crate::config::ConfigFile;
use crate::shutdown::{ShutdownAction, ShutdownPlan};
use clap::Args;
use skein_dds::agent::{AgentConfig, LostAction};
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

/// Command line of `skein agent`.
#[derive(Args, Debug)]
pub struct AgentArgs {
    /// Simulate this many vehicles in-process (sysids from --first-sysid).
    #[arg(long, value_name = "N", env = "SKEIN_SIM")]
    sim: Option<usize>,
    /// With --sim: the first simulated vehicle's MAVLink system id (its id `uav-K`).
    #[arg(long, value_name = "K", default_value_t = 1, env = "SKEIN_FIRST_SYSID",
          value_parser = clap::value_parser!(u8).range(1..))]
    first_sysid: u8,
    /// With --sim: links listen on PORT+sysid-1, simulated vehicles bind PORT+40+sysid-1;
    /// 0 = free ports.
    #[arg(long, value_name = "PORT", default_value_t = 14540)]
    sim_base_port: u16,
    /// With --sim: the vehicle model of every simulated vehicle (default: as `skein up`,
    /// the even sysids `observation`, the others `generic`).
    #[arg(long, value_name = "MODEL")]
    sim_model: Option<String>,
    /// With --sim: seed of the simulator's random processes.
    #[arg(long, default_value_t = 0)]
    sim_seed: u64,
    /// With --sim: the simulated GNSS receivers wander (as `skein up --sim-gnss-wander`).
    #[arg(long)]
    sim_gnss_wander: bool,
    /// With --sim: the simulator's stats socket (as `skein up --sim-stats`).
    #[arg(long, value_name = "ADDR:PORT")]
    sim_stats: Option<SocketAddr>,
    /// Configuration file (TOML): `[[vehicles]]`, `[agent]`, `[dds]`, swarm settings.
    #[arg(long, value_name = "FILE", env = "SKEIN_CONFIG")]
    config: Option<PathBuf>,
    /// Id on the swarm protocol topics (default `<hostname>-<pid>`).
    #[arg(long, value_name = "ID", env = "SKEIN_ID")]
    id: Option<String>,
    /// Listen address of this agent's own API (default `127.0.0.1:0`, a free port; a
    /// non-loopback address needs `[[http.tokens]]`, as `skein up`).
    #[arg(long, value_name = "ADDR:PORT", env = "SKEIN_HTTP")]
    http: Option<SocketAddr>,
    /// The DDS domain, 0 to 232 (default `[dds] domain_id`, else `ROS_DOMAIN_ID`, else 0).
    #[arg(long, value_name = "D", value_parser = skein_dds::parse_domain_id)]
    domain_id: Option<u16>,
    /// Use only the interface with this local address for DDS (repeatable).
    #[arg(long, value_name = "ADDR")]
    dds_network: Vec<IpAddr>,
    #[command(flatten)]
    dds_security: super::dds::DdsSecurityArgs,
    /// No coordinator heard for this long: hold (default `[agent] coordinator_timeout_s`,
    /// else 1.5).
    #[arg(long, value_name = "S")]
    coordinator_timeout_s: Option<f64>,
    /// How long a vehicle flies its slot on from the formation's mirror when its slot
    /// targets stop (a WLAN fade, a coordinator gone), before it holds; 0: never (default
    /// `[agent] coordinator_ride_through_s`, else 4).
    #[arg(long, value_name = "S")]
    coordinator_ride_through_s: Option<f64>,
    /// What to do after holding for --coordinator-lost-action-s: hold, land or rtl
    /// (default `[agent] coordinator_lost_action`, else hold).
    #[arg(long, value_name = "ACTION")]
    coordinator_lost_action: Option<String>,
    /// Seconds of holding before the lost action (default `[agent]
    /// coordinator_lost_action_s`, else 30).
    #[arg(long, value_name = "S")]
    coordinator_lost_action_s: Option<f64>,
    /// What the airborne vehicles do before the agent exits on SIGTERM or Ctrl-C: land,
    /// hold (PX4 Hold) or rtl (default `[agent] shutdown_action`, else land).
    #[arg(long, value_name = "ACTION")]
    shutdown_action: Option<String>,
    /// The longest wait for them at shutdown (default `[agent] shutdown_timeout_s`, else
    /// 60).
    #[arg(long, value_name = "S")]
    shutdown_timeout_s: Option<f64>,
    /// Plugin directory (as `skein up --plugin-dir`).
    #[arg(long, value_name = "DIR", env = "SKEIN_PLUGIN_DIR")]
    plugin_dir: Option<PathBuf>,
    /// Tests only: runs this process's wall clock this many milliseconds off, as a host
    /// whose clock is off would (the clock exchange must correct for it).
    #[arg(long, value_name = "MS", hide = true, allow_hyphen_values = true)]
    test_clock_skew_ms: Option<i64>,
}

/// Runs an agent until a signal or its coordinator actor's failure.
///
/// # Errors
/// A bad config or option (named), a port in use, DDS that cannot start.
pub async fn agent(args: AgentArgs) -> Result<ExitCode, String> {
    let id = match &args.id {
        Some(id) if id.trim().is_empty() => return Err("--id: empty".into()),
        Some(id) => id.clone(),
        None => format!("{}-{}", hostname(), std::process::id()),
    };
    let file = match &args.config {
        Some(path) => ConfigFile::load(path)?,
        None => ConfigFile::default(),
    };
    if let Some(ms) = args.test_clock_skew_ms {
        eprintln!("skein: tests only: this agent's wall clock runs {ms} ms off");
        skein_swarm::protocol::skew_wall_clock(ms);
    }
    let config = carrier_config(&args, &file, id)?;
    let shutdown = shutdown_plan(&args, &file)?;
    if let Some(n) = args.sim
        && usize::from(args.first_sysid) + n > 256
    {
        return Err(format!(
            "--sim {n} --first-sysid {}: system ids run past 255",
            args.first_sysid
        ));
    }
    let role = Role::Agent(AgentRole {
        first_sysid: args.first_sysid,
        config,
        shutdown,
    });
    run(role, up_args(args)?).await
}

/// `skein up`'s options at their defaults, then this role's (the API on a free loopback
/// port unless `--http` names one).
fn up_args(args: AgentArgs) -> Result<UpArgs, String> {
    let http = args
        .http
        .unwrap_or(SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), 0));
    let mut up_args = UpArgs::for_role(
        args.config,
        Some(http),
        args.domain_id,
        args.dds_network,
        args.dds_security,
    )?;
    up_args.sim = args.sim;
    up_args.sim_base_port = args.sim_base_port;
    up_args.sim_seed = args.sim_seed;
    up_args.sim_gnss_wander = args.sim_gnss_wander;
    up_args.sim_model = args.sim_model;
    up_args.sim_stats = args.sim_stats;
    up_args.plugin_dir = args.plugin_dir;
    Ok(up_args)
}

/// `what` as a time in (0, 3600] seconds, if given.
fn seconds(what: &str, v: Option<f64>) -> Result<Option<Duration>, String> {
    match v {
        None => Ok(None),
        Some(s) if s.is_finite() && s > 0.0 && s <= 3600.0 => Ok(Some(Duration::from_secs_f64(s))),
        Some(s) => Err(format!("{what}: {s} is not a time in (0, 3600] seconds")),
    }
}

/// The agent carrier's settings: the flags over `[agent]` over the defaults.
///
/// # Errors
/// A time out of range or an unknown lost action (named).
fn carrier_config(args: &AgentArgs, file: &ConfigFile, id: String) -> Result<AgentConfig, String> {
    let mut config = AgentConfig::new(id);
    if let Some(d) = seconds(
        "coordinator_timeout_s",
        args.coordinator_timeout_s
            .or(file.agent.coordinator_timeout_s),
    )? {
        config.coordinator_timeout = d;
    }
    match args
        .coordinator_ride_through_s
        .or(file.agent.coordinator_ride_through_s)
    {
        Some(0.0) => config.ride_through = Duration::ZERO,
        v => {
            if let Some(d) = seconds("coordinator_ride_through_s", v)? {
                config.ride_through = d;
            }
        }
    }
    if let Some(d) = seconds(
        "coordinator_lost_action_s",
        args.coordinator_lost_action_s
            .or(file.agent.coordinator_lost_action_s),
    )? {
        config.lost_action_after = d;
    }
    if let Some(a) = args
        .coordinator_lost_action
        .clone()
        .or(file.agent.coordinator_lost_action.clone())
    {
        config.lost_action = a
            .parse::<LostAction>()
            .map_err(|e| format!("coordinator_lost_action: {e}"))?;
    }
    Ok(config)
}

/// What the vehicles do at shutdown: the flags over `[agent]` over the default (land,
/// within 60 s).
///
/// # Errors
/// An unknown action or a time out of range (named).
fn shutdown_plan(args: &AgentArgs, file: &ConfigFile) -> Result<ShutdownPlan, String> {
    let mut shutdown = ShutdownPlan::default();
    if let Some(a) = args
        .shutdown_action
        .clone()
        .or(file.agent.shutdown_action.clone())
    {
        shutdown.action = a
            .parse::<ShutdownAction>()
            .map_err(|e| format!("shutdown_action: {e}"))?;
    }
    if let Some(d) = seconds(
        "shutdown_timeout_s",
        args.shutdown_timeout_s.or(file.agent.shutdown_timeout_s),
    )? {
        shutdown.timeout = d;
    }
    Ok(shutdown)
}
