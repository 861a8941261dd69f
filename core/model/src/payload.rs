//! A vehicle model's payload slot as configured and as the swarm protocol's attach
//! carries it ([`PayloadSpec`]): which slot, which kind, which plugin, hosted how
//! ([`Isolation`]). The drivers that fill the slots are `skein-payload`'s.

use serde::{Deserialize, Serialize};

/// How a payload is hosted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum Isolation {
    /// The plugin library is loaded into the skein process (fast; a segfault or abort in
    /// it takes skein down).
    #[default]
    InProcess,
    /// The plugin runs in a `skein plugin-host` child process (a crash kills only the
    /// child, which its supervisor restarts).
    Process,
}

/// One payload of a vehicle model: which slot, which kind, which plugin, how configured.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PayloadSpec {
    /// Slot name on the vehicle, unique per vehicle (`"gimbal"`, `"camera"`, `"radio"`).
    pub slot: String,
    /// Payload kind the plugin must provide (`"gimbal"`).
    pub kind: String,
    /// Plugin name; `None` = any loaded plugin that provides `kind`.
    #[serde(default)]
    pub plugin: Option<String>,
    /// Hosting.
    #[serde(default)]
    pub isolation: Isolation,
    /// Plugin configuration (JSON object, passed at creation).
    #[serde(default)]
    pub config: serde_json::Value,
}
