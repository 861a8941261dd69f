//! The part of a vehicle that outlives its actor: identity, link, FSM memory, and what it
//! publishes (the snapshot the API shows and the [`VehicleReport`] the coordinator flies
//! the formation with).

use super::control::Target;
use super::messages::Child;
use super::slot_correction::SlotCorrection;
use crate::config::VehicleModel;
use crate::payload::PayloadShared;
use crate::protocol::{SlotTarget, VehicleReport, wall_us};
use crate::supervision::{self, ChildKey, Supervision};
use skein_link::Telemetry;
use skein_link::VehicleLink;
use skein_model::fsm::{self, VehicleState};
use skein_model::geo::{FrameTransform, Ned, NedFrame, wrap_deg_360};
use skein_model::geofence::FenceStatus;
use skein_model::safety::{FenceViolation, SetpointShaper};
use skein_model::vehicle::{
    Battery, FormationSlot, GpsStatus, LinkStatus, Position, VehicleSnapshot, Velocity,
};
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError, RwLock};
use std::time::Instant;
use tokio::sync::watch;

/// A vehicle's payload slots by slot name.
pub type PayloadMap = BTreeMap<String, Arc<PayloadShared>>;

#[derive(Debug)]
pub(super) struct Memory {
    pub(super) state: VehicleState,
    pub(super) target: Option<Target>,
    pub(super) shaper: Option<SetpointShaper>,
    pub(super) slot: Option<SlotTarget>,
    pub(super) yaw_rad: f64,
    /// Generation of the running procedure; results of older ones are ignored.
    pub(super) procedure: u64,
    /// The takeoff procedure has PX4 in OFFBOARD and the climb target is set.
    pub(super) offboard_engaged: bool,
    /// Generation of a running procedure that brings PX4 from another mode (LAND, RTL,
    /// HOLD) into OFFBOARD for a hold or go-to: until it ends, PX4 still reporting the
    /// mode it is leaving is expected, not a failsafe.
    pub(super) entering_offboard: Option<u64>,
    pub(super) takeoff_altitude_m: f64,
    pub(super) goto_target: Option<Ned>,
    pub(super) last_fence: Option<FenceViolation>,
    /// What the control loop learnt of the vehicle's tracking lag (kept across actor
    /// restarts, like the rest of the memory).
    pub(super) slot_correction: SlotCorrection,
    /// The geofence as this vehicle flies by it (see `vehicle::fence`).
    pub(super) fence: super::fence::FenceMemory,
}

/// The part of a vehicle that outlives its actor: identity, link, FSM memory and the
/// published snapshot.
pub struct VehicleShared {
    /// User-facing id (`uav-<sysid>` by default).
    pub id: String,
    /// Vehicle model.
    pub model: VehicleModel,
    /// The link state (endpoint route, telemetry, setpoint stream).
    pub link: Arc<VehicleLink>,
    /// True for a vehicle of the in-process simulator.
    pub simulated: bool,
    /// Its endpoint's address as the snapshot shows it (written once: formatting it for
    /// every snapshot was 4 % of the control steps' CPU at 100 vehicles).
    connection: String,
    /// The payload slots (its model's, plus those attached at run time), with what each
    /// published; read with [`VehicleShared::payloads`] (copy-on-write: readers get a
    /// consistent map without holding the lock).
    payloads: RwLock<Arc<PayloadMap>>,
    memory: Mutex<Memory>,
    snapshot: watch::Sender<VehicleSnapshot>,
    report: watch::Sender<VehicleReport>,
    /// The maps swarm frame → local frame and back, worked out when either frame changes.
    transforms: Mutex<Option<Transforms>>,
}

/// What one control step reads of the telemetry (see [`VehicleShared::fix`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct Fix {
    /// The vehicle's local NED frame (its EKF origin), once known.
    pub(super) local_frame: Option<NedFrame>,
    /// Swarm-frame NED position, metres, moved on by its velocity for the sample's age.
    pub(super) position: Option<Ned>,
    /// Velocity, NED m/s.
    pub(super) velocity: Option<Ned>,
    /// Heading, radians clockwise from north (`ATTITUDE.yaw`; 0 before the first).
    pub(super) heading_rad: f64,
}

