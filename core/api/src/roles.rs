//! Who may call a route: the token roles and a route's access. A leaf: the routers
//! ([`crate::openapi::routes`]) declare each route's access with these, the contract
//! ([`crate::openapi`]) carries it, and the middleware ([`crate::auth`]) enforces it.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// What a token may do. Ordered: each role can do what the ones below it can.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize, ToSchema,
)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// Reads (every GET) and the WebSocket stream.
    Viewer,
    /// Flies: vehicle and swarm commands, formation, leader motion, payloads.
    Operator,
    /// Everything, plugins, parameter writes and fault injection included.
    Admin,
}

impl Role {
    /// The role's name as in the configuration.
    pub fn as_str(self) -> &'static str {
        match self {
            Role::Viewer => "viewer",
            Role::Operator => "operator",
            Role::Admin => "admin",
        }
    }
}

impl std::str::FromStr for Role {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "viewer" => Ok(Role::Viewer),
            "operator" => Ok(Role::Operator),
            "admin" => Ok(Role::Admin),
            _ => Err(format!(
                "unknown role `{s}` (known: viewer, operator, admin)"
            )),
        }
    }
}

impl std::fmt::Display for Role {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Who may call a route.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    /// Anyone, without a token.
    Public,
    /// A token with at least this role.
    Role(Role),
}

impl Access {
    /// As the contract writes it (`x-skein-role`): `public`, or the role's name.
    pub fn as_str(self) -> &'static str {
        match self {
            Access::Public => "public",
            Access::Role(r) => r.as_str(),
        }
    }
}

impl std::str::FromStr for Access {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "public" => Ok(Access::Public),
            role => role.parse().map(Access::Role),
        }
    }
}

/// One operation of the contract and who may call it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RouteAccess {
    /// HTTP method, upper case (`GET`).
    pub method: String,
    /// The route as axum and the contract write it (`/api/v1/vehicles/{id}`).
    pub path: String,
    /// Who may call it.
    pub access: Access,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn access_reads_back_as_the_contract_writes_it() {
        for a in [
            Access::Public,
            Access::Role(Role::Viewer),
            Access::Role(Role::Operator),
            Access::Role(Role::Admin),
        ] {
            assert_eq!(a.as_str().parse::<Access>(), Ok(a));
        }
        assert!("root".parse::<Access>().is_err());
    }
}
