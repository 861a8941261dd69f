//! `skein up`: the single-process swarm (coordinator, local vehicles, the simulator,
//! plugins, the API and dashboard, and with `--dds` the ROS 2 topics).

mod plugins;

use crate::config::ConfigFile;
use crate::process::{EXIT_COORDINATOR_FAILED, shutdown_signal, spawn_process_watchdog};
use crate::sim_control;
use plugins::{default_plugin_dir, start_plugins, warn_missing_kinds};
use skein_link::ConnectionAddress;
use skein_swarm::{EndpointSpec, Swarm, VehicleSpec};
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Duration;

/// Where the API listens without `--http` or `[http] listen`.
pub(crate) const DEFAULT_HTTP: SocketAddr = SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), 8080);

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
    enable_fault_injection: bool,
    /// Listen on a non-loopback address without any `[[http.tokens]]`: anyone who can
    /// reach the port can fly the swarm. Refused without this flag.
    #[arg(long)]
    pub(crate) insecure_no_auth: bool,
    /// Record the whole run to this MCAP file (never overwritten; Foxglove and
    /// `skein replay` read it). `POST /api/v1/recording/start` records on demand.
    #[arg(long, value_name = "FILE.mcap")]
    record: Option<PathBuf>,
    /// Forward every vehicle's MAVLink to a ground station and its commands back
    /// (overrides `[gcs] forward`), e.g. `udpout:127.0.0.1:14550` for QGroundControl;
    /// setpoints from it are dropped.
    #[arg(long, value_name = "CONNECTION")]
    gcs_forward: Option<skein_link::ConnectionAddress>,
    /// Raster map tiles under the plan view: an MBTiles file or a `z/x/y` folder
    /// (overrides `[map] tiles`; served at `/api/v1/map/tiles/{z}/{x}/{y}`).
    #[arg(long, value_name = "PATH")]
    map_tiles: Option<PathBuf>,
    /// With --sim: MAVLink 2 signing key file (`skein key create`): the simulated vehicles
    /// require signed frames and skein's links sign.
    #[arg(long, value_name = "FILE")]
    sim_signing_key_file: Option<PathBuf>,
    /// Also publish the swarm on ROS 2 topics over DDS (`/skein/<vehicle>/pose`, `navsat`,
    /// `battery`, `state`, `/skein/tracks`; as `[dds] enabled`).
    #[arg(long)]
    dds: bool,
    /// With --dds: the DDS domain, 0 to 232 (default `[dds] domain_id`, else
    /// `ROS_DOMAIN_ID`, else 0).
    #[arg(long, value_name = "D", value_parser = skein_dds::parse_domain_id)]
    pub(crate) domain_id: Option<u16>,
    /// With --dds: obey `skein_msgs/Command`s on `/skein/<vehicle>/command` (as `[dds]
    /// accept_commands`). DDS has no authentication: use on a trusted network only.
    #[arg(long)]
    dds_commands: bool,
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
    pub(crate) dds_security: super::dds::DdsSecurityArgs,
    /// With --sim: intruders, non-cooperative aircraft the simulated cameras see.
    #[command(flatten)]
    intruders: skein_sim::intruders::IntruderArgs,
    /// Set by `skein coordinator`: this process is a candidate of the coordinator
    /// election (no vehicles of its own; DDS on).
    #[arg(skip)]
    pub(crate) candidate: Option<super::candidate::CandidateArgs>,
    /// Set by `skein agent`: this process's vehicles obey the active coordinator over DDS
    /// (DDS on; simulated sysids from its first one).
    #[arg(skip)]
    pub(crate) agent: Option<super::agent::AgentRole>,
}

impl UpArgs {
    /// `skein up`'s options at their defaults (for the roles built on it: `skein
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
}

