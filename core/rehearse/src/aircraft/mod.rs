//! One vehicle of a rehearsal: a PX4-faithful simulated multicopter
//! ([`skein_sim::VirtualVehicle`], on the virtual clock) driven as skein's Vehicle actor
//! drives a real one. Its telemetry is folded by the link's own [`Telemetry`], its
//! state kept by the vehicle FSM ([`skein_model::fsm::transition`]), its commands
//! checked by that FSM and carried out by the same procedures (arm and OFFBOARD after
//! 1.1 s of setpoints, `MAV_CMD_NAV_LAND`, RTL as a mode) encoded by the link's
//! [`skein_link::LinkCommand`], and its setpoints made by the same
//! [`skein_model::safety::SetpointShaper`] (limits, geofence, separation) and, on a
//! formation slot, the same slot correction.
//!
//! - [`commands`]: commands and their procedures.
//! - [`control`]: the control step (target → shaped setpoint → the stream).

mod commands;
mod control;

use skein_link::telemetry::Change;
use skein_link::{LocalSetpoint, Telemetry};
use skein_mavlink::MavMessage;
use skein_mavlink::dialect::MavType;
use skein_mission::swarm::{SwarmSetup, VehicleSetup};
use skein_model::fsm::{Event, VehicleState, transition};
use skein_model::geo::{Ned, NedFrame};
use skein_model::geofence::Geofence;
use skein_model::safety::{MotionLimits, SetpointShaper};
use skein_sim::{SimConfig, VirtualVehicle, client};
use skein_swarm::vehicle::slot_correction::SlotCorrection;
use std::time::Duration;

pub(crate) use commands::Procedure;

/// What the stream aims at (the Vehicle actor's target).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Target {
    /// Hold a point (swarm frame).
    Hold(Ned),
    /// Track a formation slot known at `at_s` (it moves on at its velocity).
    Track {
        position: Ned,
        velocity: Ned,
        at_s: f64,
    },
}

/// One rehearsed vehicle (see the module docs).
pub(crate) struct Aircraft {
    /// Vehicle id.
    pub id: String,
    /// Carries a gimbal.
    pub observer: bool,
    sim: VirtualVehicle,
    telemetry: Telemetry,
    swarm: NedFrame,
    /// Its FSM state.
    pub state: VehicleState,
    limits: MotionLimits,
    fence: Geofence,
    separation_m: f64,
    planned_separation_m: f64,
    target: Option<Target>,
    goto_target: Option<Ned>,
    shaper: Option<SetpointShaper>,
    slot_correction: SlotCorrection,
    /// It flies a formation slot (on the transition plan).
    pub planned: bool,
    yaw_rad: f64,
    takeoff_altitude_m: f64,
    offboard_engaged: bool,
    procedure: Option<Procedure>,
    /// The setpoint the stream carries (local frame), since when.
    stream: Option<(LocalSetpoint, f64)>,
    next_heartbeat_s: f64,
    /// When the last `LOCAL_POSITION_NED` was sent, virtual seconds.
    local_at_s: f64,
    /// Battery at the start, percent: the simulator's pack starts full, the figure is
    /// moved down by the difference.
    battery_start_percent: f64,
    /// Where skein measures it (swarm frame: position, velocity) at the last step.
    pub measured: Option<(Ned, Ned)>,
    /// Where skein steers it (swarm frame: shaped position, velocity), when it does.
    pub steered: Option<(Ned, Ned)>,
}

impl std::fmt::Debug for Aircraft {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Aircraft")
            .field("id", &self.id)
            .field("state", &self.state)
            .finish_non_exhaustive()
    }
}

impl Aircraft {
    /// Vehicle `v` of `swarm` on the ground at its home, booted; `seed` seeds its
    /// simulator.
    pub fn new(v: &VehicleSetup, swarm: &SwarmSetup, seed: u64) -> Self {
        let frame = NedFrame::new(swarm.origin);
        let cfg = SimConfig {
            home: frame.to_geo(Ned::new(v.home.north_m, v.home.east_m, 0.0)),
            seed,
            params: v
                .battery_capacity_mah
                .map(|c| vec![("BAT1_CAPACITY".to_string(), c)])
                .unwrap_or_default(),
            ..SimConfig::default()
        };
        Aircraft {
            id: v.id.clone(),
            observer: v.observer,
            sim: VirtualVehicle::new(&cfg),
            telemetry: Telemetry::default(),
            swarm: frame,
            state: VehicleState::Disconnected,
            limits: v.limits,
            fence: swarm.fence.clone(),
            separation_m: swarm.setpoint_separation_m(),
            planned_separation_m: swarm.planned_separation_m(),
            target: None,
            goto_target: None,
            shaper: None,
            slot_correction: SlotCorrection::default(),
            planned: false,
            yaw_rad: 0.0,
            takeoff_altitude_m: 0.0,
            offboard_engaged: false,
            procedure: None,
            stream: None,
            next_heartbeat_s: 0.0,
            local_at_s: 0.0,
            battery_start_percent: v.battery_percent.unwrap_or(100.0).clamp(0.0, 100.0),
            measured: None,
            steered: None,
        }
    }

