//! Fault injection, shared by every supervised actor: what `panic`, `hang`, `stop` and
//! `error` do to the actor that receives them.

use ractor::{ActorProcessingErr, ActorRef, Message};
use skein_model::supervision::FaultKind;

/// Carries out `kind` inside the handler of the actor `myself` (named `who` in messages).
///
/// # Errors
/// [`FaultKind::Error`] returns an error, which fails the actor. [`FaultKind::Panic`]
/// panics (ractor turns the panic into an actor failure). [`FaultKind::Hang`] never
/// returns: the handler awaits forever until the watchdog kills the actor.
/// [`FaultKind::Stop`] asks the actor to stop after this message.
pub async fn inject<M: Message>(
    kind: FaultKind,
    myself: &ActorRef<M>,
    who: &str,
) -> Result<(), ActorProcessingErr> {
    tracing::warn!("fault injected into {who}: {}", kind.name());
    match kind {
        FaultKind::Panic => panic!("injected panic in {who}"),
        FaultKind::Hang => {
            std::future::pending::<()>().await;
            Ok(())
        }
        FaultKind::Stop => {
            myself.stop(Some(format!("injected stop of {who}")));
            Ok(())
        }
        FaultKind::Error => Err(format!("injected error in {who}").into()),
        // Only a Vehicle actor has setpoints to let through; the coordinator routes it
        // nowhere else.
        FaultKind::BypassGeofence => {
            tracing::warn!("bypass_geofence ignored by {who}: not a vehicle");
            Ok(())
        }
    }
}
