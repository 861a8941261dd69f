//! Supervision vocabulary shared by every supervised actor: restart policies, child
//! kinds and statuses, and the faults an operator can inject to test recovery.

use serde::{Deserialize, Serialize};

/// A fault to inject into an actor (`POST /api/v1/faults`, only with
/// `--enable-fault-injection`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum FaultKind {
    /// The actor panics while handling a message.
    Panic,
    /// The actor stops answering: its handler awaits forever (an asynchronous stall,
    /// which the watchdog can cancel; a CPU-bound spin cannot be pre-empted in-process,
    /// that is what process isolation is for).
    Hang,
    /// The actor stops cleanly.
    Stop,
    /// The actor's handler returns an error.
    Error,
    /// A vehicle's setpoints skip the geofence from now on (a Vehicle actor's fault only,
    /// `coordinator/<id>`): what rehearses the autopilot's own fence stopping a vehicle
    /// that skein's setpoint guard would have held.
    BypassGeofence,
}

impl FaultKind {
    /// Every kind with its API name.
    pub const ALL: [FaultKind; 5] = [
        FaultKind::Panic,
        FaultKind::Hang,
        FaultKind::Stop,
        FaultKind::Error,
        FaultKind::BypassGeofence,
    ];

    /// The API name (`"panic"`).
    pub fn name(self) -> &'static str {
        match self {
            FaultKind::Panic => "panic",
            FaultKind::Hang => "hang",
            FaultKind::Stop => "stop",
            FaultKind::Error => "error",
            FaultKind::BypassGeofence => "bypass_geofence",
        }
    }

    /// Parses an API name.
    pub fn from_name(name: &str) -> Option<FaultKind> {
        FaultKind::ALL.into_iter().find(|k| k.name() == name)
    }
}

/// When a supervisor restarts a child that ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum RestartPolicy {
    /// Never: the first failure escalates.
    Never,
    /// After a failure (panic, error, hang), not after a clean stop.
    #[default]
    OnFailure,
    /// After any end, clean stops included.
    Always,
}

/// What kind of actor a supervised child is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum ChildKind {
    /// The root supervisor.
    Coordinator,
    /// The HTTP API server.
    Api,
    /// The DDS link (ROS 2 topics, `skein up --dds`).
    Dds,
    /// A Vehicle actor.
    Vehicle,
    /// A vehicle's MAVLink link actor.
    Px4Link,
    /// A payload actor (plugin instance).
    Payload,
}

impl ChildKind {
    /// Every kind.
    pub const ALL: [ChildKind; 6] = [
        ChildKind::Coordinator,
        ChildKind::Api,
        ChildKind::Dds,
        ChildKind::Vehicle,
        ChildKind::Px4Link,
        ChildKind::Payload,
    ];

    /// The name used in paths, metrics labels and config sections (`"px4link"`).
    pub fn name(self) -> &'static str {
        match self {
            ChildKind::Coordinator => "coordinator",
            ChildKind::Api => "api",
            ChildKind::Dds => "dds",
            ChildKind::Vehicle => "vehicle",
            ChildKind::Px4Link => "px4link",
            ChildKind::Payload => "payload",
        }
    }
}

/// A supervised child's status.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum ChildStatus {
    /// Running and answering.
    Running,
    /// Ended; a restart is scheduled after its backoff.
    Restarting,
    /// Ended and not restarted: its restart budget is spent (or the policy is `never`).
    Failed,
    /// Ended cleanly and not restarted (policy `on-failure` or `never`).
    Stopped,
    /// A payload slot not started because no loaded plugin provides its kind; it starts
    /// when one is loaded (no restart budget is spent meanwhile).
    WaitingForPlugin,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for k in FaultKind::ALL {
            assert_eq!(FaultKind::from_name(k.name()), Some(k));
        }
        assert_eq!(FaultKind::from_name("explode"), None);
        assert_eq!(
            serde_json::to_string(&RestartPolicy::OnFailure).unwrap(),
            "\"on-failure\""
        );
        assert_eq!(ChildKind::Px4Link.name(), "px4link");
    }
}
