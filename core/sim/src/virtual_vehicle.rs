//! One simulated vehicle on a virtual clock, without sockets: MAVLink messages go in
//! through the vehicle's own message handling and everything it sends (telemetry at the
//! profile's rates, ACKs, STATUSTEXT) comes out decoded, time-stamped on the virtual
//! clock. A minute of flight runs in milliseconds, deterministically; the simulator's
//! flight and protocol tests, the trace-replay test (PX4 v1.16 recordings against the
//! simulator), the swarm's rehearsals and offline studies of the flight model use it.

use crate::client;
use crate::config::{SimConfig, TelemetryProfile};
use crate::report::{SimTruth, truth_of};
use crate::vehicle::{Environment, FlightLog, Outbox, Vehicle};
use skein_mavlink::dialect::{MavCmd, MavMissionResult};
use skein_mavlink::{Decoder, Encoder, Frame, MavMessage};
use skein_model::geo::Ned;
use std::time::{Duration, Instant};

/// The system id [`VirtualVehicle::send`] speaks as (a ground station's).
pub const GCS_SYSID: u8 = 255;
/// The component id [`VirtualVehicle::send`] speaks as (`MAV_COMP_ID_MISSIONPLANNER`).
pub const GCS_COMPID: u8 = 190;

/// What a virtual vehicle has counted and knows of its peers: the protocol part of
/// [`crate::SimVehicleStats`] (a virtual vehicle has no socket to count).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct VirtualStats {
    /// SET_POSITION_TARGET_LOCAL_NED messages received.
    pub setpoints_received: u64,
    /// Offboard-loss failsafes taken (`COM_OF_LOSS_T` without a setpoint).
    pub offboard_loss_failsafes: u64,
    /// Commands (COMMAND_LONG / COMMAND_INT) received.
    pub commands_received: u64,
    /// A MAV_TYPE_GCS heartbeat arrived within PX4's heartbeat timeout (1.5 s).
    pub gcs_connected: bool,
    /// A MAV_TYPE_ONBOARD_CONTROLLER heartbeat arrived within the timeout.
    pub onboard_controller_connected: bool,
    /// Geofence breaches that took `GF_ACTION`.
    pub geofence_breaches: u64,
    /// The RTK corrections' path to the GNSS receiver (GPS_RTCM_DATA, RTCM3 frames).
    pub rtcm: crate::RtcmCounts,
}

/// A simulated vehicle (sysid 1) driven by a virtual clock.
pub struct VirtualVehicle {
    vehicle: Vehicle,
    encoder: Encoder,
    client: Encoder,
    decoder: Decoder,
    buf: Vec<u8>,
    start: Instant,
    now: Instant,
    tick: Duration,
}

impl VirtualVehicle {
    /// A freshly booted vehicle with `cfg`'s environment (wind, GPS and estimator noise,
    /// the GNSS receiver's RTK timing and wander, seed, parameters, telemetry profile), stepped at the profile's tick rate (100 Hz
    /// for PX4's onboard profile). Its clock starts at 0 s.
    pub fn new(cfg: &SimConfig) -> VirtualVehicle {
        let env = Environment::of(cfg);
        let start = Instant::now();
        let tick_hz = match cfg.telemetry {
            TelemetryProfile::Px4Onboard => TelemetryProfile::Px4Onboard.tick_rate_hz(),
            TelemetryProfile::Swarm => TelemetryProfile::Swarm.tick_rate_hz(),
        };
        VirtualVehicle {
            vehicle: Vehicle::new(1, cfg.home, env, start),
            encoder: Encoder::new(1, 1),
            client: Encoder::new(GCS_SYSID, GCS_COMPID),
            decoder: Decoder::default(),
            buf: Vec::with_capacity(4096),
            start,
            now: start,
            tick: Duration::from_secs_f64(1.0 / tick_hz),
        }
    }

    /// Virtual seconds since boot.
    pub fn time_s(&self) -> f64 {
        self.now.duration_since(self.start).as_secs_f64()
    }

    /// The virtual clock as an `Instant` (it starts at the real time of
    /// [`VirtualVehicle::new`] and advances only with [`VirtualVehicle::step`]): deadlines
    /// on the virtual clock are `now() + timeout`.
    pub fn now(&self) -> Instant {
        self.now
    }

    /// The simulation step, s.
    pub fn tick_s(&self) -> f64 {
        self.tick.as_secs_f64()
    }

    /// The frames sent since the last drain, decoded.
    fn drain(&mut self) -> Vec<Frame> {
        let mut frames = Vec::new();
        self.decoder.decode_datagram(&self.buf, |f| frames.push(f));
        self.buf.clear();
        frames
    }

    /// `frames` time-stamped with the virtual time now.
    fn stamped(&self, frames: Vec<Frame>) -> Vec<(f64, MavMessage)> {
        let t = self.time_s();
        frames.into_iter().map(|f| (t, f.msg)).collect()
    }

    /// Delivers `msg` (as if sent by a ground station, [`GCS_SYSID`] / [`GCS_COMPID`]) at
    /// the current virtual time; returns what the vehicle answered at once.
    pub fn send(&mut self, msg: &MavMessage) -> Vec<(f64, MavMessage)> {
        let frames = self.send_frames(msg);
        self.stamped(frames)
    }

