//! `skein`: orchestrate a heterogeneous PX4 UAV swarm as one, from a browser.
//!
//! - `skein up --sim N`: a simulated swarm of N PX4-like multicopters, the coordinator and
//!   the dashboard (prints its URL).
//! - `skein up --config FILE`: the same for real vehicles (one `[[vehicles]]` table per
//!   vehicle, see [`config`]).
//! - `skein coordinator --priority P`: a coordinator candidate with no vehicles of its
//!   own (API, dashboard, DDS); the live candidate of highest priority is active, the
//!   others stand by (see [`coordinator`]).
//! - `skein agent --sim N --first-sysid K`: the vehicles of this computer, steered over
//!   DDS by the active coordinator (see [`agent`]).
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

mod agent;
mod bench;
mod config;
mod coordinator;
mod keys;
mod plugin_new;
mod replay;
mod sim_control;
mod up;

use clap::{Parser, Subcommand};
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::process::ExitCode;
use std::time::Duration;
use up::UpArgs;

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
    /// A coordinator candidate with no vehicles of its own: API, dashboard, DDS, and the
    /// election (`--priority P`; the live candidate with the highest is active).
    Coordinator(coordinator::CoordinatorArgs),
    /// The vehicles of this computer, steered over DDS by the active coordinator
    /// (`--sim N --first-sysid K` simulates vehicles K..K+N-1).
    Agent(agent::AgentArgs),
    /// Run the PX4 SITL-like simulator alone (instance i: sysid i+1, binds 14580+i, sends to 14540+i).
    Sim(skein_sim::cli::SimArgs),
    /// Benchmarks printing one JSON object (`skein bench swarm --vehicles N --rate-hz 50
    /// --seconds S`): runs the `skein-bench` executable beside this one.
    #[command(disable_help_flag = true)]
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

pub(crate) const DEFAULT_HTTP: SocketAddr = SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), 8080);

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
    skein_swarm::supervision::install_panic_hook();
    let result = runtime.block_on(async {
        match cli.command {
            Commands::Up(args) => up::up(args).await,
            Commands::Coordinator(args) => coordinator::coordinator(args).await,
            Commands::Agent(args) => agent::agent(args).await,
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
            Commands::Bench(args) => bench::run(args),
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
pub(crate) const EXIT_COORDINATOR_FAILED: u8 = 70;

/// Pings the coordinator from a thread of its own (so a wedged runtime cannot stop it);
/// a coordinator that does not answer within `deadline` is a hung root: exit non-zero.
pub(crate) fn spawn_process_watchdog(
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
pub(crate) fn refuse_unauthenticated(
    addr: SocketAddr,
    tokens: usize,
    insecure: bool,
) -> Result<(), String> {
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

pub(crate) async fn shutdown_signal() {
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
