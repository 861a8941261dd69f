//! What every actor of the swarm is given: the configuration, the process's services, its
//! clocks ([`Ticker`]), and the swarm frame (the common NED frame every position is expressed in, anchored once at
//! the configured origin or at the first vehicle's home). Where the other vehicles are is
//! not here: the coordinator owns the vehicle registry ([`crate::vehicle::fleet`]) and the
//! neighbour board ([`crate::neighbours`]), and hands out readers.

use crate::config::SwarmConfig;
use crate::services::{SimulatorControl, SwarmServices};
use crate::ticker::Ticker;
use skein_model::geo::{GeoPoint, NedFrame};
use std::sync::{Arc, OnceLock};

/// Configuration, services and the swarm frame (see the module docs).
pub struct SwarmContext {
    frame: OnceLock<NedFrame>,
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
    /// A context with the configured origin as the swarm frame's anchor (if any).
    pub fn new(config: SwarmConfig, services: SwarmServices) -> Self {
        let frame = OnceLock::new();
        if let Some(origin) = config.swarm_origin {
            let _ = frame.set(NedFrame::new(origin));
        }
        SwarmContext {
            frame,
            config,
            services,
            ticker: Ticker::new(),
        }
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
    /// frame in force.
    pub fn anchor(&self, origin: GeoPoint) -> NedFrame {
        *self.frame.get_or_init(|| NedFrame::new(origin))
    }
}
