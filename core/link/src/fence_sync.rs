//! Keeping one autopilot on skein's fence: upload the fence and rally items of a
//! [`FencePlan`] with the mission protocol, read both back and compare, then set
//! `GF_ACTION` and `GF_MAX_VER_DIST` with the parameter protocol; the outcome is the
//! vehicle's [`FenceStatus`] (`synced`, `differs` or `failed` with the reason).
//!
//! A sync drives the autopilot through the narrow [`FenceAutopilot`] trait: the
//! `Px4Link` actor implements it with its own mission and parameter messages
//! (`px4link/missions.rs`), so this module depends on the mission items and the fence
//! plan only, and the link actor on it. The actor runs a sync in the background on
//! connect, after a reboot or a restored link and whenever the plan the vehicle follows
//! changes (`VehicleLink::follow_fence`), and on demand for a candidate fence
//! (`Px4LinkMsg::TryFence`, what `PUT /api/v1/geofence` does before it commits). The
//! syncs of one vehicle never overlap. A vehicle whose sync failed or differs is tried
//! again every [`RETRY_AFTER`] (a refusal may have been passing: a full storage, a link
//! that dropped the transfer).

use crate::fence::{FencePlan, difference};
use crate::mission::MissionItem;
use skein_mavlink::dialect::MavMissionType;
use skein_model::geofence::{FenceStatus, FenceSyncState};
use std::future::Future;
use std::sync::{Arc, OnceLock, RwLock};
use std::time::Duration;
use tokio::sync::watch;

/// The plans a vehicle follows: the latest fence version as items (none until the swarm
/// origin is known).
pub type FencePlans = watch::Receiver<Option<Arc<FencePlan>>>;

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

/// What a fence sync needs of a vehicle's autopilot link: its side of the fence, whether
/// it is lost, the mission protocol (upload and read-back of one mission type), one
/// parameter write and the home altitude. Errors are the reason as text, naming the step.
pub trait FenceAutopilot: Send + Sync {
    /// The vehicle's side of the fence (status, one sync at a time).
    fn fence(&self) -> &FenceLink;

    /// True while the link to the vehicle is lost.
    fn is_lost(&self) -> bool;

    /// Uploads `items` as the autopilot's plan of type `kind` (fence or rally).
    fn upload(
        &self,
        kind: MavMissionType,
        items: Vec<MissionItem>,
    ) -> impl Future<Output = Result<(), String>> + Send;

    /// Reads the autopilot's plan of type `kind` back.
    fn download(
        &self,
        kind: MavMissionType,
    ) -> impl Future<Output = Result<Vec<MissionItem>, String>> + Send;

    /// Writes the parameter `name` (a float or integer PX4 parameter) as `value`.
    fn set_param(&self, name: &str, value: f64) -> impl Future<Output = Result<(), String>> + Send;

    /// The vehicle's home altitude (m AMSL) from its telemetry, if known yet.
    fn home_altitude_m(&self) -> Option<f64>;
}

/// Waits (polling the telemetry) for the vehicle's home altitude.
async fn home_altitude(autopilot: &impl FenceAutopilot) -> Option<f64> {
    let deadline = tokio::time::Instant::now() + HOME_TIMEOUT;
    loop {
        if let Some(alt) = autopilot.home_altitude_m() {
            return Some(alt);
        }
        if tokio::time::Instant::now() >= deadline {
            return None;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

/// Brings `autopilot` to `plan` (see the module docs); the outcome is stored as the
/// vehicle's status and returned. With `only_if_changed`, a vehicle already synced to
/// this version (or that failed it less than [`RETRY_AFTER`] ago) is left alone.
pub async fn sync(
    autopilot: impl FenceAutopilot,
    plan: Arc<FencePlan>,
    only_if_changed: bool,
) -> FenceStatus {
    let fence = autopilot.fence();
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
    let outcome = run(&autopilot, &plan).await;
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
async fn run(autopilot: &impl FenceAutopilot, plan: &FencePlan) -> Result<Option<String>, String> {
    use MavMissionType::{MAV_MISSION_TYPE_FENCE as FENCE, MAV_MISSION_TYPE_RALLY as RALLY};
    if autopilot.is_lost() {
        return Err("no link to the vehicle".into());
    }
    autopilot.upload(FENCE, plan.fence.clone()).await?;
    autopilot.upload(RALLY, plan.rally.clone()).await?;
    let held = autopilot.download(FENCE).await?;
    if let Some(d) = difference(&plan.fence, &held) {
        return Ok(Some(format!("fence: {d}")));
    }
    let held = autopilot.download(RALLY).await?;
    if let Some(d) = difference(&plan.rally, &held) {
        return Ok(Some(format!("rally: {d}")));
    }
    autopilot
        .set_param("GF_ACTION", f64::from(plan.gf_action))
        .await?;
    let home = home_altitude(autopilot)
        .await
        .ok_or("no home position: GF_MAX_VER_DIST is measured from it")?;
    let above_home = plan.ceiling_amsl_m - home;
    if above_home < 1.0 {
        return Err(format!(
            "the fence ceiling ({:.1} m AMSL) is not above the vehicle's home ({home:.1} m AMSL)",
            plan.ceiling_amsl_m
        ));
    }
    autopilot.set_param("GF_MAX_VER_DIST", above_home).await?;
    Ok(None)
}
