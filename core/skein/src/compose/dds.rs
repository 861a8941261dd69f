//! The DDS link of a role (`skein_dds::DdsRoles`): its settings from the flags over
//! `[dds]` over ROS 2's environment, the participant joined before the API starts (the
//! API shows the election, the peers' clocks and the link's security), then the link
//! served as a service the coordinator supervises. `skein up` runs it with `--dds` or
//! `[dds] enabled`; an agent (the agent carrier) and a coordinator candidate (the
//! election) always do.

use super::options::UpArgs;
use super::options::parse_tf_frame;
use super::role::Role;
use super::services::add_service;
use crate::config::ConfigFile;
use skein_swarm::Swarm;
use std::net::SocketAddr;
use std::sync::Arc;

/// The DDS link, joined and not yet served, with the line that says so.
pub(super) struct Dds {
    roles: Arc<skein_dds::DdsRoles>,
    summary: String,
}

/// Joins the DDS domain when the role or the options ask for it (`None` otherwise).
/// `api_scheme` and `api_local` are where the API listens (a candidate advertises it);
/// `rtk` is the process's corrections service, relayed on `/skein/rtcm`.
///
/// # Errors
/// A DDS option without DDS, a bad domain id, rate or frame, DDS that cannot start.
pub(super) fn prepare(
    role: &Role,
    args: &UpArgs,
    file: &ConfigFile,
    api_scheme: &str,
    api_local: SocketAddr,
    swarm: &Swarm,
    rtk: &Arc<skein_rtk::RtkService>,
) -> Result<Option<Dds>, String> {
    let Some(config) = dds_config(role, args, file, api_scheme, api_local)? else {
        return Ok(None);
    };
    let summary = format!(
        "skein: ROS 2 topics under /skein on DDS domain {}{}",
        config.domain_id,
        if config.accept_commands {
            ", commands accepted (unauthenticated: trusted network only)"
        } else {
            ""
        }
    );
    let roles = skein_dds::DdsRoles::new(
        config,
        swarm.coordinator.clone(),
        swarm.metrics.clone(),
        swarm.events.clone(),
        rtk.clone(),
    )
    .map_err(|e| format!("--dds: {e}"))?;
    Ok(Some(Dds { roles, summary }))
}

impl Dds {
    /// The API with what the link adds to it: the election (a candidate's), the peers'
    /// clocks, the link's security record (when secured).
    pub(super) fn extend_api(&self, state: skein_api::ApiState) -> skein_api::ApiState {
        let state = match self.roles.election() {
            Some(election) => state.with_election(election),
            None => state,
        };
        let state = state.with_clocks(self.roles.peer_clocks());
        match self.roles.link_security() {
            Some(record) => state.with_link_security(record),
            None => state,
        }
    }

    /// Has the coordinator run the link, then prints what it publishes.
    ///
    /// # Errors
    /// The coordinator did not start the service.
    pub(super) async fn serve(self, swarm: &Swarm) -> Result<(), String> {
        add_service(swarm, self.roles.service(), "the DDS link").await?;
        println!("{}", self.summary);
        Ok(())
    }
}

/// The DDS link's settings, `None` without `--dds` or `[dds] enabled` in a role that
/// does not need DDS.
///
/// # Errors
/// A DDS option without DDS, a bad `ROS_DOMAIN_ID`, `[dds] domain_id`,
/// `publish_rate_hz` or `tf_parent_frame`, an incomplete security setting.
fn dds_config(
    role: &Role,
    args: &UpArgs,
    file: &ConfigFile,
    api_scheme: &str,
    api_local: SocketAddr,
) -> Result<Option<skein_dds::DdsConfig>, String> {
    if !(args.dds || file.dds.enabled || role.needs_dds()) {
        refuse_dds_options(args)?;
        return Ok(None);
    }
    let publish_rate_hz = file.dds.publish_rate_hz.unwrap_or(10.0);
    let domain_id = domain_id(args, file)?;
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
    let candidate = role.candidate().map(|c| {
        super::election::lease_candidate(c, api_scheme, api_local, &networks, security.is_some())
    });
    Ok(Some(skein_dds::DdsConfig {
        domain_id,
        node_name: node_name(role),
        agent: role.agent().map(|a| a.config.clone()),
        candidate,
        publish_rate_hz,
        accept_commands: args.dds_commands || file.dds.accept_commands,
        networks,
        tf_parent_frame,
        security,
    }))
}

/// Refuses the DDS options given without DDS.
fn refuse_dds_options(args: &UpArgs) -> Result<(), String> {
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
    Ok(())
}

/// The DDS domain: `--domain-id`, else `[dds] domain_id`, else `ROS_DOMAIN_ID`, else 0.
fn domain_id(args: &UpArgs, file: &ConfigFile) -> Result<u16, String> {
    Ok(match (args.domain_id, file.dds.domain_id) {
        (Some(d), _) => d,
        (None, Some(d)) => skein_dds::parse_domain_id(&d.to_string())
            .map_err(|e| format!("[dds] domain_id: {e}"))?,
        (None, None) => skein_dds::domain_id_from_env()?.unwrap_or(0),
    })
}

/// The DDS node's name: the role and the process id.
fn node_name(role: &Role) -> String {
    let role = match role {
        Role::Up => "up",
        Role::Coordinator(_) => "coordinator",
        Role::Agent(_) => "agent",
    };
    format!("skein_{role}_{}", std::process::id())
}
