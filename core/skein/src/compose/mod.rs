//! The roles of a skein process as one declared composition. `skein up`, `skein agent`
//! and `skein coordinator` are one sequence of parts ([`run`]); the [`Role`] says what
//! sets them apart, and each part is a module of its own:
//!
//! | part | module | `up` | `agent` | `coordinator` |
//! |---|---|---|---|---|
//! | the role: what sets the three apart | [`role`] | [`Role::Up`] | [`Role::Agent`] | [`Role::Coordinator`] |
//! | options, config file | [`options`] | every flag | its flags | its flags |
//! | API settings: listen address, auth, TLS, map | [`api`] | ✓ | loopback by default | ✓ |
//! | vehicles: `[[vehicles]]` and simulated ones | [`vehicles`] | at least one | at least one, sysids from `--first-sysid` | the config's, maybe none |
//! | payload plugins | [`plugins`] | ✓ | ✓ | ✓ |
//! | the swarm: coordinator actor, vehicle actors | [`start_swarm`] | ✓ | ✓ | ✓ |
//! | ground-station forward | [`gcs`] | `--gcs-forward`, `[gcs]` | `[gcs]` | `[gcs]` |
//! | simulator, intruders, stats socket | [`simulator`] | `--sim N` | `--sim N`, on the agents' grid | – |
//! | recording | [`recording`] | `--record`, on demand | on demand | on demand |
//! | RTK corrections to this process's vehicles | [`rtk`] | `[rtk]`, `PUT /api/v1/rtk`; relayed to agents with `--dds` | `[rtk]`, its API, else the active coordinator's, relayed | `[rtk]`, its API: relayed to the agents while active |
//! | Remote ID's live operator location: the ground station's GNSS | [`remote_id`] | `[remote_id] operator_gnss` | refused: its receiver is the aircraft's | `[remote_id] operator_gnss`, for its own vehicles |
//! | DDS link and its roles | [`dds`] | `--dds`, `[dds] enabled` | always, the agent carrier | always, the election candidate |
//! | process watchdog, systemd readiness | `crate::process`, `crate::service` | ✓ | ✓ | ✓ |
//! | shutdown | [`lifecycle`] | exit | vehicles secured first (`crate::shutdown`) | exit |
//!
//! The role commands (`crate::cmd::{up, agent, coordinator}`) only turn their flags into
//! a [`Role`] and [`UpArgs`]; none of them imports another. The parts import their
//! siblings (`options`, `role`) and never this module, so the dependencies point one
//! way: commands → this sequence → parts.

mod api;
mod dds;
mod election;
mod gcs;
mod lifecycle;
mod options;
mod plugins;
mod recording;
mod remote_id;
mod role;
mod rtk;
mod services;
mod simulator;
mod vehicles;

pub(crate) use election::hostname;
pub(crate) use options::UpArgs;
pub(crate) use role::{AgentRole, Candidate, Role};
pub(crate) use simulator::spawn_spacing_m;
pub(crate) use vehicles::sim_mix_model;

use crate::config::ConfigFile;
use skein_swarm::Swarm;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Duration;

/// Runs the process of `role` with `args` until a signal or the coordinator's failure:
/// the parts in order (see the module docs), then the shutdown.
///
/// # Errors
/// A bad config or option (named), a port in use, a part that cannot start.
pub(crate) async fn run(role: Role, args: UpArgs) -> Result<ExitCode, String> {
    let file = args.config_file()?;
    let api = api::ApiSettings::resolve(&args, &file)?;
    let fleet = vehicles::Fleet::plan(&role, &args, &file)?;
    let watchdog_deadline = watchdog_deadline(&file)?;
    let plugins = plugins::Plugins::start(&args, &file, &fleet)?;
    let vehicles::Fleet {
        mut spec,
        simulated,
    } = fleet;
    remote_id::start_operator_gnss(&role, &file, &mut spec.config)?;
    let sim_slot = simulator::SimSlot::default();
    let mut swarm = start_swarm(&file, spec, &plugins, sim_slot.control(&simulated)).await?;
    // Kept for the life of the process: dropping it stops the forwarding.
    let _gcs = gcs::forward(&args, &file, &swarm).await?;
    plugins.follow(&swarm);
    let sim = simulator::start(&role, &args, &simulated, &swarm, &sim_slot).await?;
    let listener = api.bind()?;
    let dashboard = format!("{}://{}/", api.scheme(), listener.local);
    let recorder = recording::start(&args, &file, &swarm)?;
    let rtk = rtk::start(&file, &swarm)?;
    let dds = dds::prepare(
        &role,
        &args,
        &file,
        api.scheme(),
        listener.local,
        &swarm,
        &rtk,
    )?;
    api.serve(listener, plugins, &recorder, rtk, dds.as_ref(), &swarm)
        .await?;
    if let Some(dds) = dds {
        dds.serve(&swarm).await?;
        if let Some(line) = role.describe() {
            println!("{line}");
        }
    }
    crate::process::spawn_process_watchdog(swarm.coordinator.clone(), watchdog_deadline);
    // systemd (`Type=notify`) starts the units that wait for this one now.
    crate::service::ready(&format!("dashboard at {dashboard}"));
    let code = lifecycle::wait(&role, &mut swarm).await;
    recording::finish(&recorder).await;
    lifecycle::stop(swarm, sim).await;
    Ok(code)
}

/// How long the coordinator may leave the process watchdog's ping unanswered: twice its
/// own watchdog's deadline, at least 2 s.
fn watchdog_deadline(file: &ConfigFile) -> Result<Duration, String> {
    let deadline_ms = file.swarm_config()?.supervision.watchdog_deadline_ms;
    Ok(Duration::from_millis(deadline_ms.max(1000) * 2))
}

/// Starts the coordinator and the vehicle actors of `spec`, with the plugins' payloads
/// and the simulator's controls (`None` without a simulator).
///
/// # Errors
/// The swarm's own (an endpoint that cannot open, a bad setting).
async fn start_swarm(
    file: &ConfigFile,
    spec: vehicles::SwarmSpec,
    plugins: &plugins::Plugins,
    simulator: Option<Arc<dyn skein_swarm::SimulatorControl>>,
) -> Result<Swarm, String> {
    let services = skein_swarm::SwarmServices {
        payloads: Arc::clone(&plugins.factory),
        simulator,
    };
    Swarm::start(spec.config, services, file.identity(), spec.endpoints)
        .await
        .map_err(|e| e.to_string())
}