    /// [`VirtualVehicle::send`], the answers as the frames they were (sysid, compid,
    /// sequence number).
    pub fn send_frames(&mut self, msg: &MavMessage) -> Vec<Frame> {
        let mut wire = Vec::with_capacity(64);
        self.client.encode_into(msg, &mut wire);
        let mut frames = Vec::new();
        Decoder::default().decode_datagram(&wire, |f| frames.push(f));
        {
            let mut out = Outbox {
                enc: &mut self.encoder,
                buf: &mut self.buf,
                frames: 0,
            };
            for f in &frames {
                self.vehicle.handle_frame(self.now, f, &mut out);
            }
        }
        self.drain()
    }

    /// Advances one tick: physics, then the telemetry that is due; returns what the
    /// vehicle sent, time-stamped.
    pub fn step(&mut self) -> Vec<(f64, MavMessage)> {
        let frames = self.step_frames();
        self.stamped(frames)
    }

    /// [`VirtualVehicle::step`], what was sent as the frames it was.
    pub fn step_frames(&mut self) -> Vec<Frame> {
        self.now += self.tick;
        {
            let mut out = Outbox {
                enc: &mut self.encoder,
                buf: &mut self.buf,
                frames: 0,
            };
            let dt = self.tick.as_secs_f64();
            self.vehicle.step(self.now, dt, &mut out);
            self.vehicle.emit_due_streams(self.now, &mut out);
        }
        self.drain()
    }

    /// Runs until virtual time `t_s`; returns everything sent.
    pub fn run_until(&mut self, t_s: f64) -> Vec<(f64, MavMessage)> {
        let mut all = Vec::new();
        while self.time_s() + 1e-9 < t_s {
            all.extend(self.step());
        }
        all
    }

    /// Ground truth now, as [`crate::Simulator::truth`] gives it for a simulator's vehicle.
    pub fn truth(&self) -> SimTruth {
        truth_of(&self.vehicle, self.now)
    }

    /// The vehicle's counters and peers now.
    pub fn stats(&self) -> VirtualStats {
        let v = &self.vehicle;
        VirtualStats {
            setpoints_received: v.counters.setpoints_received,
            offboard_loss_failsafes: v.counters.offboard_loss_failsafes,
            commands_received: v.counters.commands_received,
            gcs_connected: v.gcs_connected(self.now),
            onboard_controller_connected: v.onboard_controller_connected(self.now),
            geofence_breaches: v.counters.geofence_breaches,
            rtcm: v.counters.rtcm,
        }
    }

    /// Makes every fence and rally upload end in `fault` (see
    /// [`crate::Simulator::set_mission_fault`]); `None` clears it.
    pub fn set_mission_fault(&mut self, fault: Option<MavMissionResult>) {
        self.vehicle.missions.fault = fault;
    }

    /// Ground truth: local NED position, m.
    pub fn true_position_ned_m(&self) -> [f64; 3] {
        let p = self.vehicle.pos;
        [p.north_m, p.east_m, p.down_m]
    }

    /// True while armed.
    pub fn armed(&self) -> bool {
        self.vehicle.armed
    }

    /// The vehicle's flight logs, as [`crate::Simulator::flight_logs`] gives them.
    pub fn flight_logs(&self) -> Vec<FlightLog> {
        self.vehicle.flight_logs.list()
    }

    /// Reboots the vehicle now, as [`crate::Simulator::reboot`] does (its flight logs
    /// stay).
    pub fn reboot(&mut self) {
        self.vehicle.reboot(self.now);
        self.encoder = Encoder::new(1, 1);
    }
}

impl VirtualVehicle {
    /// Boots, arms and takes off in OFFBOARD to `altitude_m` above where it stands, as a
    /// ground station would (GCS heartbeat each second, a hold setpoint at 50 Hz), for
    /// `settle_s` seconds; true when it is armed and its estimate (what LOCAL_POSITION_NED
    /// reports, and what PX4 controls) is within 0.5 m of the hold point. The truth may
    /// sit further off by the estimator's error when the estimator noise is on.
    pub fn take_off_offboard(&mut self, altitude_m: f64, settle_s: f64) -> bool {
        let hold = Ned::new(0.0, 0.0, -altitude_m);
        let sp = client::setpoint(client::POSITION_YAW, hold, Ned::ZERO, Ned::ZERO, 0.0);
        self.send(&client::gcs_heartbeat());
        self.run_until(self.time_s() + 1.5);
        self.send(&sp);
        self.send(&client::command(
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        ));
        self.send(&client::command(
            MavCmd::MAV_CMD_DO_SET_MODE,
            [1.0, 6.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        ));
        let end = self.time_s() + settle_s;
        let (mut next_sp, mut next_hb) = (self.time_s(), self.time_s() + 1.0);
        while self.time_s() < end {
            if self.time_s() >= next_sp {
                self.send(&sp);
                next_sp += 0.02;
            }
            if self.time_s() >= next_hb {
                self.send(&client::gcs_heartbeat());
                next_hb += 1.0;
            }
            self.step();
        }
        self.armed() && (self.vehicle.est_pos() - hold).norm() < 0.5
    }
}
