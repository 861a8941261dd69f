//! The `skein bench` command line: one subcommand per benchmark, each printing one JSON
//! object on stdout (progress on stderr).

use crate::{
    ApiBenchArgs, DdsBenchArgs, FormationBenchArgs, MissionBenchArgs, RestartBenchArgs,
    TrackingBenchArgs,
};
use crate::{api, dds, formation, mission, plugins, restart, swarm, tracking};

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
    /// RMSE, time to confirm, identity switches, false tracks (see `core/bench/src/tracking/`).
    Tracking(TrackingBenchArgs),
    /// ROS 2 topics: CPU of the DDS link per vehicle and pose latency to a subscriber on
    /// this host (see `core/bench/src/dds.rs`).
    Dds(DdsBenchArgs),
    /// The API's reads while the coordinator is busy: latency of the dashboard's polled
    /// routes, quiet and with clients keeping the coordinator's mailbox full (see
    /// `core/bench/src/api.rs`).
    Api(ApiBenchArgs),
    /// A sortie of 8 vehicles (survey, patrol, an intruder, a battery swap) rehearsed in
    /// virtual time: its figures and how much faster than real time (see
    /// `core/bench/src/mission.rs`).
    Mission(MissionBenchArgs),
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
    /// After skein, fly the same swarm with this baseline against a fresh simulator in
    /// the same run and compare CPU per vehicle-second: `pymavlink` (a plain pymavlink
    /// loop, `tests/peers/pymavlink_loop.py`, run by `SKEIN_PYTHON`, the repository's
    /// `.venv`, or `python3`; a port per vehicle) or `floor` (a minimal controller on a
    /// thread of this process that only moves datagrams: frames encoded once, one
    /// `sendmmsg` per period for every vehicle, `recvmmsg` drains of the telemetry without
    /// decoding, CPU from the thread's schedstat; the run's ports per vehicle).
    #[arg(long, value_parser = clap::builder::PossibleValuesParser::new(crate::peer::PEERS))]
    pub peer: Option<String>,
    /// The baseline's script, instead of the repository's.
    #[arg(long)]
    pub peer_script: Option<std::path::PathBuf>,
    /// Vehicles per UDP port (1 to 250): 1 gives each vehicle its own port pair, as PX4
    /// SITL's first instances have; more share one `udpin` endpoint per group, as PX4's
    /// instances from the 10th on share port 14549 (frames told apart by sysid, the
    /// setpoints of a group handed to the socket in one `sendmmsg`). The pymavlink
    /// baseline keeps a port per vehicle; the floor shares ports as skein does.
    #[arg(long, default_value_t = 1)]
    pub vehicles_per_port: usize,
}

/// Runs `skein bench <what>`.
pub async fn run(args: BenchArgs) -> Result<(), String> {
    match args.what {
        BenchWhat::Swarm(a) => {
            let report = swarm(a).await?;
            println!("{report}");
            Ok(())
        }
        BenchWhat::Mission(a) => {
            let report = tokio::task::spawn_blocking(move || mission(&a))
                .await
                .map_err(|e| e.to_string())??;
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
        BenchWhat::Api(a) => {
            let report = tokio::task::spawn_blocking(move || api(&a))
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
