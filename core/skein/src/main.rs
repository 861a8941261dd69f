//! `skein`: orchestrate a heterogeneous PX4 UAV swarm as one, from a browser.
//!
//! - `skein up --sim N`: a simulated swarm of N PX4-like multicopters, the coordinator and
//!   the dashboard (prints its URL).
//! - `skein up --config FILE`: the same for real vehicles (one `[[vehicles]]` table per
//!   vehicle, see [`config`]).
//! - `skein sim --vehicles N`: the simulator alone, for any MAVLink client.
//! - `skein fault --target PATH --kind panic|hang|stop|error`: inject a fault through the
//!   API of a running `skein up --enable-fault-injection`.
//! - `skein token create --role viewer|operator|admin [--name NAME]`: a new API token
//!   and the `[[http.tokens]]` line (with its salted hash) to add to the config.
//! - `skein key create [--out FILE]`: a random MAVLink 2 signing key file (mode 0600) and
//!   the `signing_key_file` line that uses it (see [`keys`]).
//! - `skein plugin new NAME [--kind KIND] [--dir DIR]`: write a payload plugin crate that
//!   builds as it is (see [`plugin_new`]).
//! - `skein plugin-host --socket PATH --library PATH` (internal, not in `--help`): the
//!   child process that runs one payload plugin library under process isolation, spoken
//!   to over a Unix socket (see `skein_plugin_host`).
#![warn(missing_docs)]

mod bench;
mod config;
mod keys;
mod plugin_new;
mod replay;
mod sim_control;

use clap::{Parser, Subcommand};
use config::ConfigFile;
use skein_link::ConnectionAddress;
use skein_swarm::{EndpointSpec, Swarm, VehicleSpec};
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Duration;

/// Command line.
#[derive(Parser, Debug)]
#[command(
    name = "skein",
    version,
    about = "Fly a swarm of PX4 drones as one, from a browser."
)]
struct Cli {
    #[command(subcommand)]
    command: Commands,
}

#[derive(Subcommand, Debug)]
enum Commands {
    /// Run the coordinator, the HTTP API and the dashboard (with simulated and/or real vehicles).
    Up(UpArgs),
    /// Run the PX4 SITL-like simulator alone (instance i: sysid i+1, binds 14580+i, sends to 14540+i).
    Sim(skein_sim::cli::SimArgs),
    /// Benchmarks printing one JSON object (`skein bench swarm --vehicles N --rate-hz 50 --seconds S`).
    Bench(bench::BenchArgs),
    /// Inject a fault into an actor of a running skein (needs --enable-fault-injection there).
    Fault(FaultArgs),
    /// Payload plugins: `skein plugin new NAME` writes a plugin crate ready to build.
    #[command(subcommand)]
    Plugin(PluginCommand),
    /// API tokens: `skein token create --role operator --name ops` prints a new token and
    /// the `[[http.tokens]]` line to add to the config.
    #[command(subcommand)]
    Token(TokenCommand),
    /// MAVLink 2 signing keys: `skein key create --out uav.key` writes a random key
    /// (mode 0600) and prints the `signing_key_file` line to add to the config.
    #[command(subcommand)]
    Key(KeyCommand),
    /// Play a recording (`skein up --record FILE.mcap`) back into the dashboard, read-only.
    Replay(replay::ReplayArgs),
}

#[derive(Subcommand, Debug)]
enum KeyCommand {
    /// Write a new random signing key file (64 hex characters, mode 0600).
    Create(keys::KeyCreateArgs),
}

#[derive(Subcommand, Debug)]
enum TokenCommand {
    /// Print a new random token (give it to its holder) and the config line with its hash
    /// (the token itself is stored nowhere).
    Create(TokenCreateArgs),
}

#[derive(clap::Args, Debug)]
struct TokenCreateArgs {
    /// viewer (reads, the stream), operator (flies: commands, formation, payloads) or
    /// admin (plugins, parameter writes, faults, and everything else).
    #[arg(long)]
    role: skein_api::auth::Role,
    /// Who holds it (shown in the dashboard); default: the role.
    #[arg(long)]
    name: Option<String>,
}