impl Fix {
    /// Position and velocity (zero when unknown), when the position is known.
    pub(super) fn measured(&self) -> Option<(Ned, Ned)> {
        self.position
            .map(|p| (p, self.velocity.unwrap_or(Ned::ZERO)))
    }
}

/// The maps between the swarm frame and a vehicle's local frame.
#[derive(Debug, Clone, Copy)]
pub(super) struct Transforms {
    /// Swarm NED → the vehicle's local NED (setpoints).
    pub(super) to_local: FrameTransform,
    /// The vehicle's local NED → swarm NED (positions).
    pub(super) to_swarm: FrameTransform,
}

impl std::fmt::Debug for VehicleShared {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VehicleShared")
            .field("id", &self.id)
            .finish_non_exhaustive()
    }
}

impl VehicleShared {
    /// A vehicle never heard from, in [`VehicleState::Disconnected`].
    pub fn new(
        id: String,
        model: VehicleModel,
        link: Arc<VehicleLink>,
        simulated: bool,
    ) -> Arc<Self> {
        let payloads = RwLock::new(Arc::new(
            model
                .payloads
                .iter()
                .map(|p| (p.slot.clone(), PayloadShared::new(p.clone())))
                .collect(),
        ));
        let connection = link.endpoint.address().to_string();
        let snapshot = VehicleSnapshot {
            id: id.clone(),
            sysid: link.sysid,
            connection: connection.clone(),
            model: model.name.clone(),
            state: VehicleState::Disconnected,
            armed: false,
            px4_mode: "UNKNOWN".into(),
            landed_state: Default::default(),
            position: None,
            home: None,
            velocity: Velocity::default(),
            heading_deg: 0.0,
            battery: None,
            gps: None,
            prearm_ok: None,
            px4_messages: vec![],
            px4_arming_checks: vec![],
            link: LinkStatus {
                connected: false,
                last_seen_ms: 0,
            },
            formation: None,
            payloads: vec![],
            fence: None,
            remote_id: None,
        };
        Arc::new(VehicleShared {
            id,
            model,
            link,
            simulated,
            connection,
            payloads,
            memory: Mutex::new(Memory {
                state: VehicleState::Disconnected,
                target: None,
                shaper: None,
                slot: None,
                yaw_rad: 0.0,
                procedure: 0,
                offboard_engaged: false,
                entering_offboard: None,
                takeoff_altitude_m: 0.0,
                goto_target: None,
                last_fence: None,
                slot_correction: SlotCorrection::default(),
                fence: Default::default(),
            }),
            snapshot: watch::channel(snapshot).0,
            report: watch::channel(VehicleReport::disconnected()).0,
            transforms: Mutex::new(None),
        })
    }

