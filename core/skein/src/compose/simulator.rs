//! The in-process simulator of `skein up --sim N` and `skein agent --sim N`: started once
//! the swarm's endpoints are bound (each simulated vehicle sends to its link's address),
//! with its intruders (`--intruders`) and its stats socket (`--sim-stats`). The swarm is
//! given the simulator's controls before it exists ([`SimSlot`]): payloads reach it once
//! it runs.

use super::options::UpArgs;
use super::role::Role;
use super::vehicles::Simulated;
use crate::sim_control::LateSimControl;
use skein_swarm::Swarm;
use std::sync::{Arc, OnceLock};

/// Columns of the spawn grid of agents' simulated vehicles (index `sysid - 1`), so that
/// agents on one machine never spawn two vehicles on one point.
const AGENT_GRID_COLUMNS: usize = 4;

/// Where the simulator is put once it runs (the swarm starts first).
#[derive(Default, Clone)]
pub(super) struct SimSlot(Arc<OnceLock<skein_sim::Simulator>>);

impl SimSlot {
    /// The swarm's controls of the simulator, `None` without simulated vehicles.
    pub(super) fn control(
        &self,
        simulated: &Simulated,
    ) -> Option<Arc<dyn skein_swarm::SimulatorControl>> {
        if simulated.vehicles.is_empty() {
            return None;
        }
        Some(Arc::new(LateSimControl(self.0.clone())))
    }
}

/// Starts the simulated vehicles of `simulated` (none: `None`), sending to their links in
/// `swarm`, with the intruders and the stats socket `args` ask for; puts the simulator in
/// `slot` and prints where its links listen.
///
/// # Errors
/// The simulator, the intruders or the stats socket cannot start (named).
pub(super) async fn start(
    role: &Role,
    args: &UpArgs,
    simulated: &Simulated,
    swarm: &Swarm,
    slot: &SimSlot,
) -> Result<Option<skein_sim::Simulator>, String> {
    if simulated.vehicles.is_empty() {
        return Ok(None);
    }
    let cfg = sim_config(role, args, simulated, swarm);
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
    let _ = slot.0.set(sim.clone());
    if let Some(addr) = args.sim_stats {
        serve_stats(&sim, addr).await?;
    }
    let ports: Vec<String> = swarm.endpoints[simulated.first_endpoint..]
        .iter()
        .filter_map(|e| e.local_addr().map(|a| a.port().to_string()))
        .collect();
    println!(
        "skein: {} simulated vehicles, MAVLink links on udp 127.0.0.1 ports {}",
        simulated.vehicles.len(),
        ports.join(",")
    );
    Ok(Some(sim))
}

/// The simulator's configuration: each vehicle sends to its link's bound address.
fn sim_config(
    role: &Role,
    args: &UpArgs,
    simulated: &Simulated,
    swarm: &Swarm,
) -> skein_sim::SimConfig {
    let vehicles = simulated
        .vehicles
        .iter()
        .enumerate()
        .map(|(i, v)| skein_sim::SimVehicleConfig {
            sysid: v.sysid,
            bind: v.bind,
            target: swarm.endpoints[simulated.first_endpoint + i]
                .local_addr()
                .expect("udp endpoint has an address"),
        })
        .collect();
    let mut cfg = skein_sim::SimConfig::with_vehicles(vehicles);
    cfg.seed = args.sim_seed;
    cfg.gnss_wander = args.sim_gnss_wander;
    if matches!(role, Role::Agent(_)) {
        // Agents on one machine lay their vehicles out by sysid on one grid.
        cfg.grid_columns = Some(AGENT_GRID_COLUMNS);
    }
    if let Some(key) = simulated.signing_key.clone() {
        cfg.signing_key = Some(key);
        cfg.params.push(("MAV_SIGN_CFG".into(), 2.0));
    }
    cfg.spacing_m = spawn_spacing_m(simulated.setpoint_separation_m);
    cfg
}

/// The spacing of the simulated vehicles' spawn grid, metres, for a swarm whose setpoints
/// keep `setpoint_separation_m`: the simulator's own (3 m), or as far apart as formation
/// slots must be, so that the first formation's transition keeps the separation too (see
/// skein_swarm::formation).
pub(crate) fn spawn_spacing_m(setpoint_separation_m: f64) -> f64 {
    skein_sim::SimConfig::default()
        .spacing_m
        .max(1.05 * std::f64::consts::SQRT_2 * setpoint_separation_m)
}

/// Opens the simulator's stats socket on `addr` and prints where it listens.
///
/// # Errors
/// The address cannot be bound.
async fn serve_stats(sim: &skein_sim::Simulator, addr: std::net::SocketAddr) -> Result<(), String> {
    let listener = tokio::net::TcpListener::bind(addr)
        .await
        .map_err(|e| format!("--sim-stats {addr}: {e}"))?;
    let local = listener.local_addr().map_err(|e| e.to_string())?;
    println!("skein: simulator stats at {local}");
    tokio::spawn(skein_sim::cli::serve_stats(sim.clone(), listener));
    Ok(())
}
