//! The options of a skein process: every one is a flag of `skein up` ([`UpArgs`]); `skein
//! agent` and `skein coordinator` start from their defaults ([`UpArgs::defaults`]) and
//! set the few they have flags for.

use crate::config::ConfigFile;
use std::net::{IpAddr, SocketAddr};
use std::path::PathBuf;

/// Command line of `skein up`, and the options of every role.
#[derive(clap::Args, Debug)]
pub struct UpArgs {
    /// Simulate this many vehicles in-process.
    #[arg(long, value_name = "N")]
    pub(crate) sim: Option<usize>,
    /// Configuration file (TOML) with real vehicles and swarm settings.
    #[arg(long, value_name = "FILE", env = "SKEIN_CONFIG")]
    pub(crate) config: Option<PathBuf>,
    /// Listen address of the HTTP API and dashboard (port 0 picks a free port).
    #[arg(long, value_name = "ADDR:PORT")]
    pub(crate) http: Option<SocketAddr>,
    /// With --sim: links listen on PORT+i and simulated vehicle i binds PORT+40+i (the
    /// PX4 SITL layout for 14540); 0 = free ports for both.
    #[arg(long, value_name = "PORT", default_value_t = 14540)]
    pub(crate) sim_base_port: u16,
    /// With --sim: seed of the simulator's random processes.
    #[arg(long, default_value_t = 0)]
    pub(crate) sim_seed: u64,
    /// With --sim: each simulated GNSS receiver's position wanders as GNSS does (metres
    /// with a 3D fix, decimetres with RTK float, centimetres with RTK fixed from
    /// `GPS_RTCM_DATA` corrections), and the vehicles fly on that estimate (see
    /// docs/simulator.md, "GNSS and RTK"). Off: exact positions.
    #[arg(long)]
    pub(crate) sim_gnss_wander: bool,
    /// With --sim: the vehicle model of every simulated vehicle (default: a mix, the
    /// even-numbered vehicles uav-2, uav-4, … `observation`, the others `generic`).
    #[arg(long, value_name = "MODEL")]
    pub(crate) sim_model: Option<String>,
    /// Payload plugin directory: every `lib*.so` in it is loaded at start (overrides
    /// `[plugins] dir`; default: the directory holding the skein executable, where
    /// `cargo build --release` puts the plugins).
    #[arg(long, value_name = "DIR", env = "SKEIN_PLUGIN_DIR")]
    pub(crate) plugin_dir: Option<PathBuf>,
    /// With --sim: open the simulator's stats socket here (one JSON line per command:
    /// stats, reset, silence SYSID MS, reboot SYSID); port 0 picks one, printed at start.
    #[arg(long, value_name = "ADDR:PORT")]
    pub(crate) sim_stats: Option<SocketAddr>,
    /// Accept POST /api/v1/faults (make actors panic, hang, stop or fail on purpose).
    #[arg(long)]
    pub(crate) enable_fault_injection: bool,
    /// Listen on a non-loopback address without any `[[http.tokens]]`: anyone who can
    /// reach the port can fly the swarm. Refused without this flag.
    #[arg(long)]
    pub(crate) insecure_no_auth: bool,
    /// Record the whole run to this MCAP file (never overwritten; Foxglove and
    /// `skein replay` read it). `POST /api/v1/recording/start` records on demand.
    #[arg(long, value_name = "FILE.mcap")]
    pub(crate) record: Option<PathBuf>,
    /// Forward every vehicle's MAVLink to a ground station and its commands back
    /// (overrides `[gcs] forward`), e.g. `udpout:127.0.0.1:14550` for QGroundControl;
    /// setpoints from it are dropped.
    #[arg(long, value_name = "CONNECTION")]
    pub(crate) gcs_forward: Option<skein_link::ConnectionAddress>,
    /// Raster map tiles under the plan view: an MBTiles file or a `z/x/y` folder
    /// (overrides `[map] tiles`; served at `/api/v1/map/tiles/{z}/{x}/{y}`).
    #[arg(long, value_name = "PATH")]
    pub(crate) map_tiles: Option<PathBuf>,
    /// With --sim: MAVLink 2 signing key file (`skein key create`): the simulated vehicles
    /// require signed frames and skein's links sign.
    #[arg(long, value_name = "FILE")]
    pub(crate) sim_signing_key_file: Option<PathBuf>,
    /// Also publish the swarm on ROS 2 topics over DDS (`/skein/<vehicle>/pose`, `navsat`,
    /// `battery`, `state`, `/skein/tracks`; as `[dds] enabled`).
    #[arg(long)]
    pub(crate) dds: bool,
    /// With --dds: the DDS domain, 0 to 232 (default `[dds] domain_id`, else
    /// `ROS_DOMAIN_ID`, else 0).
    #[arg(long, value_name = "D", value_parser = skein_dds::parse_domain_id)]
    pub(crate) domain_id: Option<u16>,
    /// With --dds: obey `skein_msgs/Command`s on `/skein/<vehicle>/command` (as `[dds]
    /// accept_commands`). DDS has no authentication: use on a trusted network only.
    #[arg(long)]
    pub(crate) dds_commands: bool,
    /// With --dds: use only the interface with this local address (repeatable; as `[dds]
    /// networks`); `127.0.0.1` keeps DDS on this host.
    #[arg(long, value_name = "ADDR")]
    pub(crate) dds_network: Vec<IpAddr>,
    /// With --dds: the parent of the swarm frame `skein_swarm` on `/tf_static`, as an
    /// identity (`map`: your map frame is the swarm frame; as `[dds] tf_parent_frame`);
    /// default `earth`, the swarm origin's place in ECEF (REP 105).
    #[arg(long, value_name = "FRAME", value_parser = parse_tf_frame)]
    pub(crate) dds_tf_parent: Option<String>,
    #[command(flatten)]
    pub(crate) dds_security: crate::cmd::dds::DdsSecurityArgs,
    /// With --sim: intruders, non-cooperative aircraft the simulated cameras see.
    #[command(flatten)]
    pub(crate) intruders: skein_sim::intruders::IntruderArgs,
}