#[derive(Subcommand, Debug)]
enum PluginCommand {
    /// Write a new payload plugin crate (Cargo.toml on this skein's SDK, export_plugin!,
    /// tests) that builds as it is.
    New(plugin_new::NewArgs),
}

#[derive(clap::Args, Debug)]
struct FaultArgs {
    /// Base URL of the running skein's API.
    #[arg(long, default_value = "http://127.0.0.1:8080")]
    url: String,
    /// API token (admin); default: the SKEIN_TOKEN environment variable.
    #[arg(long)]
    token: Option<String>,
    /// Actor path, e.g. coordinator/uav-1/px4link (see GET /api/v1/supervision).
    #[arg(long)]
    target: String,
    /// What to do to it: panic, hang, stop or error.
    #[arg(long)]
    kind: String,
}

#[derive(clap::Args, Debug)]
struct UpArgs {
    /// Simulate this many vehicles in-process.
    #[arg(long, value_name = "N")]
    sim: Option<usize>,
    /// Configuration file (TOML) with real vehicles and swarm settings.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Listen address of the HTTP API and dashboard (port 0 picks a free port).
    #[arg(long, value_name = "ADDR:PORT")]
    http: Option<SocketAddr>,
    /// With --sim: links listen on PORT+i and simulated vehicle i binds PORT+40+i (the
    /// PX4 SITL layout for 14540); 0 = free ports for both.
    #[arg(long, value_name = "PORT", default_value_t = 14540)]
    sim_base_port: u16,
    /// With --sim: seed of the simulator's random processes.
    #[arg(long, default_value_t = 0)]
    sim_seed: u64,
    /// With --sim: the vehicle model of every simulated vehicle (default: a mix, the
    /// even-numbered vehicles uav-2, uav-4, … `observation`, the others `generic`).
    #[arg(long, value_name = "MODEL")]
    sim_model: Option<String>,
    /// Payload plugin directory: every `lib*.so` in it is loaded at start (overrides
    /// `[plugins] dir`; default: the directory holding the skein executable, where
    /// `cargo build --release` puts the plugins).
    #[arg(long, value_name = "DIR")]
    plugin_dir: Option<PathBuf>,
    /// With --sim: open the simulator's stats socket here (one JSON line per command:
    /// stats, reset, silence SYSID MS, reboot SYSID); port 0 picks one, printed at start.
    #[arg(long, value_name = "ADDR:PORT")]
    sim_stats: Option<SocketAddr>,
    /// Accept POST /api/v1/faults (make actors panic, hang, stop or fail on purpose).
    #[arg(long)]
    enable_fault_injection: bool,
    /// Listen on a non-loopback address without any `[[http.tokens]]`: anyone who can
    /// reach the port can fly the swarm. Refused without this flag.
    #[arg(long)]
    insecure_no_auth: bool,
    /// Record the whole run to this MCAP file (never overwritten; Foxglove and
    /// `skein replay` read it). `POST /api/v1/recording/start` records on demand.
    #[arg(long, value_name = "FILE.mcap")]
    record: Option<PathBuf>,
    /// Forward every vehicle's MAVLink to a ground station and its commands back
    /// (overrides `[gcs] forward`), e.g. `udpout:127.0.0.1:14550` for QGroundControl;
    /// setpoints from it are dropped.
    #[arg(long, value_name = "CONNECTION")]
    gcs_forward: Option<skein_link::ConnectionAddress>,
    /// With --sim: MAVLink 2 signing key file (`skein key create`): the simulated vehicles
    /// require signed frames and skein's links sign.
    #[arg(long, value_name = "FILE")]
    sim_signing_key_file: Option<PathBuf>,
    /// With --sim: intruders, non-cooperative aircraft the simulated cameras see.
    #[command(flatten)]
    intruders: skein_sim::intruders::IntruderArgs,
}

const DEFAULT_HTTP: SocketAddr = SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), 8080);

