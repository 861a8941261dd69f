//! The `Px4Link` actor as a [`FenceAutopilot`]: a fence sync's uploads, read-backs and
//! parameter writes become calls to the actor's own mission and parameter messages
//! ([`Px4LinkMsg::MissionUpload`], [`Px4LinkMsg::MissionDownload`],
//! [`Px4LinkMsg::ParamSet`]); the fence status and the home altitude come from the shared
//! [`VehicleLink`].

use super::{Px4LinkMsg, VehicleLink};
use crate::fence_sync::{FenceAutopilot, FenceLink};
use crate::mission::MissionItem;
use ractor::ActorRef;
use ractor::rpc::CallResult;
use skein_mavlink::dialect::MavMissionType;
use std::sync::Arc;
use std::time::Duration;

/// Longest wait for one mission operation or parameter write (the protocols' own
/// time-outs end them well before).
const CALL_TIMEOUT: Duration = Duration::from_secs(60);

/// One vehicle's link actor and its shared state, driven by a fence sync.
pub(super) struct LinkAutopilot {
    /// The vehicle's `Px4Link` actor.
    pub(super) link: ActorRef<Px4LinkMsg>,
    /// The vehicle's shared link state.
    pub(super) vehicle: Arc<VehicleLink>,
}

/// Asks the link actor `msg`, naming `what` in the error when it does not answer.
async fn call<T: Send + 'static>(
    link: &ActorRef<Px4LinkMsg>,
    msg: impl FnOnce(ractor::RpcReplyPort<T>) -> Px4LinkMsg,
    what: &str,
) -> Result<T, String> {
    match link.call(msg, Some(CALL_TIMEOUT)).await {
        Ok(CallResult::Success(v)) => Ok(v),
        Ok(_) => Err(format!("{what}: no answer from the link")),
        Err(e) => Err(format!("{what}: the link stopped ({e})")),
    }
}

impl FenceAutopilot for LinkAutopilot {
    fn fence(&self) -> &FenceLink {
        self.vehicle.fence()
    }

    fn is_lost(&self) -> bool {
        self.vehicle.is_lost()
    }

    async fn upload(&self, kind: MavMissionType, items: Vec<MissionItem>) -> Result<(), String> {
        let what = format!("{} upload", crate::mission::type_name(kind));
        call(
            &self.link,
            |r| Px4LinkMsg::MissionUpload(kind, items, r),
            &what,
        )
        .await?
        .map_err(|e| e.to_string())
    }

    async fn download(&self, kind: MavMissionType) -> Result<Vec<MissionItem>, String> {
        let what = format!("{} read-back", crate::mission::type_name(kind));
        call(&self.link, |r| Px4LinkMsg::MissionDownload(kind, r), &what)
            .await?
            .map_err(|e| e.to_string())
    }

    async fn set_param(&self, name: &str, value: f64) -> Result<(), String> {
        let n = name.to_string();
        call(&self.link, |r| Px4LinkMsg::ParamSet(n, value, r), name)
            .await?
            .map(|_| ())
            .map_err(|e| format!("{name}: {e}"))
    }

    fn home_altitude_m(&self) -> Option<f64> {
        self.vehicle
            .with_telemetry(|t| t.home.map(|h| h.geo.alt_amsl_m))
    }
}
