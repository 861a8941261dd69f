//! [`VehicleLink`]: the part of a vehicle's link that outlives its `Px4Link` actor: the
//! endpoint route, the latest telemetry, the setpoint stream, liveness, the connect-time
//! setup and the vehicle's side of the fence.

use crate::corrections::CorrectionsLink;
use crate::endpoint::{Endpoint, Peer};
use crate::fence_sync::{FenceLink, FencePlans};
use crate::remote_id::RemoteIdLink;
use crate::setpoint::SetpointStream;
use crate::setup::LinkSetup;
use crate::telemetry::{Change, Telemetry};
use skein_mavlink::MavMessage;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, RwLock};
use std::time::{Duration, Instant};

/// The per-vehicle state that outlives the link actor: the endpoint route, the latest
/// telemetry and the setpoint stream. Identity of a vehicle is (endpoint, sysid).
pub struct VehicleLink {
    /// The endpoint the vehicle is reached through.
    pub endpoint: Arc<Endpoint>,
    /// The vehicle's system id.
    pub sysid: u8,
    /// The autopilot's component id (1 for PX4).
    pub compid: u8,
    pub(super) telemetry: RwLock<Telemetry>,
    /// The endpoint's record of `sysid` (kept for the endpoint's life), so that asking
    /// how long the vehicle has been silent looks nothing up.
    peer: Arc<Peer>,
    stream: SetpointStream,
    pub(super) lost: AtomicBool,
    pub(super) setup: LinkSetup,
    fence: FenceLink,
    corrections: CorrectionsLink,
    remote_id: RemoteIdLink,
}

impl std::fmt::Debug for VehicleLink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VehicleLink")
            .field("endpoint", &self.endpoint.address())
            .field("sysid", &self.sysid)
            .finish_non_exhaustive()
    }
}

impl VehicleLink {
    /// Creates the shared state and starts the (idle) setpoint stream at `stream_rate_hz`;
    /// `setup` is applied at every (re)connection.
    pub fn new(
        endpoint: Arc<Endpoint>,
        sysid: u8,
        compid: u8,
        stream_rate_hz: f64,
        setup: LinkSetup,
    ) -> Arc<Self> {
        let stream = SetpointStream::start(endpoint.clone(), sysid, compid, stream_rate_hz);
        let peer = endpoint.peer(sysid);
        Arc::new(VehicleLink {
            endpoint,
            sysid,
            compid,
            telemetry: RwLock::new(Telemetry::default()),
            peer,
            stream,
            lost: AtomicBool::new(false),
            setup,
            fence: FenceLink::default(),
            corrections: CorrectionsLink::default(),
            remote_id: RemoteIdLink::default(),
        })
    }

    /// Keeps the autopilot on the latest plan of `plans` (skein's geofence as mission
    /// items): uploaded on connect, after a reboot and on every change. Once per link,
    /// before its actor starts.
    pub fn follow_fence(&self, plans: FencePlans) {
        self.fence.follow(plans);
    }

    /// The vehicle's side of the fence (its status: [`FenceLink::status`]).
    pub fn fence(&self) -> &FenceLink {
        &self.fence
    }

    /// GNSS corrections to the vehicle: their rate budget and what was sent
    /// ([`crate::corrections`]).
    pub fn corrections(&self) -> &CorrectionsLink {
        &self.corrections
    }

    /// The vehicle's side of Remote ID: the operator location last sent
    /// ([`crate::remote_id`]).
    pub fn remote_id(&self) -> &RemoteIdLink {
        &self.remote_id
    }

    /// What is applied at every (re)connection, and sent meanwhile (Remote ID).
    pub fn setup(&self) -> &LinkSetup {
        &self.setup
    }

    /// A copy of the latest telemetry.
    pub fn telemetry(&self) -> Telemetry {
        self.telemetry.read().expect("telemetry lock").clone()
    }

    /// Reads the telemetry in place (no clone) under the lock.
    pub fn with_telemetry<R>(&self, f: impl FnOnce(&Telemetry) -> R) -> R {
        f(&self.telemetry.read().expect("telemetry lock"))
    }

    /// Applies a message from the autopilot to the telemetry now; returns what it
    /// changed that matters to the vehicle's state machine.
    pub(super) fn apply(&self, msg: &MavMessage) -> Change {
        self.telemetry
            .write()
            .expect("telemetry lock")
            .apply(msg, Instant::now())
    }

    /// Changes the telemetry in place under the lock.
    pub(super) fn with_telemetry_mut<R>(&self, f: impl FnOnce(&mut Telemetry) -> R) -> R {
        f(&mut self.telemetry.write().expect("telemetry lock"))
    }

    /// Keeps a text the vehicle sent ([`Telemetry::keep_message`]), stamped now.
    pub(super) fn keep_message(&self, severity: u8, text: &str) {
        let unix_ms = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_millis() as u64);
        self.telemetry
            .write()
            .expect("telemetry lock")
            .keep_message(severity, text, unix_ms);
    }

    /// The offboard setpoint stream.
    pub fn stream(&self) -> &SetpointStream {
        &self.stream
    }

    /// True while the link is lost.
    pub fn is_lost(&self) -> bool {
        self.lost.load(Ordering::Relaxed)
    }

    /// Time since the last valid message from the vehicle.
    pub fn silence(&self) -> Option<Duration> {
        self.silence_at(Instant::now())
    }

    /// Time from the last valid message from the vehicle to `now`.
    pub fn silence_at(&self, now: Instant) -> Option<Duration> {
        self.endpoint
            .seen(&self.peer)
            .map(|t| now.saturating_duration_since(t))
    }
}
