//! The three roles a skein process can play ([`Role`]) and what sets them apart in the
//! composition (see [`super`]): whether vehicles are needed, whether DDS always runs,
//! the first simulated sysid, the candidate's or the agent's own settings.

use crate::shutdown::ShutdownPlan;
use skein_dds::agent::AgentConfig;

/// Which role this process plays: what sets the parts apart (see the module docs).
#[derive(Debug, Clone)]
pub(crate) enum Role {
    /// `skein up`: everything in one process; DDS only when asked for.
    Up,
    /// `skein coordinator`: a candidate of the coordinator election, no vehicles needed.
    Coordinator(Candidate),
    /// `skein agent`: this computer's vehicles, steered over DDS by the active coordinator.
    Agent(AgentRole),
}

/// A coordinator candidate's identity in the election.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Candidate {
    /// Id on the lease topic.
    pub id: String,
    /// Priority: the live candidate with the highest is active.
    pub priority: u32,
}

/// What an agent needs beyond `skein up`'s options.
#[derive(Debug, Clone)]
pub(crate) struct AgentRole {
    /// The first simulated vehicle's sysid.
    pub first_sysid: u8,
    /// The carrier's settings.
    pub config: AgentConfig,
    /// What the vehicles do before the process exits.
    pub shutdown: ShutdownPlan,
}

impl Role {
    /// Whether the process refuses to start without a vehicle (`--sim N` or
    /// `[[vehicles]]`): a coordinator candidate flies the agents' vehicles.
    pub(super) fn needs_vehicles(&self) -> bool {
        !matches!(self, Role::Coordinator(_))
    }

    /// Whether the DDS link runs whatever `--dds` and `[dds] enabled` say.
    pub(super) fn needs_dds(&self) -> bool {
        !matches!(self, Role::Up)
    }

    /// The sysid of the first simulated vehicle.
    pub(super) fn first_sysid(&self) -> u8 {
        match self {
            Role::Agent(a) => a.first_sysid,
            Role::Up | Role::Coordinator(_) => 1,
        }
    }

    /// The election candidate this process is, if any.
    pub(super) fn candidate(&self) -> Option<&Candidate> {
        match self {
            Role::Coordinator(c) => Some(c),
            Role::Up | Role::Agent(_) => None,
        }
    }

    /// The agent this process is, if any.
    pub(super) fn agent(&self) -> Option<&AgentRole> {
        match self {
            Role::Agent(a) => Some(a),
            Role::Up | Role::Coordinator(_) => None,
        }
    }

    /// The line that says what the role does on DDS, printed once DDS runs.
    pub(super) fn describe(&self) -> Option<String> {
        match self {
            Role::Up => None,
            Role::Coordinator(c) => Some(format!(
                "skein: coordinator candidate `{}`, priority {} (GET /api/v1/coordinator)",
                c.id, c.priority
            )),
            Role::Agent(a) => {
                let c = &a.config;
                Some(format!(
                    "skein: agent `{}`: obeys the active coordinator; rides through {:.1} s of \
                     silence on its slots; without a coordinator for {:.1} s it holds, then \
                     after {:.1} s more: {:?}",
                    c.agent_id,
                    c.ride_through.as_secs_f64(),
                    c.coordinator_timeout.max(c.ride_through).as_secs_f64(),
                    c.lost_action_after.as_secs_f64(),
                    c.lost_action
                ))
            }
        }
    }
}
