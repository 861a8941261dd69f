//! The simulated vehicle's test harness: one vehicle stepped at 100 Hz on a synthetic
//! clock, fed a client's messages, what it sends decoded.

use super::*;
use crate::client;
use crate::config::{PX4_SITL_HOME, TelemetryProfile};
use skein_mavlink::Decoder;

/// The environment of a test vehicle: `wind`, GPS noise, `seed`; the swarm telemetry
/// profile, an immediate EKF fix, no parameters.
pub(super) fn env(wind: WindConfig, gps_noise_m: f64, seed: u64) -> Environment {
    Environment {
        wind,
        gps_noise_m,
        ekf_fix_delay: Duration::ZERO,
        params: Vec::new(),
        seed,
        profile: TelemetryProfile::Swarm,
        offboard_min_stream: Duration::ZERO,
        estimator_noise: false,
        rtk: gnss::RtkTiming::default(),
        gnss_wander: false,
    }
}

/// A vehicle driven on a synthetic clock (100 Hz steps), with a MAVLink client.
pub(super) struct Harness {
    pub(super) v: Vehicle,
    enc: Encoder,
    buf: Vec<u8>,
    pub(super) now: Instant,
}

impl Harness {
    pub(super) fn new(env: Environment) -> Harness {
        let now = Instant::now();
        Harness {
            v: Vehicle::new(1, PX4_SITL_HOME, env, now),
            enc: Encoder::new(1, 1),
            buf: Vec::new(),
            now,
        }
    }

    /// Steps the vehicle for `secs`; returns what it sent meanwhile.
    pub(super) fn run(&mut self, secs: f64) -> Vec<MavMessage> {
        let mut all = Vec::new();
        for _ in 0..(secs * 100.0).round() as usize {
            self.now += Duration::from_millis(10);
            let mut out = Outbox {
                enc: &mut self.enc,
                buf: &mut self.buf,
                frames: 0,
            };
            self.v.step(self.now, 0.01, &mut out);
            all.extend(self.sent());
        }
        all
    }

    /// What the vehicle sent since the last call.
    fn sent(&mut self) -> Vec<MavMessage> {
        let mut msgs = Vec::new();
        Decoder::default().decode_datagram(&self.buf, |f| msgs.push(f.msg));
        self.buf.clear();
        msgs
    }

    /// Feeds one message from a client (sysid 245); returns what the vehicle answered.
    pub(super) fn input(&mut self, msg: MavMessage) -> Vec<MavMessage> {
        let frame = Frame {
            sysid: 245,
            compid: 190,
            seq: 0,
            version: 2,
            msg,
        };
        let mut out = Outbox {
            enc: &mut self.enc,
            buf: &mut self.buf,
            frames: 0,
        };
        self.v.handle_frame(self.now, &frame, &mut out);
        self.sent()
    }

    /// Sends a command; returns the COMMAND_ACK results it caused.
    pub(super) fn command(&mut self, command: MavCmd, p: [f32; 7]) -> Vec<MavResult> {
        self.input(client::command(command, p))
            .into_iter()
            .filter_map(|m| match m {
                MavMessage::COMMAND_ACK(a) => Some(a.result),
                _ => None,
            })
            .collect()
    }

    pub(super) fn setpoint(&mut self, mask: u16, pos: [f32; 3], vel: [f32; 3]) {
        let ned = |v: [f32; 3]| Ned::new(v[0].into(), v[1].into(), v[2].into());
        self.input(client::setpoint(mask, ned(pos), ned(vel), Ned::ZERO, 0.0));
    }

    pub(super) fn takeoff(&mut self) {
        self.run(0.1);
        let nan = f32::NAN;
        let r = self.command(
            MavCmd::MAV_CMD_NAV_TAKEOFF,
            [0.0, 0.0, 0.0, nan, nan, nan, nan],
        );
        assert_eq!(r, vec![MavResult::MAV_RESULT_ACCEPTED]);
        let r = self.command(
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        );
        assert_eq!(r, vec![MavResult::MAV_RESULT_ACCEPTED]);
        self.run(10.0);
        assert_eq!(self.v.mode, Px4Mode::Hold, "takeoff did not complete");
    }

    /// Streams `sp` at 20 Hz for `secs`.
    pub(super) fn stream(&mut self, secs: f64, mask: u16, pos: [f32; 3], vel: [f32; 3]) {
        for _ in 0..(secs * 20.0).round() as usize {
            self.setpoint(mask, pos, vel);
            self.run(0.05);
        }
    }
}
