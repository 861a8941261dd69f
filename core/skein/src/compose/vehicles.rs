//! The vehicles a role flies: the config's `[[vehicles]]` endpoints, then with `--sim N`
//! one `udpin` endpoint per simulated vehicle (sysids from the role's first, ports in the
//! PX4 SITL layout from `--sim-base-port`), with the swarm settings they fly under.

use super::options::UpArgs;
use super::role::Role;
use crate::config::ConfigFile;
use skein_link::ConnectionAddress;
use skein_mavlink::signing::SigningKey;
use skein_swarm::{EndpointSpec, SwarmConfig, VehicleSpec};
use std::net::{IpAddr, Ipv4Addr, SocketAddr};

/// What the swarm starts with: its settings and every endpoint (the config's first).
pub(super) struct SwarmSpec {
    /// The swarm's settings (`--enable-fault-injection` applied).
    pub(super) config: SwarmConfig,
    /// The endpoints, real ones first, then one per simulated vehicle.
    pub(super) endpoints: Vec<EndpointSpec>,
}

/// One simulated vehicle: its sysid and the address it binds.
#[derive(Debug, Clone, Copy)]
pub(super) struct SimVehicle {
    /// MAVLink system id.
    pub(super) sysid: u8,
    /// The address its UDP socket binds (port 0: a free one).
    pub(super) bind: SocketAddr,
}

/// The simulated vehicles and what the simulator needs to know of the swarm.
#[derive(Debug, Clone)]
pub(super) struct Simulated {
    /// Index in the swarm's endpoints of the first simulated vehicle's link (one per
    /// vehicle, in order).
    pub(super) first_endpoint: usize,
    /// The vehicles, by sysid.
    pub(super) vehicles: Vec<SimVehicle>,
    /// `--sim-signing-key-file`'s key: the simulated vehicles require signed frames.
    pub(super) signing_key: Option<SigningKey>,
    /// The swarm's separation between setpoints, m (the spawn spacing follows it).
    pub(super) setpoint_separation_m: f64,
}

/// The vehicles of a role, planned.
pub(super) struct Fleet {
    /// What the swarm starts with.
    pub(super) spec: SwarmSpec,
    /// The simulated vehicles (none without `--sim`).
    pub(super) simulated: Simulated,
}

impl Fleet {
    /// Plans the vehicles of `role` from `args` and `file`.
    ///
    /// # Errors
    /// `--intruders` without `--sim`, nothing to fly where the role needs vehicles, a bad
    /// `[[vehicles]]` table or swarm setting, an unreadable signing key, more than 255
    /// sysids, ports past 65535, an unknown `--sim-model`.
    pub(super) fn plan(role: &Role, args: &UpArgs, file: &ConfigFile) -> Result<Fleet, String> {
        if args.sim.is_none() && args.intruders.intruders > 0 {
            return Err("--intruders needs --sim N (intruders fly in the simulator)".into());
        }
        if args.sim.is_none() && file.vehicles.is_empty() && role.needs_vehicles() {
            return Err("nothing to fly: give --sim N or a --config file with [[vehicles]]".into());
        }
        let mut endpoints: Vec<EndpointSpec> = file.endpoints()?;
        let signing_key = match &args.sim_signing_key_file {
            Some(f) => Some(SigningKey::load(f).map_err(|e| e.to_string())?),
            None => None,
        };
        let first_endpoint = endpoints.len();
        let n_sim = args.sim.unwrap_or(0);
        let first = usize::from(role.first_sysid());
        if n_sim + first > 256 {
            return Err(format!(
                "--sim {n_sim}: at most 255 simulated vehicles (MAVLink system ids)"
            ));
        }
        let mut config = file.swarm_config()?;
        config.fault_injection = args.enable_fault_injection;
        check_model(&config, args.sim_model.as_deref())?;
        let mut vehicles = Vec::with_capacity(n_sim);
        for i in 0..n_sim {
            let offset = first - 1 + i;
            let link = SocketAddr::new(LOCALHOST, port(args.sim_base_port, offset)?);
            endpoints.push(sim_endpoint(args, link, first + i, signing_key.as_ref()));
            vehicles.push(SimVehicle {
                sysid: (first + i) as u8,
                bind: SocketAddr::new(LOCALHOST, port(args.sim_base_port, 40 + offset)?),
            });
        }
        let setpoint_separation_m = config.setpoint_separation_m();
        Ok(Fleet {
            spec: SwarmSpec { config, endpoints },
            simulated: Simulated {
                first_endpoint,
                vehicles,
                signing_key,
                setpoint_separation_m,
            },
        })
    }
}

/// The simulated vehicles' links and sockets are on this host.
const LOCALHOST: IpAddr = IpAddr::V4(Ipv4Addr::LOCALHOST);

/// Port `base + offset`, or 0 (a free one) when `base` is 0.
///
/// # Errors
/// The port runs past 65535.
fn port(base: u16, offset: usize) -> Result<u16, String> {
    if base == 0 {
        return Ok(0);
    }
    u16::try_from(usize::from(base) + offset)
        .map_err(|_| format!("--sim-base-port {base}: ports run past 65535"))
}

/// Refuses a `--sim-model` the swarm does not know.
fn check_model(config: &SwarmConfig, model: Option<&str>) -> Result<(), String> {
    match model {
        Some(m) if !config.models.contains_key(m) => Err(format!(
            "--sim-model {m}: no such vehicle model (known: {})",
            config.models.keys().cloned().collect::<Vec<_>>().join(", ")
        )),
        _ => Ok(()),
    }
}

/// The link of simulated vehicle `sysid`, listening on `link`.
fn sim_endpoint(
    args: &UpArgs,
    link: SocketAddr,
    sysid: usize,
    signing_key: Option<&SigningKey>,
) -> EndpointSpec {
    EndpointSpec {
        connection: ConnectionAddress::UdpIn(link),
        vehicles: vec![VehicleSpec {
            id: None,
            sysid: Some(sysid as u8),
            model: Some(
                args.sim_model
                    .clone()
                    .unwrap_or_else(|| sim_mix_model(sysid).to_string()),
            ),
            signing: signing_key.map(|key| skein_link::SigningSpec {
                key: key.clone(),
                link_id: 0,
            }),
        }],
        simulated: true,
    }
}

/// The model of simulated vehicle `sysid` when `--sim-model` is not given: every other
/// vehicle (the even sysids: uav-2, uav-4, …) is an `observation` UAV (gimbal and camera),
/// the others `generic`, so the dashboard shows both.
pub(crate) fn sim_mix_model(sysid: usize) -> &'static str {
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
