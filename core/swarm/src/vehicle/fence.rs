//! The geofence as one vehicle flies by it: the fence its setpoints are clamped into (the
//! one in force, followed at once when an operator changes it; a test fault can bypass
//! it), skein's own breach check of the vehicle in the air, and the events that tell the
//! operator about both and about its autopilot's copy of the fence.

use super::VehicleCore;
use super::shared::Memory;
use crate::context::LiveFence;
use crate::events::SwarmEvent;
use skein_model::fsm::VehicleState;
use skein_model::geo::Ned;
use skein_model::geofence::{FenceSyncState, Geofence};
use std::sync::{Arc, LazyLock};

/// How far outside the fence a vehicle must be before skein calls it a breach, metres:
/// setpoints stay 2 m inside, and a vehicle overshoots them by less than that.
pub const BREACH_TOLERANCE_M: f64 = 1.0;

/// What a bypassed vehicle's setpoints are clamped into (see [`Geofence::unbounded`]).
static UNBOUNDED: LazyLock<Arc<LiveFence>> = LazyLock::new(|| {
    Arc::new(LiveFence {
        fence: Geofence::unbounded(),
        version: 0,
    })
});

/// A vehicle's geofence memory (kept across actor restarts with the rest of its FSM memory).
#[derive(Debug, Clone, Default)]
pub struct FenceMemory {
    /// (version, bypassed) of the fence the shaper clamps into.
    applied: Option<(u64, bool)>,
    /// Test fault `bypass_geofence`: setpoints skip the geofence (the autopilot's own
    /// fence is what stops the vehicle).
    pub bypassed: bool,
    /// skein's own check: airborne and more than [`BREACH_TOLERANCE_M`] outside.
    pub breached: bool,
    /// The autopilot's copy as last told in an event (state, version).
    told: Option<(FenceSyncState, u64)>,
}

impl VehicleCore {
    /// The fence setpoints are clamped into now: the one in force, or with the test fault
    /// one nothing reaches. Brings the shaper up to date when either changed.
    pub(super) fn setpoint_fence(&self, mem: &mut Memory) -> Arc<LiveFence> {
        let fence = if mem.fence.bypassed {
            UNBOUNDED.clone()
        } else {
            self.context.geofence()
        };
        let key = (fence.version, mem.fence.bypassed);
        if mem.fence.applied != Some(key) {
            if let Some(s) = mem.shaper.as_mut() {
                s.set_fence(&fence.fence);
            }
            mem.fence.applied = Some(key);
        }
        fence
    }

    /// The test fault `bypass_geofence`: this vehicle's setpoints skip the geofence from
    /// now on (until skein restarts).
    pub(super) fn bypass_geofence(&self) {
        tracing::warn!(id = %self.shared.id, "fault injected: setpoints bypass the geofence");
        self.shared.memory().fence.bypassed = true;
    }

    /// At the publish rate: skein's own breach check of the vehicle at `current` (swarm
    /// frame) in `state`, and the autopilot's fence status, as events when they change.
    pub(super) fn watch_fence(&self, current: Option<Ned>, state: VehicleState) {
        let live = self.context.geofence();
        let outside = current.filter(|_| state.is_airborne()).and_then(|p| {
            let (q, v) = live.fence.clamp(p, false);
            (v.is_some() && (q - p).norm() > BREACH_TOLERANCE_M).then_some(p)
        });
        let status = self.shared.link.fence().status();
        let mut mem = self.shared.memory();
        let breached = outside.is_some();
        if breached != mem.fence.breached {
            mem.fence.breached = breached;
            let p = outside.or(current).unwrap_or(Ned::ZERO);
            self.emit(SwarmEvent::GeofenceBreach {
                id: self.shared.id.clone(),
                breached,
                position: [p.north_m, p.east_m, -p.down_m],
            });
        }
        let now = Some((status.state, status.version));
        if mem.fence.told != now && status.version > 0 {
            mem.fence.told = now;
            self.emit(SwarmEvent::FenceSync {
                id: self.shared.id.clone(),
                state: status.state.name().into(),
                version: status.version,
                reason: status.reason,
            });
        }
    }
}
