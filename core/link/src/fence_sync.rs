//! Keeping one autopilot on skein's fence: upload the fence and rally items of a
//! [`FencePlan`] with the mission protocol, read both back and compare, then set
//! `GF_ACTION` and `GF_MAX_VER_DIST` with the parameter protocol; the outcome is the
//! vehicle's [`FenceStatus`] (`synced`, `differs` or `failed` with the reason).
//!
//! The `Px4Link` actor runs a sync as a task talking to the actor itself
//! ([`Px4LinkMsg::MissionUpload`] …), in the background on connect, after a reboot or a
//! restored link and whenever the plan the vehicle follows changes
//! ([`VehicleLink::follow_fence`]), and on demand for a candidate fence
//! ([`Px4LinkMsg::TryFence`], what `PUT /api/v1/geofence` does before it commits). The
//! syncs of one vehicle never overlap. A vehicle whose sync failed or differs is tried
//! again every [`RETRY_AFTER`] (a refusal may have been passing: a full storage, a link
//! that dropped the transfer).

use crate::fence::{FencePlan, difference};
use crate::mission::MissionItem;
use crate::px4link::{Px4LinkMsg, VehicleLink};
use ractor::ActorRef;
use ractor::rpc::CallResult;
use skein_mavlink::dialect::MavMissionType;
use skein_model::geofence::{FenceStatus, FenceSyncState};
use std::sync::{Arc, OnceLock, RwLock};
use std::time::Duration;
use tokio::sync::watch;

/// The plans a vehicle follows: the latest fence version as items (none until the swarm
/// origin is known).
pub type FencePlans = watch::Receiver<Option<Arc<FencePlan>>>;

/// Longest wait for one mission operation or parameter write (the protocols' own
/// time-outs end them well before).
const CALL_TIMEOUT: Duration = Duration::from_secs(60);
/// Longest wait for a home position (what `GF_MAX_VER_DIST` is measured from).
const HOME_TIMEOUT: Duration = Duration::from_secs(15);
/// A vehicle whose sync failed or differs is tried again this long after.
pub const RETRY_AFTER: Duration = Duration::from_secs(10);

/// A vehicle's side of the fence: the plans it follows, its status, one sync at a time.
pub struct FenceLink {
    plans: OnceLock<FencePlans>,
    status: RwLock<FenceStatus>,
    running: tokio::sync::Mutex<()>,
    /// When the last sync ended.
    ended: RwLock<Option<std::time::Instant>>,
}

impl Default for FenceLink {
    fn default() -> Self {
        FenceLink {
            plans: OnceLock::new(),
            status: RwLock::new(FenceStatus::pending(0, "no fence plan yet")),
            running: tokio::sync::Mutex::new(()),
            ended: RwLock::new(None),
        }
    }
}

impl FenceLink {
    /// The plans followed, if any.
    pub fn plans(&self) -> Option<&FencePlans> {
        self.plans.get()
    }

    /// Follows `plans` (once; later calls are ignored).
    pub fn follow(&self, plans: FencePlans) {
        let _ = self.plans.set(plans);
    }

    /// The latest plan, if any.
    pub fn current(&self) -> Option<Arc<FencePlan>> {
        self.plans.get().and_then(|p| p.borrow().clone())
    }

    /// The status now.
    pub fn status(&self) -> FenceStatus {
        self.status
            .read()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .clone()
    }

    /// True when the last sync failed or differs and ended [`RETRY_AFTER`] ago.
    pub fn retry_due(&self) -> bool {
        let failed = matches!(
            self.status().state,
            FenceSyncState::Failed | FenceSyncState::Differs
        );
        let ended = *self
            .ended
            .read()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        failed && ended.is_some_and(|t| t.elapsed() >= RETRY_AFTER)
    }

    fn set(&self, status: FenceStatus) {
        *self
            .status
            .write()
            .unwrap_or_else(std::sync::PoisonError::into_inner) = status;
    }
}

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

async fn upload(
    link: &ActorRef<Px4LinkMsg>,
    kind: MavMissionType,
    items: &[MissionItem],
) -> Result<(), String> {
    let what = format!("{} upload", crate::mission::type_name(kind));
    let items = items.to_vec();
    call(link, |r| Px4LinkMsg::MissionUpload(kind, items, r), &what)
        .await?
        .map_err(|e| e.to_string())
}

async fn download(
    link: &ActorRef<Px4LinkMsg>,
    kind: MavMissionType,
) -> Result<Vec<MissionItem>, String> {
    let what = format!("{} read-back", crate::mission::type_name(kind));
    call(link, |r| Px4LinkMsg::MissionDownload(kind, r), &what)
        .await?
        .map_err(|e| e.to_string())
}

