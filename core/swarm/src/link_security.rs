//! What the swarm's link proves about who speaks on it, for the operator
//! (`dds_security` in `GET /api/v1/coordinator`): under DDS Security the enclave this
//! coordinator presents, and for each remote vehicle the agent whose enclave first
//! reported it, as its certificate proves it (`skein_dds::remote` binds the vehicle to
//! that enclave and refuses every other). Written by the DDS link, read by the API.

use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::{Mutex, PoisonError};

/// The swarm link's security, as `GET /api/v1/coordinator` shows it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, utoipa::ToSchema)]
pub struct LinkSecurityStatus {
    /// The enclave this process presents (`/skein/coordinator/gcs_a`).
    pub enclave: String,
    /// Each remote vehicle's agent, by vehicle id.
    pub vehicles: BTreeMap<String, ProvenAgent>,
}

/// The agent a remote vehicle is bound to.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, utoipa::ToSchema)]
pub struct ProvenAgent {
    /// The agent's id on the swarm topics (what it says of itself).
    pub agent: String,
    /// The identity its certificate proves: 12 hex digits, the start of its DDS GUID
    /// (DDS Security 1.1 §9.3.1.1).
    pub identity: String,
    /// The enclave with that identity (`/skein/agent/a1`), when this process's keystore
    /// holds it; `null` otherwise.
    pub enclave: Option<String>,
}

/// The shared record (see the module docs).
#[derive(Debug)]
pub struct LinkSecurity {
    status: Mutex<LinkSecurityStatus>,
}

impl LinkSecurity {
    /// A record for a process presenting `enclave`, no vehicle bound yet.
    pub fn new(enclave: impl Into<String>) -> Self {
        LinkSecurity {
            status: Mutex::new(LinkSecurityStatus {
                enclave: enclave.into(),
                vehicles: BTreeMap::new(),
            }),
        }
    }

    /// Vehicle `vehicle` is bound to `agent`.
    pub fn bound(&self, vehicle: &str, agent: ProvenAgent) {
        self.status
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .vehicles
            .insert(vehicle.to_string(), agent);
    }

    /// What the API shows now.
    pub fn snapshot(&self) -> LinkSecurityStatus {
        self.status
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }
}
