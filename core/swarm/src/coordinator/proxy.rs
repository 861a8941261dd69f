//! The coordinator's view of one vehicle: where to send [`ToVehicle`] messages, its
//! latest snapshot and [`VehicleReport`], and (for a vehicle of this process) the local
//! part the coordinator supervises.

use crate::carrier::LocalPort;
use crate::protocol::{REPORT_EXTRAPOLATION, ToVehicle, VehiclePort, VehicleReport};
use crate::vehicle::VehicleShared;
use ractor::ActorRef;
use skein_link::Px4LinkMsg;
use skein_model::fsm::VehicleState;
use skein_model::geo::Ned;
use skein_model::vehicle::VehicleSnapshot;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::watch;

/// A remote vehicle not reported for this long is `Lost`, its link down.
pub const REMOTE_SILENCE: Duration = Duration::from_secs(2);

/// A vehicle run by this process: what its supervisor (the coordinator, in `skein up`)
/// holds.
pub struct LocalVehicle {
    /// Its persistent part.
    pub shared: Arc<VehicleShared>,
    /// The port to its current actor.
    pub port: Arc<LocalPort>,
    /// The link actor that carried an escalation, kept for the vehicle's telemetry.
    pub safe_link: Option<ActorRef<Px4LinkMsg>>,
}

/// One vehicle as the coordinator sees it.
pub struct VehicleProxy {
    port: Arc<dyn VehiclePort>,
    readout: VehicleReadout,
    /// Its actor kept failing and it was commanded to HOLD/LAND: it gets no commands.
    pub failed: bool,
    /// The local part, for a vehicle of this process.
    pub local: Option<LocalVehicle>,
}

/// Where a vehicle's latest snapshot and report are read: its vehicle actor (or its
/// agent's carrier) writes them, anyone reads them without asking the coordinator (the
/// API's vehicle reads, see [`super::published`]). Cheap to clone.
#[derive(Clone)]
pub struct VehicleReadout {
    snapshots: watch::Receiver<VehicleSnapshot>,
    reports: watch::Receiver<VehicleReport>,
    /// A vehicle of another process (silent for [`REMOTE_SILENCE`]: `Lost`).
    remote: bool,
}

impl VehicleReadout {
    /// True when this is a remote vehicle not reported for [`REMOTE_SILENCE`] (its agent
    /// or the network is down).
    fn remote_silent(&self) -> Option<Duration> {
        if !self.remote {
            return None;
        }
        let age = crate::protocol::age_of(self.reports.borrow().stamp_us);
        (age > REMOTE_SILENCE).then_some(age)
    }

    /// The latest snapshot (`GET /api/v1/vehicles/{id}`). A remote vehicle silent for
    /// [`REMOTE_SILENCE`] shows as `Lost` with its link down, its last values kept.
    pub fn snapshot(&self) -> VehicleSnapshot {
        let mut s = self.snapshots.borrow().clone();
        if let Some(age) = self.remote_silent() {
            s.state = VehicleState::Lost;
            s.link.connected = false;
            s.link.last_seen_ms = s.link.last_seen_ms.max(age.as_millis() as u64);
        }
        s
    }

    /// The latest report; a silent remote vehicle's state is `Lost`.
    pub fn report(&self) -> VehicleReport {
        let mut r = *self.reports.borrow();
        if self.remote_silent().is_some() {
            r.state = VehicleState::Lost;
        }
        r
    }
}

impl VehicleProxy {
    /// A proxy for a vehicle of this process.
    pub fn local(shared: Arc<VehicleShared>) -> Self {
        let port = LocalPort::new();
        VehicleProxy {
            port: port.clone(),
            readout: VehicleReadout {
                snapshots: shared.subscribe_snapshots(),
                reports: shared.subscribe_reports(),
                remote: false,
            },
            failed: false,
            local: Some(LocalVehicle {
                shared,
                port,
                safe_link: None,
            }),
        }
    }

    /// A proxy for a vehicle of another process (an agent's, see [`super::distributed`]).
    pub fn remote(
        port: Arc<dyn VehiclePort>,
        snapshots: watch::Receiver<VehicleSnapshot>,
        reports: watch::Receiver<VehicleReport>,
    ) -> Self {
        VehicleProxy {
            port,
            readout: VehicleReadout {
                snapshots,
                reports,
                remote: true,
            },
            failed: false,
            local: None,
        }
    }

    /// Sends a protocol message; `Err` says why the vehicle cannot be reached.
    pub fn send(&self, msg: ToVehicle) -> Result<(), String> {
        self.port.send(msg)
    }

    /// Where its snapshot and report are read (cheap to clone).
    pub fn readout(&self) -> &VehicleReadout {
        &self.readout
    }

    fn remote_silent(&self) -> Option<Duration> {
        self.readout.remote_silent()
    }

    /// The latest snapshot (see [`VehicleReadout::snapshot`]).
    pub fn snapshot(&self) -> VehicleSnapshot {
        self.readout.snapshot()
    }

    /// The latest report; a silent remote vehicle's state is `Lost` (so the formation
    /// plans around it as a hazard, as around a local vehicle whose link is silent).
    pub fn report(&self) -> VehicleReport {
        self.readout.report()
    }

    /// FSM state as last reported (`Lost` for a silent remote vehicle).
    pub fn state(&self) -> VehicleState {
        self.report().state
    }

    /// The report of a vehicle that flies a formation slot: one last heard in
    /// `InFormation`, and, if it is silent, silent for less than its ride-through (its
    /// agent flies it on its slot meanwhile, see
    /// [`crate::formation::Member::ride_through`]). `None` for any other.
    pub fn formation_report(&self) -> Option<VehicleReport> {
        let r = *self.readout.reports.borrow();
        if r.state != VehicleState::InFormation {
            return None;
        }
        if self.remote_silent().is_none() {
            return Some(r);
        }
        (r.silence_now() < self.ride_through()).then_some(r)
    }

    /// True for a silent remote member of the formation within its ride-through (see
    /// [`VehicleProxy::formation_report`]): not lost to the formation, nor a hazard.
    pub fn riding_through(&self) -> bool {
        self.remote_silent().is_some() && self.formation_report().is_some()
    }

    /// How long a silent member flies its slot on its own: its agent's ride-through, or
    /// [`crate::formation::LEADER_SILENCE`] for a vehicle of this process.
    pub fn ride_through(&self) -> Duration {
        self.readout
            .reports
            .borrow()
            .ride_through_s
            .filter(|s| s.is_finite() && *s >= 0.0)
            .map_or(crate::formation::LEADER_SILENCE, Duration::from_secs_f64)
    }

    /// Swarm-frame position now (the report's, moved on by its age).
    pub fn position(&self) -> Option<Ned> {
        self.readout
            .reports
            .borrow()
            .position_now(REPORT_EXTRAPOLATION)
    }
}