impl UpArgs {
    /// `skein up`'s options at their defaults (for the roles that set a few of them: `skein
    /// coordinator`, `skein agent`).
    ///
    /// # Errors
    /// Never for the options as declared (clap's message otherwise).
    pub(crate) fn defaults() -> Result<UpArgs, String> {
        use clap::{Args, FromArgMatches};
        let matches = UpArgs::augment_args(clap::Command::new("up"))
            .try_get_matches_from(["up"])
            .map_err(|e| e.to_string())?;
        UpArgs::from_arg_matches(&matches).map_err(|e| e.to_string())
    }

    /// `skein up`'s options at their defaults, then the ones every role has flags for: the
    /// config file, the API's address, the DDS domain, networks and security.
    ///
    /// # Errors
    /// As [`UpArgs::defaults`].
    pub(crate) fn for_role(
        config: Option<PathBuf>,
        http: Option<SocketAddr>,
        domain_id: Option<u16>,
        dds_network: Vec<IpAddr>,
        dds_security: crate::cmd::dds::DdsSecurityArgs,
    ) -> Result<UpArgs, String> {
        let mut args = UpArgs::defaults()?;
        args.config = config;
        args.http = http;
        args.domain_id = domain_id;
        args.dds_network = dds_network;
        args.dds_security = dds_security;
        Ok(args)
    }

    /// The configuration file `--config` names, or the defaults without one.
    ///
    /// # Errors
    /// The file cannot be read or parsed (named).
    pub(crate) fn config_file(&self) -> Result<ConfigFile, String> {
        match &self.config {
            Some(path) => ConfigFile::load(path),
            None => Ok(ConfigFile::default()),
        }
    }
}

/// A TF frame id for `--dds-tf-parent` (`skein_dds::tf::check_frame_id`'s rules).
pub(crate) fn parse_tf_frame(s: &str) -> Result<String, String> {
    skein_dds::tf::check_frame_id(s).map(|()| s.to_string())
}