fn main() -> ExitCode {
    // The plugin host child runs before anything else: no runtime, no logging set-up of
    // ours, nothing a plugin could disturb.
    let mut argv = std::env::args_os();
    if argv.nth(1).is_some_and(|a| a == "plugin-host") {
        return match skein_plugin_host::PluginHostArgs::parse(argv) {
            Ok(args) => skein_plugin_host::plugin_host_main(args),
            Err(e) => {
                eprintln!("skein {e}");
                ExitCode::from(2)
            }
        };
    }
    let cli = Cli::parse();
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_env("SKEIN_LOG")
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .init();
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
    {
        Ok(r) => r,
        Err(e) => {
            eprintln!("skein: cannot start the runtime: {e}");
            return ExitCode::FAILURE;
        }
    };
    install_panic_hook();
    let result = runtime.block_on(async {
        match cli.command {
            Commands::Up(args) => up(args).await,
            Commands::Sim(args) => skein_sim::cli::run(args)
                .await
                .map(|()| ExitCode::SUCCESS)
                .map_err(|e| e.to_string()),
            Commands::Fault(args) => fault(args),
            Commands::Plugin(PluginCommand::New(args)) => plugin_new::run(args).map(|dir| {
                println!(
                    "skein: plugin crate written to {} (build it with `cargo build --release` \
                     there; its README says how to load and attach it)",
                    dir.display()
                );
                ExitCode::SUCCESS
            }),
            Commands::Bench(args) => bench::run(args).await.map(|()| ExitCode::SUCCESS),
            Commands::Token(TokenCommand::Create(args)) => token_create(&args),
            Commands::Key(KeyCommand::Create(args)) => keys::key_create(&args),
            Commands::Replay(args) => replay::run(args).await,
        }
    });
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("skein: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Exit status when the coordinator failed (EX_SOFTWARE): for systemd or Docker to
/// restart the process.
const EXIT_COORDINATOR_FAILED: u8 = 70;

/// One line per panic, no backtrace: supervised actors panic on purpose in fault tests,
/// and the default hook (with `RUST_BACKTRACE=1`) costs ~100 µs of restart latency.
fn install_panic_hook() {
    std::panic::set_hook(Box::new(|info| {
        let msg = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "non-string panic payload".into());
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        tracing::error!("panic: {msg}{at}");
    }));
}

/// Pings the coordinator from a thread of its own (so a wedged runtime cannot stop it);
/// a coordinator that does not answer within `deadline` is a hung root: exit non-zero.
fn spawn_process_watchdog(
    coordinator: ractor::ActorRef<skein_swarm::CoordinatorMsg>,
    deadline: Duration,
) {
    std::thread::Builder::new()
        .name("skein-watchdog".into())
        .spawn(move || {
            let Ok(rt) = tokio::runtime::Builder::new_current_thread()
                .enable_time()
                .build()
            else {
                return;
            };
            rt.block_on(async move {
                loop {
                    tokio::time::sleep(Duration::from_millis(500)).await;
                    match coordinator
                        .call(skein_swarm::CoordinatorMsg::Ping, Some(deadline))
                        .await
                    {
                        Ok(ractor::rpc::CallResult::Success(())) => {}
                        Ok(ractor::rpc::CallResult::Timeout) => {
                            tracing::error!(
                                "the coordinator did not answer for {} ms: exiting",
                                deadline.as_millis()
                            );
                            std::process::exit(i32::from(EXIT_COORDINATOR_FAILED));
                        }
                        // Stopped or failed: the main task handles it.
                        _ => return,
                    }
                }
            });
        })
        .expect("spawn the watchdog thread");
}

fn token_create(args: &TokenCreateArgs) -> Result<ExitCode, String> {
    let token = skein_api::auth::new_token()?;
    let hash = skein_api::auth::hash_token(&token)?;
    let name = args.name.clone().unwrap_or_else(|| args.role.to_string());
    if name.contains(['"', '\\', '\n']) {
        return Err(format!(
            "--name {name:?}: no quotes, backslashes or newlines"
        ));
    }
    println!("token: {token}");
    println!();
    println!("# Add to the [http] part of the config file (the token itself is not stored):");
    println!("[[http.tokens]]");
    println!("name = \"{name}\"");
    println!("role = \"{}\"", args.role);
    println!("hash = \"{hash}\"");
    Ok(ExitCode::SUCCESS)
}

/// Why skein will not listen on `addr`: not loopback, no tokens, and no
/// `--insecure-no-auth`.
fn refuse_unauthenticated(addr: SocketAddr, tokens: usize, insecure: bool) -> Result<(), String> {
    if tokens > 0 || insecure || addr.ip().is_loopback() {
        return Ok(());
    }
    Err(format!(
        "refusing to listen on {addr} without authentication: anyone on that network could \
         fly the swarm. Add tokens to the config ([[http.tokens]], made by `skein token create \
         --role operator`), listen on 127.0.0.1, or pass --insecure-no-auth if you really mean it"
    ))
}

fn fault(args: FaultArgs) -> Result<ExitCode, String> {
    let agent: ureq::Agent = ureq::Agent::config_builder()
        .http_status_as_error(false)
        .timeout_global(Some(Duration::from_secs(10)))
        .build()
        .into();
    let url = format!("{}/api/v1/faults", args.url.trim_end_matches('/'));
    let mut req = agent.post(&url);
    if let Some(t) = args
        .token
        .clone()
        .or_else(|| std::env::var("SKEIN_TOKEN").ok())
    {
        req = req.header("Authorization", format!("Bearer {t}"));
    }
    let mut resp = req
        .send_json(serde_json::json!({"target": args.target, "kind": args.kind}))
        .map_err(|e| format!("{url}: {e}"))?;
    let status = resp.status().as_u16();
    let body = resp.body_mut().read_to_string().unwrap_or_default();
    if status == 202 {
        println!("{body}");
        Ok(ExitCode::SUCCESS)
    } else {
        Err(format!("{url}: HTTP {status}: {body}"))
    }
}

async fn shutdown_signal() {
    let ctrl_c = tokio::signal::ctrl_c();
    #[cfg(unix)]
    {
        let mut term =
            match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
                Ok(t) => t,
                Err(_) => {
                    let _ = ctrl_c.await;
                    return;
                }
            };
        tokio::select! {
            _ = ctrl_c => {}
            _ = term.recv() => {}
        }
    }
    #[cfg(not(unix))]
    let _ = ctrl_c.await;
}

