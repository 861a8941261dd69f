//! Each vehicle's newest flight log brought home by itself after its flight (`[logs]
//! fetch_after_landing`): when a vehicle goes from a flying state to `Landed` (PX4 closes
//! the flight's log at disarm), its logs are listed and the newest downloaded as `POST
//! /api/v1/logs/fetch_latest` would ([`crate::flight_logs`]); the downloads show in
//! `GET /api/v1/logs`. A vehicle that does not answer, or is busy with another transfer,
//! is asked again a few times.

use crate::ApiState;
use skein_model::fsm::VehicleState;
use skein_swarm::SwarmEvent;
use std::time::Duration;
use tokio::sync::broadcast::error::RecvError;

/// Listings tried per landing before giving up.
const ATTEMPTS: u32 = 4;
/// Wait between them.
const RETRY: Duration = Duration::from_secs(3);

/// Starts fetching each vehicle's newest log after each of its landings, for as long as
/// the swarm's events flow.
pub fn spawn(state: ApiState) {
    let mut events = state.events.subscribe();
    tokio::spawn(async move {
        loop {
            match events.recv().await {
                Ok(SwarmEvent::StateChanged { id, from, to }) if landed(from, to) => {
                    tokio::spawn(fetch(state.clone(), id));
                }
                Ok(_) | Err(RecvError::Lagged(_)) => {}
                Err(RecvError::Closed) => return,
            }
        }
    });
}

/// A flight ended: from a state in the air to `Landed` (disarmed).
fn landed(from: VehicleState, to: VehicleState) -> bool {
    from.is_airborne() && to == VehicleState::Landed
}

async fn fetch(s: ApiState, vehicle: String) {
    for attempt in 1..=ATTEMPTS {
        match crate::flight_logs::fetch_newest(&s, &vehicle).await {
            Ok(status) => {
                tracing::info!(
                    "{vehicle} landed: fetching its log {} ({} bytes)",
                    status.log_id,
                    status.size_bytes
                );
                return;
            }
            Err(e) if attempt == ATTEMPTS => {
                tracing::warn!("{vehicle} landed, its log was not fetched: {}", e.error);
            }
            Err(_) => tokio::time::sleep(RETRY).await,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_end_of_a_flight_fetches() {
        assert!(landed(VehicleState::Landing, VehicleState::Landed));
        assert!(landed(VehicleState::ReturnToLaunch, VehicleState::Landed));
        assert!(
            !landed(VehicleState::Armed, VehicleState::Landed),
            "disarmed unflown"
        );
        assert!(!landed(VehicleState::Disconnected, VehicleState::Landed));
        assert!(!landed(VehicleState::Landing, VehicleState::Lost));
    }
}