    /// The FSM memory, recovered if a panic poisoned its lock (the state it guards is
    /// what a restarted actor must resume from).
    pub(super) fn memory(&self) -> MutexGuard<'_, Memory> {
        self.memory.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The payload slots now (a snapshot: attaches and detaches after this call replace
    /// the map, they do not change this one).
    pub fn payloads(&self) -> Arc<PayloadMap> {
        self.payloads
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// The payload in `slot`, if the vehicle has that slot.
    pub fn payload(&self, slot: &str) -> Option<Arc<PayloadShared>> {
        self.payloads().get(slot).cloned()
    }

    /// Adds a slot (a run-time attach; it lasts until skein restarts); false if the slot
    /// exists already.
    pub(crate) fn insert_payload(&self, payload: Arc<PayloadShared>) -> bool {
        let mut map = self
            .payloads
            .write()
            .unwrap_or_else(PoisonError::into_inner);
        if map.contains_key(&payload.spec.slot) {
            return false;
        }
        let mut next = PayloadMap::clone(&map);
        next.insert(payload.spec.slot.clone(), payload);
        *map = Arc::new(next);
        true
    }

    /// Removes a slot (a run-time detach); the removed payload, if there was one.
    pub(crate) fn remove_payload(&self, slot: &str) -> Option<Arc<PayloadShared>> {
        let mut map = self
            .payloads
            .write()
            .unwrap_or_else(PoisonError::into_inner);
        let mut next = PayloadMap::clone(&map);
        let removed = next.remove(slot);
        *map = Arc::new(next);
        removed
    }

    /// The latest published snapshot.
    pub fn snapshot(&self) -> VehicleSnapshot {
        self.snapshot.borrow().clone()
    }

    /// `f` of the latest published snapshot, read in place (the channel's lock is held
    /// meanwhile: `f` must be quick).
    pub fn with_snapshot<R>(&self, f: impl FnOnce(&VehicleSnapshot) -> R) -> R {
        f(&self.snapshot.borrow())
    }

    /// The published snapshots (the in-process carrier of the vehicle's state topic).
    pub fn subscribe_snapshots(&self) -> watch::Receiver<VehicleSnapshot> {
        self.snapshot.subscribe()
    }

    /// The published reports (the in-process carrier of what the formation engine needs).
    ///
    /// Read them with `borrow()`: the control step replaces the report every period
    /// without marking it changed, so `changed()` never fires. Nobody waits for a report
    /// (the formation and the DDS link read them on their own clocks), and waking nobody
    /// cost a watch channel's eight notifier locks per vehicle and period.
    pub fn subscribe_reports(&self) -> watch::Receiver<VehicleReport> {
        self.report.subscribe()
    }

    /// Publishes a [`VehicleReport`] from the telemetry and the FSM memory, positions in
    /// the swarm `frame` (none without a frame).
    pub fn publish_report(&self, frame: Option<NedFrame>) {
        let now = Instant::now();
        let fix = frame.map(|f| self.fix(&f, now));
        let measured = fix.and_then(|f| f.measured());
        let memory = {
            let mem = self.memory();
            (mem.state, mem.target)
        };
        let heading_rad = fix.map_or_else(|| self.heading_rad(), |f| f.heading_rad);
        self.publish_measured(measured, heading_rad, memory, now);
    }

    /// Publishes a [`VehicleReport`] from what the control step has just read at `now`
    /// (`measured` position and velocity, swarm frame, and `heading_rad`) and the FSM
    /// `state` and `target` it left, so that nothing is read twice.
    pub(super) fn publish_measured(
        &self,
        measured: Option<(Ned, Ned)>,
        heading_rad: f64,
        (state, target): (VehicleState, Option<Target>),
        now: Instant,
    ) {
        let report = VehicleReport {
            state,
            position: measured.map(|(p, _)| p),
            velocity: measured.map_or(Ned::ZERO, |(_, v)| v),
            heading_rad,
            link_silence_s: self.link.silence_at(now).map(|s| s.as_secs_f64()),
            target: target.map(|t| t.position()),
            stamp_us: wall_us(),
            ride_through_s: None,
        };
        // Replaced in place without waking anyone: see `subscribe_reports`.
        self.report.send_if_modified(|r| {
            *r = report;
            false
        });
    }

    /// The FSM state.
    pub fn state(&self) -> VehicleState {
        self.memory().state
    }

    /// The maps between the swarm frame `swarm` and the vehicle's local frame `local`
    /// (worked out again only when one of them changed).
    pub(super) fn transforms(&self, swarm: &NedFrame, local: &NedFrame) -> Transforms {
        let mut cached = self
            .transforms
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        match *cached {
            Some(t) if t.to_local.maps(swarm, local) => t,
            _ => {
                let t = Transforms {
                    to_local: swarm.transform_to(local),
                    to_swarm: local.transform_to(swarm),
                };
                *cached = Some(t);
                t
            }
        }
    }

    /// Current swarm-frame position (from the vehicle's local position through its origin
    /// and the swarm frame), if known, moved on by its velocity for the age of the sample
    /// (at most 200 ms: PX4 streams it at 10–30 Hz, and a vehicle at 5 m/s covers 17 cm
    /// between two samples).
    pub fn position(&self, swarm: &NedFrame) -> Option<Ned> {
        self.fix(swarm, Instant::now()).position
    }

    /// What a control step needs of the telemetry at `now`, read in one look under its
    /// lock: the vehicle's local frame, and its position ([`VehicleShared::position`],
    /// swarm frame), velocity ([`VehicleShared::velocity`]) and heading
    /// ([`VehicleShared::heading_rad`]).
    pub(super) fn fix(&self, swarm: &NedFrame, now: Instant) -> Fix {
        let (local, local_frame, received, global, velocity, heading_rad) =
            self.link.with_telemetry(|t| {
                (
                    t.local,
                    t.local_frame(),
                    t.local_received,
                    t.global,
                    velocity_of(t),
                    heading_of(t),
                )
            });
        let position = match (local, local_frame) {
            (Some(l), Some(frame)) => {
                let age = received.map_or(0.0, |at| {
                    now.saturating_duration_since(at).as_secs_f64().min(0.2)
                });
                let to_swarm = self.transforms(swarm, &frame).to_swarm;
                Some(to_swarm.apply(l.position + l.velocity_m_s * age))
            }
            _ => global.map(|g| swarm.to_ned(&g.geo)),
        };
        Fix {
            local_frame,
            position,
            velocity,
            heading_rad,
        }
    }

    /// Heading, radians clockwise from north (`ATTITUDE.yaw`).
    pub fn heading_rad(&self) -> f64 {
        self.link.with_telemetry(heading_of)
    }

    /// Publishes a fresh snapshot from the telemetry, the FSM state, the formation slot
    /// and the payloads' supervision status and state.
    pub fn publish(
        &self,
        frame: Option<NedFrame>,
        slot: Option<SlotTarget>,
        supervision: &Supervision,
    ) {
        let state = self.state();
        let fence = self.fence_status();
        let current = frame.and_then(|f| self.position(&f));
        let link = &self.link;
        let silence = link.silence();
        let vehicle_path = format!("{}/{}", supervision::ROOT, self.id);
        let payloads = self
            .payloads()
            .iter()
            .map(|(slot, p)| {
                let path = Child::Payload(slot.clone()).path(&vehicle_path);
                let status = supervision.record(&path).map(|r| r.status);
                payload_json(p, status)
            })
            .collect();
        let snap = link.with_telemetry(|t| {
            let position = frame.and_then(|frame| {
                t.global.map(|g| {
                    let mut p = Position::from_geo(g.geo, g.relative_alt_m, &frame);
                    if let Some(c) = current {
                        p.north_m = c.north_m;
                        p.east_m = c.east_m;
                        p.down_m = c.down_m;
                    }
                    p
                })
            });
            let slot = slot.map(|s| FormationSlot {
                slot: s.slot,
                leader: s.leader,
                target: s.goal,
                error_m: current.map_or(f64::NAN, |c| (c - s.goal).norm()),
            });
            let vel = velocity_of(t).unwrap_or(Ned::ZERO);
            VehicleSnapshot {
                id: self.id.clone(),
                sysid: link.sysid,
                connection: self.connection.clone(),
                model: self.model.name.clone(),
                state,
                armed: t.heartbeat.is_some_and(|h| h.armed),
                px4_mode: t.heartbeat.map_or("UNKNOWN", |h| h.mode.name()).to_string(),
                landed_state: t.landed_state,
                position,
                home: frame.and_then(|f| t.home.map(|h| Position::from_geo(h.geo, 0.0, &f))),
                velocity: Velocity {
                    north_m_s: vel.north_m,
                    east_m_s: vel.east_m,
                    down_m_s: vel.down_m,
                },
                heading_deg: t.heading_deg().map_or(0.0, wrap_deg_360),
                battery: t.battery.map(|b| Battery {
                    percent: b.percent.unwrap_or(f64::NAN),
                    voltage_v: b.voltage_v.unwrap_or(f64::NAN),
                }),
                link: LinkStatus {
                    connected: t.heartbeat.is_some() && !link.is_lost(),
                    last_seen_ms: silence.map_or(0, |s| s.as_millis() as u64),
                },
                formation: slot,
                payloads,
                gps: t.gps_fix_type.map(|fix_type| GpsStatus {
                    fix_type,
                    satellites: t.satellites.unwrap_or(0),
                    eph_m: t.gps_eph_m,
                    epv_m: t.gps_epv_m,
                    correction_age_s: correction_age_s(link),
                }),
                prearm_ok: t.prearm_ok,
                px4_messages: t.px4_messages.iter().cloned().collect(),
                px4_arming_checks: t.px4_arming_checks(),
                fence: Some(fence),
                remote_id: link.remote_id().status(
                    link.setup().remote_id.as_ref(),
                    link.setup().operator_gnss.as_ref(),
                    t.remote_id.clone(),
                    std::time::Instant::now(),
                ),
            }
        });
        self.snapshot.send_replace(snap);
    }

    /// The geofence on this vehicle: its autopilot's copy (from the link) and skein's own
    /// breach check.
    pub fn fence_status(&self) -> FenceStatus {
        let mut status = self.link.fence().status();
        status.breached = self.memory().fence.breached;
        status
    }

    /// True when the vehicle has at least one payload slot.
    pub fn has_payloads(&self) -> bool {
        !self.payloads().is_empty()
    }

    /// With no Vehicle actor (escalated), the FSM state follows telemetry alone.
    pub fn settle_from_telemetry(&self) {
        if let Some(o) = self.link.with_telemetry(|t| t.observed()) {
            self.memory().state = fsm::settle(o);
        }
    }

    /// Where the vehicle is being held or sent (swarm frame), if skein is steering it.
    pub fn target_position(&self) -> Option<Ned> {
        self.memory().target.map(|t| t.position())
    }

    /// Current velocity, NED m/s.
    pub fn velocity(&self) -> Option<Ned> {
        self.link.with_telemetry(velocity_of)
    }
}

/// Velocity, NED m/s: `LOCAL_POSITION_NED`'s, else `GLOBAL_POSITION_INT`'s.
/// Seconds since the vehicle was last sent RTK corrections, if ever.
fn correction_age_s(link: &VehicleLink) -> Option<f64> {
    let sent_ms = link.corrections().sent().last_unix_ms?;
    let now_ms = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .ok()?
        .as_millis() as u64;
    Some(now_ms.saturating_sub(sent_ms) as f64 / 1000.0)
}

fn velocity_of(t: &Telemetry) -> Option<Ned> {
    t.local
        .map(|l| l.velocity_m_s)
        .or(t.global.map(|g| g.velocity_m_s))
}

/// Heading, radians clockwise from north (`ATTITUDE.yaw`; 0 before the first).
fn heading_of(t: &Telemetry) -> f64 {
    t.attitude.map_or(0.0, |a| a.yaw_rad)
}

/// One payload as the vehicle snapshot lists it: `slot`, `kind`, `requested_plugin` (the
/// spec's), `plugin` / `plugin_version` / `generation` (the library serving it now, `null`
/// while none does), `isolation`, `status` (the supervision status, e.g. `running` or
/// `waiting_for_plugin`), `waiting_for` (naming the kind, while it waits), `state`,
/// `frames`.
pub fn payload_json(
    p: &PayloadShared,
    status: Option<skein_model::supervision::ChildStatus>,
) -> serde_json::Value {
    let served = p.served_by();
    serde_json::json!({
        "slot": p.spec.slot,
        "kind": p.spec.kind,
        "requested_plugin": p.spec.plugin,
        "plugin": served.as_ref().map(|s| &s.plugin),
        "plugin_version": served.as_ref().map(|s| &s.version),
        "generation": served.as_ref().map(|s| s.generation),
        "isolation": p.spec.isolation,
        "status": status,
        "waiting_for": p.waiting(),
        "state": p.state(),
        "frames": p.frames_published(),
    })
}
