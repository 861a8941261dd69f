//! `skein`: orchestrate a heterogeneous PX4 UAV swarm as one, from a browser.
//!
//! - `skein up --sim N`: a simulated swarm of N PX4-like multicopters, the coordinator and
//!   the dashboard (prints its URL).
//! - `skein up --config FILE`: the same for real vehicles (one `[[vehicles]]` table per
//!   vehicle, see [`config`]).
//! - `skein coordinator --priority P`: a coordinator candidate with no vehicles of its
//!   own (API, dashboard, DDS); the live candidate of highest priority is active, the
//!   others stand by (see [`cmd::coordinator`]).
//! - `skein agent --sim N --first-sysid K`: the vehicles of this computer, steered over
//!   DDS by the active coordinator (see [`cmd::agent`]).
//! - `skein sim --vehicles N`: the simulator alone, for any MAVLink client.
//! - `skein fault --target PATH --kind panic|hang|stop|error`: inject a fault through the
//!   API of a running `skein up --enable-fault-injection`.
//! - `skein health [--url URL]`: exit 0 when the skein behind that API is healthy (the
//!   container image's health check, see [`cmd::health`]).
//! - `skein token create --role viewer|operator|admin [--name NAME]`: a new API token
//!   and the `[[http.tokens]]` line (with its salted hash) to add to the config.
//! - `skein key create [--out FILE]`: a random MAVLink 2 signing key file (mode 0600) and
//!   the `signing_key_file` line that uses it (see [`cmd::keys`]).
//! - `skein dds keystore create DIR`, `skein dds enclave create DIR --enclave NAME --role
//!   agent|coordinator|viewer`: DDS Security's SROS 2 keystore and a participant's enclave
//!   (see [`cmd::dds`]).
//! - `skein mission rehearse PLAN [--sim N] [--config FILE] [--svg FILE]`: a mission plan
//!   flown in virtual time on the swarm `skein up --sim N` would fly; its figures as JSON
//!   (see [`cmd::mission`]).
//! - `skein plugin new NAME [--kind KIND] [--dir DIR]`: write a payload plugin crate that
//!   builds as it is (see [`cmd::plugin_new`]).
//! - `skein plugin-host --socket PATH --library PATH` (internal, not in `--help`): the
//!   child process that runs one payload plugin library under process isolation, spoken
//!   to over a Unix socket (see `skein_plugin_host`).
//!
//! Each command is a module of [`cmd`] (the table there maps roles to files); `up`,
//! `coordinator` and `agent` are one composition of parts in three roles ([`compose`]); [`config`]
//! reads the config file, [`process`] holds what every long-running command shares
//! (signals, the exit status of a failed coordinator, the process watchdog), [`service`]
//! talks to systemd (readiness, watchdog), [`shutdown`] is what an agent does with its
//! vehicles before it exits.
#![warn(missing_docs)]

mod cmd;
mod compose;
mod config;
mod process;
mod service;
mod shutdown;
mod sim_control;

use clap::{Parser, Subcommand};
use cmd::{
    agent, bench, coordinator, dds, fault, health, keys, mission, plugin_new, replay, token, up,
};
use std::process::ExitCode;

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
    // Boxed: `skein up` has many more options than any other command.
    Up(Box<up::UpArgs>),
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
    Fault(fault::FaultArgs),
    /// Exit 0 when the skein behind an API is healthy (`GET /api/v1/health`), 1 otherwise:
    /// the container image's health check.
    Health(health::HealthArgs),
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
    /// Missions: `skein mission rehearse plan.toml --sim 4` flies a plan in virtual time on
    /// the swarm `skein up --sim 4` would fly and prints its figures (JSON).
    #[command(subcommand)]
    Mission(mission::MissionCommand),
    /// Play a recording (`skein up --record FILE.mcap`) back into the dashboard, read-only.
    Replay(replay::ReplayArgs),
    /// DDS Security: `skein dds keystore create DIR`, then `skein dds enclave create DIR
    /// --enclave /skein/agent/a1 --role agent` for each participant.
    #[command(subcommand)]
    Dds(dds::DdsCommand),
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
    Create(token::TokenCreateArgs),
}

#[derive(Subcommand, Debug)]
enum PluginCommand {
    /// Write a new payload plugin crate (Cargo.toml on this skein's SDK, export_plugin!,
    /// tests) that builds as it is.
    New(plugin_new::NewArgs),
}

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
            Commands::Up(args) => up::up(*args).await,
            Commands::Coordinator(args) => coordinator::coordinator(args).await,
            Commands::Agent(args) => agent::agent(args).await,
            Commands::Sim(args) => skein_sim::cli::run(args)
                .await
                .map(|()| ExitCode::SUCCESS)
                .map_err(|e| e.to_string()),
            Commands::Fault(args) => fault::fault(args),
            Commands::Health(args) => health::health(&args),
            Commands::Plugin(PluginCommand::New(args)) => plugin_new::run(args).map(|dir| {
                println!(
                    "skein: plugin crate written to {} (build it with `cargo build --release` \
                     there; its README says how to load and attach it)",
                    dir.display()
                );
                ExitCode::SUCCESS
            }),
            Commands::Bench(args) => bench::run(args),
            Commands::Token(TokenCommand::Create(args)) => token::token_create(&args),
            Commands::Key(KeyCommand::Create(args)) => keys::key_create(&args),
            Commands::Mission(command) => Ok(mission::run(command)),
            Commands::Replay(args) => replay::run(args).await,
            Commands::Dds(command) => dds::run(command),
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
