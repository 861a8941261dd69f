//! The parts the coordinator runs as supervised services (the API, the DDS link).

use skein_swarm::Swarm;
use std::time::Duration;

/// Has the coordinator start and supervise `service` (`what` names it in the error).
///
/// # Errors
/// The service's own start error, or a coordinator that did not answer within 10 s.
pub(super) async fn add_service(
    swarm: &Swarm,
    service: skein_swarm::ServiceSpec,
    what: &str,
) -> Result<(), String> {
    match swarm
        .coordinator
        .call(
            |r| skein_swarm::AdminMsg::AddService(service, r).into(),
            Some(Duration::from_secs(10)),
        )
        .await
    {
        Ok(ractor::rpc::CallResult::Success(Ok(()))) => Ok(()),
        Ok(ractor::rpc::CallResult::Success(Err(e))) => Err(e),
        _ => Err(format!("the coordinator did not start {what}")),
    }
}
