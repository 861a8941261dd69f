//! What every actor of the swarm is given: the configuration, the process's services, its
//! clocks ([`Ticker`]), the swarm frame (the common NED frame every position is expressed
//! in, anchored once at the configured origin or at the first vehicle's home), and the
//! geofence in force (the configured one until an operator replaces it,
//! [`SwarmContext::set_geofence`]) with its plan for the autopilots. Where the other
//! vehicles are is not here: the coordinator owns the vehicle registry
//! ([`crate::vehicle::fleet`]) and the neighbour board ([`crate::neighbours`]), and hands
//! out readers.

use crate::config::SwarmConfig;
use crate::services::{SimulatorControl, SwarmServices};
use crate::ticker::Ticker;
use skein_link::fence::FencePlan;
use skein_link::fence_sync::FencePlans;
use skein_model::geo::{GeoPoint, NedFrame};
use skein_model::geofence::Geofence;
use std::sync::{Arc, OnceLock};
use tokio::sync::watch;

/// The geofence in force and its version (1 = the configured fence; each accepted change
/// adds one).
#[derive(Debug, Clone, PartialEq)]
pub struct LiveFence {
    /// The fence, swarm frame.
    pub fence: Geofence,
    /// Its version.
    pub version: u64,
}

/// Configuration, services, the swarm frame and the fence in force (see the module docs).
pub struct SwarmContext {
    frame: OnceLock<NedFrame>,
    fence: watch::Sender<Arc<LiveFence>>,
    plans: watch::Sender<Option<Arc<FencePlan>>>,
    /// The configuration the swarm runs with.
    pub config: SwarmConfig,
    /// Payload factory and simulator hooks.
    pub services: SwarmServices,
    /// The process's clocks for every actor's periodic messages.
    pub ticker: Ticker,
}

impl std::fmt::Debug for SwarmContext {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SwarmContext")
            .field("frame", &self.frame)
            .finish_non_exhaustive()
    }
}

impl SwarmContext {
    /// A context with the configured origin as the swarm frame's anchor (if any) and the
    /// configured geofence in force.
    pub fn new(config: SwarmConfig, services: SwarmServices) -> Self {
        let frame = OnceLock::new();
        if let Some(origin) = config.swarm_origin {
            let _ = frame.set(NedFrame::new(origin));
        }
        let live = LiveFence {
            fence: config.geofence.clone(),
            version: 1,
        };
        let plan = frame
            .get()
            .map(|f| Arc::new(FencePlan::new(&live.fence, f, live.version)));
        SwarmContext {
            frame,
            fence: watch::channel(Arc::new(live)).0,
            plans: watch::channel(plan).0,
            config,
            services,
            ticker: Ticker::new(),
        }
    }

    /// The geofence in force now (every setpoint, formation and go-to check reads it).
    pub fn geofence(&self) -> Arc<LiveFence> {
        self.fence.borrow().clone()
    }

    /// The fence as the autopilots' mission items, for [`skein_link::VehicleLink::follow_fence`]
    /// (none until the swarm frame is anchored).
    pub fn fence_plans(&self) -> FencePlans {
        self.plans.subscribe()
    }

    /// The plan `fence` would be as version `version`, if the swarm frame is anchored.
    pub fn plan_of(&self, fence: &Geofence, version: u64) -> Option<Arc<FencePlan>> {
        self.frame()
            .map(|f| Arc::new(FencePlan::new(fence, &f, version)))
    }

    /// Puts `fence` (checked by the caller) in force as the next version, with `plan`
    /// (from [`SwarmContext::plan_of`], already held by the autopilots) as its plan;
    /// returns the version.
    pub fn set_geofence(&self, fence: Geofence, plan: Option<Arc<FencePlan>>) -> u64 {
        let version = self.geofence().version + 1;
        let plan = plan
            .filter(|p| p.version == version)
            .or_else(|| self.plan_of(&fence, version));
        self.fence
            .send_replace(Arc::new(LiveFence { fence, version }));
        self.plans.send_replace(plan);
        version
    }

    /// The in-process simulator's controls, if any.
    pub fn simulator(&self) -> Option<&Arc<dyn SimulatorControl>> {
        self.services.simulator.as_ref()
    }

    /// The swarm frame, once anchored.
    pub fn frame(&self) -> Option<NedFrame> {
        self.frame.get().copied()
    }

    /// Anchors the swarm frame at `origin` unless it is already anchored; returns the
    /// frame in force. The fence's plan for the autopilots exists from then on.
    pub fn anchor(&self, origin: GeoPoint) -> NedFrame {
        let frame = *self.frame.get_or_init(|| NedFrame::new(origin));
        self.plans.send_if_modified(|plan| {
            if plan.is_some() {
                return false;
            }
            let live = self.fence.borrow().clone();
            *plan = Some(Arc::new(FencePlan::new(&live.fence, &frame, live.version)));
            true
        });
        frame
    }
}