async fn up(args: UpArgs) -> Result<ExitCode, String> {
    let file = match &args.config {
        Some(path) => ConfigFile::load(path)?,
        None => ConfigFile::default(),
    };
    let http = args.http.or(file.http.listen).unwrap_or(DEFAULT_HTTP);
    refuse_unauthenticated(http, file.http.tokens.len(), args.insecure_no_auth)?;
    let auth = skein_api::auth::Auth::new(&file.http.tokens)?;
    let tls = match (&file.http.tls_cert, &file.http.tls_key) {
        (Some(cert), Some(key)) => Some(skein_api::tls::server_config(cert, key)?),
        (None, None) => None,
        _ => return Err("[http]: tls_cert and tls_key go together".into()),
    };
    if args.insecure_no_auth && !auth.enabled() && !http.ip().is_loopback() {
        eprintln!("skein: WARNING: --insecure-no-auth: the API on {http} has no authentication");
    }
    if args.sim.is_none() && args.intruders.intruders > 0 {
        return Err("--intruders needs --sim N (intruders fly in the simulator)".into());
    }
    if args.sim.is_none() && file.vehicles.is_empty() {
        return Err("nothing to fly: give --sim N or a --config file with [[vehicles]]".into());
    }
    let mut endpoints: Vec<EndpointSpec> = file.endpoints()?;
    let sim_key = match &args.sim_signing_key_file {
        Some(f) => Some(skein_mavlink::signing::SigningKey::load(f).map_err(|e| e.to_string())?),
        None => None,
    };
    let real = endpoints.len();
    let n_sim = args.sim.unwrap_or(0);
    if n_sim > 255 {
        return Err(format!(
            "--sim {n_sim}: at most 255 simulated vehicles (MAVLink system ids)"
        ));
    }
    let localhost = IpAddr::V4(Ipv4Addr::LOCALHOST);
    let port = |offset: usize| -> Result<u16, String> {
        if args.sim_base_port == 0 {
            return Ok(0);
        }
        u16::try_from(usize::from(args.sim_base_port) + offset).map_err(|_| {
            format!(
                "--sim-base-port {}: ports run past 65535",
                args.sim_base_port
            )
        })
    };
    let mut config = file.swarm_config()?;
    config.fault_injection = args.enable_fault_injection;
    let geofence = config.geofence.clone();
    let swarm_setpoint_separation = config.setpoint_separation_m();
    if let Some(m) = &args.sim_model
        && !config.models.contains_key(m)
    {
        return Err(format!(
            "--sim-model {m}: no such vehicle model (known: {})",
            config.models.keys().cloned().collect::<Vec<_>>().join(", ")
        ));
    }
    for i in 0..n_sim {
        endpoints.push(EndpointSpec {
            connection: ConnectionAddress::UdpIn(SocketAddr::new(localhost, port(i)?)),
            vehicles: vec![VehicleSpec {
                id: None,
                sysid: Some((i + 1) as u8),
                model: Some(
                    args.sim_model
                        .clone()
                        .unwrap_or_else(|| sim_mix_model(i + 1).to_string()),
                ),
                signing: sim_key
                    .clone()
                    .map(|key| skein_link::SigningSpec { key, link_id: 0 }),
            }],
            simulated: true,
        });
    }
    let plugin_dir = match args.plugin_dir.clone().or(file.plugins.dir.clone()) {
        Some(d) => d,
        None => default_plugin_dir()?,
    };
    let (plugins, refused) = start_plugins(&plugin_dir)?;
    let factory: Arc<dyn skein_payload::PayloadFactory> =
        Arc::new(skein_swarm::payload::Factories(vec![
            Arc::new(plugins.clone()),
            Arc::new(skein_swarm::payload::BuiltinPayloads),
        ]));
    warn_missing_kinds(&config, &endpoints, factory.as_ref(), &plugin_dir);
    // The simulator is created before the swarm so payloads can reach it; it starts
    // sending once it knows where (after the endpoints are bound).
    let sim_slot: Arc<std::sync::OnceLock<skein_sim::Simulator>> = Arc::default();
    let services = skein_swarm::SwarmServices {
        payloads: factory,
        simulator: if n_sim > 0 {
            Some(Arc::new(sim_control::LateSimControl(sim_slot.clone())))
        } else {
            None
        },
    };
    let mut swarm = Swarm::start(config, services, file.identity(), endpoints)
        .await
        .map_err(|e| e.to_string())?;
    // Kept for the life of the process: dropping it stops the forwarding.
    let _gcs = match args
        .gcs_forward
        .clone()
        .or(file.gcs.forward.clone().map(|c| c.0))
    {
        Some(addr) => {
            let fwd = swarm
                .forward_to_gcs(addr)
                .await
                .map_err(|e| e.to_string())?;
            println!(
                "skein: forwarding MAVLink to the ground station at {}",
                fwd.address()
            );
            Some(fwd)
        }
        None => None,
    };
    // A reloaded plugin: the vehicles re-create its instances on the new build at once
    // (an instance that calls first re-creates itself; either way no failure is counted).
    // A loaded or unloaded one: the vehicles start the slots waiting for it, or stop its
    // instances (their slots wait again).
    let coordinator = swarm.coordinator.clone();
    plugins.subscribe(move |event| match event {
        skein_plugin_host::PluginEvent::Reloaded {
            stale_instances, ..
        } => {
            let list = stale_instances
                .iter()
                .map(|i| (i.vehicle_id.clone(), i.slot.clone()))
                .collect();
            let _ = coordinator.cast(skein_swarm::CoordinatorMsg::RefreshPayloads(
                list,
                std::time::Instant::now(),
            ));
        }
        skein_plugin_host::PluginEvent::Loaded { .. }
        | skein_plugin_host::PluginEvent::Unloaded { .. } => {
            let _ = coordinator.cast(skein_swarm::CoordinatorMsg::PluginsChanged);
        }
        skein_plugin_host::PluginEvent::Refused { .. } => {}
    });

    let sim = if n_sim > 0 {
        let vehicles = (0..n_sim)
            .map(|i| {
                let target = swarm.endpoints[real + i]
                    .local_addr()
                    .expect("udp endpoint has an address");
                Ok(skein_sim::SimVehicleConfig {
                    sysid: (i + 1) as u8,
                    bind: SocketAddr::new(localhost, port(40 + i)?),
                    target,
                })
            })
            .collect::<Result<Vec<_>, String>>()?;
        let mut cfg = skein_sim::SimConfig::with_vehicles(vehicles);
        cfg.seed = args.sim_seed;
        if let Some(key) = sim_key {
            cfg.signing_key = Some(key);
            cfg.params.push(("MAV_SIGN_CFG".into(), 2.0));
        }
        // Vehicles start as far apart as formation slots must be, so that the first
        // formation's transition keeps the separation too (see skein_swarm::formation).
        cfg.spacing_m = cfg
            .spacing_m
            .max(1.05 * std::f64::consts::SQRT_2 * swarm_setpoint_separation);
        let sim = skein_sim::Simulator::start(cfg)
            .await
            .map_err(|e| format!("simulator: {e}"))?;
        if args.intruders.intruders > 0 {
            sim.start_intruders(args.intruders.config(args.sim_seed))
                .map_err(|e| format!("--intruders: {e}"))?;
            println!(
                "skein: {} intruders in the simulator",
                args.intruders.intruders
            );
        }
        let _ = sim_slot.set(sim.clone());
        if let Some(addr) = args.sim_stats {
            let listener = tokio::net::TcpListener::bind(addr)
                .await
                .map_err(|e| format!("--sim-stats {addr}: {e}"))?;
            let local = listener.local_addr().map_err(|e| e.to_string())?;
            println!("skein: simulator stats at {local}");
            tokio::spawn(skein_sim::cli::serve_stats(sim.clone(), listener));
        }
        let ports: Vec<String> = swarm.endpoints[real..]
            .iter()
            .filter_map(|e| e.local_addr().map(|a| a.port().to_string()))
            .collect();
        println!(
            "skein: {n_sim} simulated vehicles, MAVLink links on udp 127.0.0.1 ports {}",
            ports.join(",")
        );
        Some(sim)
    } else {
        None
    };

    let listener = std::net::TcpListener::bind(http).map_err(|e| format!("--http {http}: {e}"))?;
    let local = listener.local_addr().map_err(|e| e.to_string())?;
    let recorder = skein_record::Recorder::new(
        skein_record::Sources {
            coordinator: swarm.coordinator.clone(),
            events: swarm.events.clone(),
            endpoints: swarm.endpoints.clone(),
        },
        file.recording
            .dir
            .clone()
            .unwrap_or_else(|| PathBuf::from("recordings")),
    );
    if let Some(path) = &args.record {
        let info = recorder
            .start(None, Some(path))
            .map_err(|e| format!("--record {}: {e}", path.display()))?;
        println!("skein: recording to {}", info.path.display());
    }
    let state = skein_api::ApiState::new(swarm.coordinator.clone(), swarm.events.clone())
        .with_plugins(plugins, refused)
        .with_geofence(geofence)
        .with_auth(auth)
        .with_recorder(recorder.clone());
    let scheme = if tls.is_some() { "https" } else { "http" };
    let state = match tls {
        Some(t) => state.with_tls(t),
        None => state,
    };
    let service = skein_api::ApiServer::service(listener, state);
    match swarm
        .coordinator
        .call(
            |r| skein_swarm::CoordinatorMsg::AddService(service, r),
            Some(Duration::from_secs(10)),
        )
        .await
    {
        Ok(ractor::rpc::CallResult::Success(Ok(()))) => {}
        Ok(ractor::rpc::CallResult::Success(Err(e))) => return Err(e),
        _ => return Err("the coordinator did not start the API".into()),
    }
    println!("skein: dashboard at {scheme}://{local}/");
    spawn_process_watchdog(
        swarm.coordinator.clone(),
        Duration::from_millis(
            file.swarm_config()?
                .supervision
                .watchdog_deadline_ms
                .max(1000)
                * 2,
        ),
    );
    let code = tokio::select! {
        _ = shutdown_signal() => {
            eprintln!("skein: shutting down");
            ExitCode::SUCCESS
        }
        _ = swarm.stopped() => {
            tracing::error!("the coordinator failed: exiting for the outer supervisor to restart skein");
            ExitCode::from(EXIT_COORDINATOR_FAILED)
        }
    };
    if recorder.status().is_some() {
        match recorder.stop().await {
            Ok(s) => println!(
                "skein: recording {} finished: {} messages on {} channels, {:.1} s",
                s.path.display(),
                s.messages,
                s.channels,
                s.duration_s
            ),
            Err(e) => eprintln!("skein: the recording could not be finished: {e}"),
        }
    }
    if swarm.is_running() {
        swarm.stop().await;
    }
    if let Some(sim) = sim {
        sim.shutdown().await;
    }
    Ok(code)
}

