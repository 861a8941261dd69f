//! The end of a role's process: it runs until SIGTERM or Ctrl-C (exit 0; an agent first
//! secures its airborne vehicles, see [`crate::shutdown`], and a second signal ends that
//! wait) or until the coordinator fails (exit [`EXIT_COORDINATOR_FAILED`] for the outer
//! supervisor to restart skein); then the swarm and the simulator stop.

use super::role::Role;
use crate::process::{EXIT_COORDINATOR_FAILED, shutdown_signal};
use crate::shutdown::ShutdownPlan;
use skein_swarm::{CoordinatorMsg, Swarm};
use std::process::ExitCode;

/// Waits for a signal or the coordinator's end and returns the exit status.
pub(super) async fn wait(role: &Role, swarm: &mut Swarm) -> ExitCode {
    let signalled = tokio::select! {
        _ = shutdown_signal() => true,
        _ = swarm.stopped() => false,
    };
    if !signalled {
        tracing::error!(
            "the coordinator failed: exiting for the outer supervisor to restart skein"
        );
        return ExitCode::from(EXIT_COORDINATOR_FAILED);
    }
    eprintln!("skein: shutting down");
    crate::service::stopping("shutting down");
    match role.agent().map(|a| a.shutdown) {
        // An agent leaves its airborne vehicles in a mode PX4 flies alone, first.
        Some(plan) => secure(&swarm.coordinator, plan).await,
        None => ExitCode::SUCCESS,
    }
}

/// Secures the vehicles under `plan`, unless a second signal comes first.
async fn secure(coordinator: &ractor::ActorRef<CoordinatorMsg>, plan: ShutdownPlan) -> ExitCode {
    tokio::select! {
        r = crate::shutdown::secure_vehicles(coordinator, plan) => match r {
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
    }
}

/// Stops the swarm (if it still runs) and the simulator.
pub(super) async fn stop(swarm: Swarm, sim: Option<skein_sim::Simulator>) {
    if swarm.is_running() {
        swarm.stop().await;
    }
    if let Some(sim) = sim {
        sim.shutdown().await;
    }
}