async fn set_param(link: &ActorRef<Px4LinkMsg>, name: &str, value: f64) -> Result<(), String> {
    let n = name.to_string();
    call(link, |r| Px4LinkMsg::ParamSet(n, value, r), name)
        .await?
        .map(|_| ())
        .map_err(|e| format!("{name}: {e}"))
}

/// Waits (polling the telemetry) for the vehicle's home altitude.
async fn home_altitude(vehicle: &VehicleLink) -> Option<f64> {
    let deadline = tokio::time::Instant::now() + HOME_TIMEOUT;
    loop {
        if let Some(alt) = vehicle.with_telemetry(|t| t.home.map(|h| h.geo.alt_amsl_m)) {
            return Some(alt);
        }
        if tokio::time::Instant::now() >= deadline {
            return None;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

/// Brings the autopilot behind `link` to `plan` (see the module docs); the outcome is
/// stored as the vehicle's status and returned. With `only_if_changed`, a vehicle already
/// synced to this version (or that failed it less than [`RETRY_AFTER`] ago) is left
/// alone.
pub async fn sync(
    link: ActorRef<Px4LinkMsg>,
    vehicle: Arc<VehicleLink>,
    plan: Arc<FencePlan>,
    only_if_changed: bool,
) -> FenceStatus {
    let fence = vehicle.fence();
    let _turn = fence.running.lock().await;
    let before = fence.status();
    let recent = fence
        .ended
        .read()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .is_some_and(|t| t.elapsed() < RETRY_AFTER);
    if only_if_changed
        && before.version == plan.version
        && (before.state == FenceSyncState::Synced || recent)
    {
        return before;
    }
    *fence
        .ended
        .write()
        .unwrap_or_else(std::sync::PoisonError::into_inner) = None;
    fence.set(FenceStatus {
        breached: before.breached,
        ..FenceStatus::pending(plan.version, "uploading")
    });
    let outcome = run(&link, &vehicle, &plan).await;
    let status = match outcome {
        Ok(None) => FenceStatus {
            state: FenceSyncState::Synced,
            reason: None,
            version: plan.version,
            fence_items: plan.fence.len(),
            rally_items: plan.rally.len(),
            breached: before.breached,
        },
        Ok(Some(diff)) => FenceStatus {
            state: FenceSyncState::Differs,
            reason: Some(diff),
            version: plan.version,
            fence_items: 0,
            rally_items: 0,
            breached: before.breached,
        },
        Err(why) => FenceStatus {
            state: FenceSyncState::Failed,
            reason: Some(why),
            version: plan.version,
            fence_items: 0,
            rally_items: 0,
            breached: before.breached,
        },
    };
    fence.set(status.clone());
    *fence
        .ended
        .write()
        .unwrap_or_else(std::sync::PoisonError::into_inner) = Some(std::time::Instant::now());
    status
}

/// The steps: `Ok(None)` synced, `Ok(Some(how))` the read-back differs, `Err` a step
/// failed.
async fn run(
    link: &ActorRef<Px4LinkMsg>,
    vehicle: &VehicleLink,
    plan: &FencePlan,
) -> Result<Option<String>, String> {
    use MavMissionType::{MAV_MISSION_TYPE_FENCE as FENCE, MAV_MISSION_TYPE_RALLY as RALLY};
    if vehicle.is_lost() {
        return Err("no link to the vehicle".into());
    }
    upload(link, FENCE, &plan.fence).await?;
    upload(link, RALLY, &plan.rally).await?;
    let held = download(link, FENCE).await?;
    if let Some(d) = difference(&plan.fence, &held) {
        return Ok(Some(format!("fence: {d}")));
    }
    let held = download(link, RALLY).await?;
    if let Some(d) = difference(&plan.rally, &held) {
        return Ok(Some(format!("rally: {d}")));
    }
    set_param(link, "GF_ACTION", f64::from(plan.gf_action)).await?;
    let home = home_altitude(vehicle)
        .await
        .ok_or("no home position: GF_MAX_VER_DIST is measured from it")?;
    let above_home = plan.ceiling_amsl_m - home;
    if above_home < 1.0 {
        return Err(format!(
            "the fence ceiling ({:.1} m AMSL) is not above the vehicle's home ({home:.1} m AMSL)",
            plan.ceiling_amsl_m
        ));
    }
    set_param(link, "GF_MAX_VER_DIST", above_home).await?;
    Ok(None)
}