    /// Virtual seconds since the rehearsal began.
    pub fn time_s(&self) -> f64 {
        self.sim.time_s()
    }

    /// Ready to fly: connected, with a home (its local frame) and a position.
    pub fn ready(&self) -> bool {
        self.state != VehicleState::Disconnected
            && self.telemetry.local_frame().is_some()
            && self.measured.is_some()
    }

    /// Where it really is (swarm frame): the simulator's truth.
    pub fn truth(&self) -> Ned {
        let [n, e, d] = self.sim.true_position_ned_m();
        match self.telemetry.local_frame() {
            Some(local) => local.convert_to(&self.swarm, Ned::new(n, e, d)),
            None => Ned::new(n, e, d),
        }
    }

    /// Heading, radians clockwise from north (`ATTITUDE.yaw`; 0 before one arrived).
    pub fn heading_rad(&self) -> f64 {
        self.telemetry.attitude.map_or(0.0, |a| a.yaw_rad)
    }

    /// Height above its home, metres (`GLOBAL_POSITION_INT.relative_alt`).
    pub fn relative_alt_m(&self) -> Option<f64> {
        self.telemetry.global.map(|g| g.relative_alt_m)
    }

    /// Battery now, percent: the simulator's reading moved down by what the vehicle
    /// lacked at the start.
    pub fn battery_percent(&self) -> Option<f64> {
        let sim = self.telemetry.battery.and_then(|b| b.percent)?;
        Some((sim - (100.0 - self.battery_start_percent)).max(0.0))
    }

    /// Flies the simulated vehicle on to virtual time `until_s`, folding what it sends
    /// into the telemetry and the FSM; a ground station's heartbeat once a second.
    pub fn advance(&mut self, until_s: f64) {
        if self.sim.time_s() >= self.next_heartbeat_s {
            self.sim
                .send(&client::heartbeat(MavType::MAV_TYPE_ONBOARD_CONTROLLER));
            self.next_heartbeat_s += 1.0;
        }
        if let Some((sp, _)) = self.stream {
            let boot_ms = (self.sim.time_s() * 1000.0) as u32;
            self.sim.send(&sp.to_mavlink(boot_ms, 1, 1));
        }
        let sent = self.sim.run_until(until_s);
        let (end, end_s) = (self.sim.now(), self.sim.time_s());
        for (t, msg) in sent {
            let at = end
                .checked_sub(Duration::from_secs_f64((end_s - t).max(0.0)))
                .unwrap_or(end);
            if matches!(msg, MavMessage::LOCAL_POSITION_NED(_)) {
                self.local_at_s = t;
            }
            if let Change::Observed(o) = self.telemetry.apply(&msg, at) {
                let event = if self.state == VehicleState::Disconnected {
                    Event::Connected(o)
                } else {
                    Event::Observed(o)
                };
                self.apply(event);
            }
        }
        self.measure();
    }

    /// Applies `event` to the FSM (only commands are refused: see [`commands`]).
    fn apply(&mut self, event: Event) {
        if let Ok(next) = transition(self.state, event) {
            self.state = next;
        }
    }

    /// The swarm-frame position and velocity from `LOCAL_POSITION_NED` through the
    /// vehicle's origin, moved on by the sample's age (at most 0.2 s), as the Vehicle
    /// actor's fix.
    fn measure(&mut self) {
        let (Some(l), Some(local)) = (self.telemetry.local, self.telemetry.local_frame()) else {
            return;
        };
        let age_s = (self.sim.time_s() - self.local_at_s).clamp(0.0, 0.2);
        let to_swarm = local.transform_to(&self.swarm);
        let v = to_swarm.apply(l.velocity_m_s) - to_swarm.apply(Ned::ZERO);
        let p = to_swarm.apply(l.position + l.velocity_m_s * age_s);
        self.measured = Some((p, v));
    }

    /// The FSM's view of telemetry (armed, mode, landed), once a heartbeat arrived.
    fn observed(&self) -> Option<skein_model::fsm::Observed> {
        self.telemetry.observed()
    }
}
