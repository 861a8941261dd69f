//! One simulated vehicle on a virtual clock, without sockets: MAVLink messages go in
//! through the vehicle's own message handling and everything it sends (telemetry at the
//! profile's rates, ACKs, STATUSTEXT) comes out decoded, time-stamped on the virtual
//! clock. A minute of flight runs in milliseconds, deterministically; the trace-replay
//! test (PX4 v1.16 recordings against the simulator) and offline studies of the flight
//! model use it.

use crate::config::{SimConfig, TelemetryProfile};
use crate::vehicle::{Environment, Outbox, Vehicle};
use skein_mavlink::{Decoder, Encoder, Frame, MavMessage};
use std::time::{Duration, Instant};

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
    /// seed, parameters, telemetry profile), stepped at the profile's tick rate (100 Hz
    /// for PX4's onboard profile). Its clock starts at 0 s.
    pub fn new(cfg: &SimConfig) -> VirtualVehicle {
        let env = Environment {
            wind: cfg.wind,
            gps_noise_m: cfg.gps_noise_m.max(0.0),
            ekf_fix_delay: Duration::from_secs_f64(cfg.ekf_fix_delay_s.max(0.0)),
            params: cfg.params.clone(),
            seed: cfg.seed,
            profile: cfg.telemetry,
            offboard_min_stream: Duration::from_secs_f64(cfg.offboard_min_stream_s.max(0.0)),
            estimator_noise: cfg.estimator_noise,
        };
        let start = Instant::now();
        let tick_hz = match cfg.telemetry {
            TelemetryProfile::Px4Onboard => TelemetryProfile::Px4Onboard.tick_rate_hz(),
            TelemetryProfile::Swarm => TelemetryProfile::Swarm.tick_rate_hz(),
        };
        VirtualVehicle {
            vehicle: Vehicle::new(1, cfg.home, env, start),
            encoder: Encoder::new(1, 1),
            client: Encoder::new(255, 190),
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

    /// The simulation step, s.
    pub fn tick_s(&self) -> f64 {
        self.tick.as_secs_f64()
    }

    fn drain(&mut self, out: &mut Vec<(f64, MavMessage)>) {
        let t = self.time_s();
        let buf = std::mem::take(&mut self.buf);
        self.decoder
            .decode_datagram(&buf, |f: Frame| out.push((t, f.msg)));
        self.buf = buf;
        self.buf.clear();
    }

    /// Delivers `msg` (as if sent by a ground station, sysid 255 / compid 190) at the
    /// current virtual time; returns what the vehicle answered at once.
    pub fn send(&mut self, msg: &MavMessage) -> Vec<(f64, MavMessage)> {
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
        let mut answers = Vec::new();
        self.drain(&mut answers);
        answers
    }

    /// Advances one tick: physics, then the telemetry that is due; returns what the
    /// vehicle sent, time-stamped.
    pub fn step(&mut self) -> Vec<(f64, MavMessage)> {
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
        let mut sent = Vec::new();
        self.drain(&mut sent);
        sent
    }

    /// Runs until virtual time `t_s`; returns everything sent.
    pub fn run_until(&mut self, t_s: f64) -> Vec<(f64, MavMessage)> {
        let mut all = Vec::new();
        while self.time_s() + 1e-9 < t_s {
            all.extend(self.step());
        }
        all
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
}