/// The model of simulated vehicle `sysid` when `--sim-model` is not given: every other
/// vehicle (the even sysids: uav-2, uav-4, …) is an `observation` UAV (gimbal and camera),
/// the others `generic`, so the dashboard shows both.
fn sim_mix_model(sysid: usize) -> &'static str {
    if sysid.is_multiple_of(2) {
        "observation"
    } else {
        "generic"
    }
}

/// The plugin directory when none is configured: the directory of the running executable
/// (cargo builds the plugin libraries `libskein_plugin_*.so` next to `target/*/skein`).
///
/// # Errors
/// The executable's path cannot be found.
fn default_plugin_dir() -> Result<PathBuf, String> {
    let exe = std::env::current_exe()
        .map_err(|e| format!("cannot find the skein executable's directory: {e}"))?;
    exe.parent()
        .map(std::path::Path::to_path_buf)
        .ok_or_else(|| format!("{}: no parent directory", exe.display()))
}

/// Creates the plugin manager for `dir` and loads every library in it. The manager logs
/// each loaded library and each refused file (naming the file and what differs); one
/// summary line goes to stdout.
///
/// Returns the manager and the refused files with the reason.
///
/// # Errors
/// `dir` cannot be read, or the plugin work directory cannot be created.
fn start_plugins(
    dir: &std::path::Path,
) -> Result<(skein_plugin_host::PluginManager, Refused), String> {
    let manager = skein_plugin_host::PluginManager::new(skein_plugin_host::HostConfig::new(dir))
        .map_err(|e| format!("plugins: {e}"))?;
    let entries = manager
        .scan()
        .map_err(|e| format!("--plugin-dir {}: {e}", dir.display()))?;
    let loaded: Vec<String> = entries
        .iter()
        .filter_map(|e| e.result.as_ref().ok())
        .map(|i| format!("{} {}", i.name, i.version))
        .collect();
    let refused: Refused = entries
        .iter()
        .filter_map(|e| match &e.result {
            Err(err) => Some((e.file.clone(), err.to_string())),
            Ok(_) => None,
        })
        .collect();
    println!(
        "skein: plugins from {}: {} loaded ({}), {} refused",
        dir.display(),
        loaded.len(),
        loaded.join(", "),
        refused.len()
    );
    Ok((manager, refused))
}