pub async fn up(args: UpArgs) -> Result<ExitCode, String> {
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
    // The map first: a tile set that cannot be read stops skein before anything flies.
    let mut map_config = file.map.clone();
    if let Some(p) = &args.map_tiles {
        map_config.tiles = Some(p.clone());
    }
    let map = skein_api::map::MapTiles::from_config(&map_config)
        .map_err(|e| format!("--map-tiles / [map]: {e}"))?;
    if args.insecure_no_auth && !auth.enabled() && !http.ip().is_loopback() {
        eprintln!("skein: WARNING: --insecure-no-auth: the API on {http} has no authentication");
    }
    if args.sim.is_none() && args.intruders.intruders > 0 {
        return Err("--intruders needs --sim N (intruders fly in the simulator)".into());
    }
    if args.sim.is_none() && file.vehicles.is_empty() && args.candidate.is_none() {
        return Err("nothing to fly: give --sim N or a --config file with [[vehicles]]".into());
    }
    let mut endpoints: Vec<EndpointSpec> = file.endpoints()?;
    let sim_key = match &args.sim_signing_key_file {
        Some(f) => Some(skein_mavlink::signing::SigningKey::load(f).map_err(|e| e.to_string())?),
        None => None,
    };
    let real = endpoints.len();
    let n_sim = args.sim.unwrap_or(0);
    // Simulated vehicle i has sysid `first + i`, its ports offset by `first - 1 + i`.
    let first = usize::from(args.agent.as_ref().map_or(1, |a| a.first_sysid));
    if n_sim + first > 256 {
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
            connection: ConnectionAddress::UdpIn(SocketAddr::new(localhost, port(first - 1 + i)?)),
            vehicles: vec![VehicleSpec {
                id: None,
                sysid: Some((first + i) as u8),
                model: Some(
                    args.sim_model
                        .clone()
                        .unwrap_or_else(|| sim_mix_model(first + i).to_string()),
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
                    sysid: (first + i) as u8,
                    bind: SocketAddr::new(localhost, port(40 + first - 1 + i)?),
                    target,
                })
            })
            .collect::<Result<Vec<_>, String>>()?;
        let mut cfg = skein_sim::SimConfig::with_vehicles(vehicles);
        cfg.seed = args.sim_seed;
        if args.agent.is_some() {
            // Agents on one machine lay their vehicles out by sysid on one grid.
            cfg.grid_columns = Some(AGENT_GRID_COLUMNS);
        }
        if let Some(key) = sim_key {
            cfg.signing_key = Some(key);
            cfg.params.push(("MAV_SIGN_CFG".into(), 2.0));
        }
        // Vehicles start as far apart as formation slots must be, so that the first
        // formation's transition keeps the separation too (see skein_swarm::formation).
        cfg.spacing_m = cfg
            .spacing_m
            .max(1.05 * std::f64::consts::SQRT_2 * swarm_setpoint_separation);
        let sim = skein_sim::Simulator::start_on_own_threads(cfg)
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
    let scheme = if tls.is_some() { "https" } else { "http" };
    let dds = match dds_config(&args, &file, scheme, local)? {
        Some(dds) => {
            let summary = format!(
                "skein: ROS 2 topics under /skein on DDS domain {}{}",
                dds.domain_id,
                if dds.accept_commands {
                    ", commands accepted (unauthenticated: trusted network only)"
                } else {
                    ""
                }
            );
            let shared = skein_dds::DdsRoles::new(
                dds,
                swarm.coordinator.clone(),
                swarm.metrics.clone(),
                swarm.events.clone(),
            )
            .map_err(|e| format!("--dds: {e}"))?;
            Some((shared, summary))
        }
        None => None,
    };
    let state = skein_api::ApiState::new(swarm.coordinator.clone(), swarm.events.clone())
        .with_plugins(plugins, refused)
        .with_map(map)
        .with_auth(auth)
        .with_recorder(recorder.clone());
    let state = match dds.as_ref().and_then(|(d, _)| d.election()) {
        Some(election) => state.with_election(election),
        None => state,
    };
    let state = match dds.as_ref() {
        Some((d, _)) => state.with_clocks(d.peer_clocks()),
        None => state,
    };
    let state = match dds.as_ref().and_then(|(d, _)| d.link_security()) {
        Some(record) => state.with_link_security(record),
        None => state,
    };
    let state = match tls {
        Some(t) => state.with_tls(t),
        None => state,
    };
    add_service(
        &swarm,
        skein_api::ApiServer::service(listener, state),
        "the API",
    )
    .await?;
    println!("skein: dashboard at {scheme}://{local}/");
    if let Some((shared, summary)) = dds {
        add_service(&swarm, shared.service(), "the DDS link").await?;
        println!("{summary}");
        if let Some(c) = &args.candidate {
            println!(
                "skein: coordinator candidate `{}`, priority {} (GET /api/v1/coordinator)",
                c.id, c.priority
            );
        }
        if let Some(a) = &args.agent {
            let c = &a.config;
            println!(
                "skein: agent `{}`: obeys the active coordinator; rides through {:.1} s of \
                 silence on its slots; without a coordinator for {:.1} s it holds, then \
                 after {:.1} s more: {:?}",
                c.agent_id,
                c.ride_through.as_secs_f64(),
                c.coordinator_timeout.max(c.ride_through).as_secs_f64(),
                c.lost_action_after.as_secs_f64(),
                c.lost_action
            );
        }
    }
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
    // systemd (`Type=notify`) starts the units that wait for this one now.
    crate::service::ready(&format!("dashboard at {scheme}://{local}/"));
    let signalled = tokio::select! {
        _ = shutdown_signal() => true,
        _ = swarm.stopped() => false,
    };
    let code = if signalled {
        eprintln!("skein: shutting down");
        crate::service::stopping("shutting down");
        match args.agent.as_ref().map(|a| a.shutdown) {
            // An agent leaves its airborne vehicles in a mode PX4 flies alone, first.
            Some(plan) => tokio::select! {
                r = crate::shutdown::secure_vehicles(&swarm.coordinator, plan) => match r {
                    Ok(()) => ExitCode::SUCCESS,
                    Err(e) => {
                        eprintln!("skein: shutdown: {e}");
                        ExitCode::FAILURE
                    }
                },
                _ = shutdown_signal() => {
                    eprintln!("skein: shutdown: a second signal: exiting at once");
                    ExitCode::FAILURE
                }
            },
            None => ExitCode::SUCCESS,
        }
    } else {
        tracing::error!(
            "the coordinator failed: exiting for the outer supervisor to restart skein"
        );
        ExitCode::from(EXIT_COORDINATOR_FAILED)
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

/// Has the coordinator start and supervise `service` (`what` names it in the error).
async fn add_service(
    swarm: &Swarm,
    service: skein_swarm::ServiceSpec,
    what: &str,
) -> Result<(), String> {
    match swarm
        .coordinator
        .call(
            |r| skein_swarm::CoordinatorMsg::AddService(service, r),
            Some(Duration::from_secs(10)),
        )
        .await
    {
        Ok(ractor::rpc::CallResult::Success(Ok(()))) => Ok(()),
        Ok(ractor::rpc::CallResult::Success(Err(e))) => Err(e),
        _ => Err(format!("the coordinator did not start {what}")),
    }
}

/// The DDS link's settings, `None` without `--dds` or `[dds] enabled`.
///
/// # Errors
/// A bad `ROS_DOMAIN_ID`, `[dds] domain_id` or `publish_rate_hz`.
fn dds_config(
    args: &UpArgs,
    file: &ConfigFile,
    api_scheme: &str,
    api_local: SocketAddr,
) -> Result<Option<skein_dds::DdsConfig>, String> {
    if !(args.dds || file.dds.enabled || args.candidate.is_some() || args.agent.is_some()) {
        if args.domain_id.is_some()
            || args.dds_commands
            || !args.dds_network.is_empty()
            || args.dds_tf_parent.is_some()
            || args.dds_security.given()
        {
            return Err(
                "--domain-id, --dds-commands, --dds-network, --dds-tf-parent, --dds-keystore \
                 and --dds-enclave go with --dds"
                    .into(),
            );
        }
        return Ok(None);
    }
    let domain_id = match (args.domain_id, file.dds.domain_id) {
        (Some(d), _) => d,
        (None, Some(d)) => skein_dds::parse_domain_id(&d.to_string())
            .map_err(|e| format!("[dds] domain_id: {e}"))?,
        (None, None) => skein_dds::domain_id_from_env()?.unwrap_or(0),
    };
    let publish_rate_hz = file.dds.publish_rate_hz.unwrap_or(10.0);
    if !(publish_rate_hz > 0.0 && publish_rate_hz <= 100.0) {
        return Err(format!(
            "[dds] publish_rate_hz: {publish_rate_hz} is not in (0, 100]"
        ));
    }
    let tf_parent_frame = match (&args.dds_tf_parent, &file.dds.tf_parent_frame) {
        (Some(f), _) => Some(f.clone()),
        (None, Some(f)) => {
            Some(parse_tf_frame(f).map_err(|e| format!("[dds] tf_parent_frame: {e}"))?)
        }
        (None, None) => None,
    };
    let networks = if args.dds_network.is_empty() {
        file.dds.networks.clone()
    } else {
        args.dds_network.clone()
    };
    let security = args.dds_security.resolve(&file.dds)?;
    let timing = skein_swarm::election::ElectionConfig {
        first_listen: match security {
            Some(_) => skein_dds::security::FIRST_LISTEN,
            None => skein_swarm::election::ElectionConfig::default().first_listen,
        },
        ..Default::default()
    };
    Ok(Some(skein_dds::DdsConfig {
        domain_id,
        node_name: match (&args.candidate, &args.agent) {
            (Some(_), _) => format!("skein_coordinator_{}", std::process::id()),
            (None, Some(_)) => format!("skein_agent_{}", std::process::id()),
            (None, None) => format!("skein_up_{}", std::process::id()),
        },
        agent: args.agent.as_ref().map(|a| a.config.clone()),
        candidate: args
            .candidate
            .as_ref()
            .map(|c| skein_dds::lease::Candidate {
                coordinator_id: c.id.clone(),
                priority: c.priority,
                api_url: super::candidate::advertised_url(api_scheme, api_local, &networks),
                timing,
            }),
        publish_rate_hz,
        accept_commands: args.dds_commands || file.dds.accept_commands,
        networks,
        tf_parent_frame,
        security,
    }))
}

/// A TF frame id for `--dds-tf-parent` (`skein_dds::tf::check_frame_id`'s rules).
fn parse_tf_frame(s: &str) -> Result<String, String> {
    skein_dds::tf::check_frame_id(s).map(|()| s.to_string())
}

/// Columns of the spawn grid of agents' simulated vehicles (index `sysid - 1`), so that
/// agents on one machine never spawn two vehicles on one point.
const AGENT_GRID_COLUMNS: usize = 4;

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