/// Files the plugin scan refused, with the reason.
type Refused = Vec<(PathBuf, String)>;

/// Warns once per payload kind that a vehicle's model needs and no loaded plugin (nor a
/// built-in) provides: those payloads wait for a plugin (loaded later through the API)
/// while the vehicles fly on.
fn warn_missing_kinds(
    config: &skein_swarm::SwarmConfig,
    endpoints: &[EndpointSpec],
    factory: &dyn skein_payload::PayloadFactory,
    plugin_dir: &std::path::Path,
) {
    let providers = factory.providers();
    let mut warned = std::collections::BTreeSet::new();
    for v in endpoints.iter().flat_map(|e| &e.vehicles) {
        let model = config.model(v.model.as_deref().unwrap_or("generic"));
        for p in &model.payloads {
            let provided = providers.iter().any(|pr| {
                pr.kinds.contains(&p.kind) && p.plugin.as_ref().is_none_or(|n| *n == pr.name)
            });
            if !provided && warned.insert(p.kind.clone()) {
                tracing::warn!(
                    "no plugin in {} provides payload kind `{}` (model `{}`, slot `{}`): those \
                     payloads wait for one while the vehicles fly on; build the plugins with \
                     `cargo build --release` (they land next to the skein binary) or give \
                     --plugin-dir, or load one at run time (POST /api/v1/plugins/load)",
                    plugin_dir.display(),
                    p.kind,
                    model.name,
                    p.slot
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sim_mix_alternates_generic_and_observation() {
        let models: Vec<&str> = (1..=5).map(sim_mix_model).collect();
        assert_eq!(
            models,
            [
                "generic",
                "observation",
                "generic",
                "observation",
                "generic"
            ]
        );
    }
}
