//! [`VirtualClient`]: a ground station on a [`VirtualVehicle`], on the vehicle's virtual
//! clock. Waiting steps the simulation instead of sleeping, so a minute of flight takes
//! milliseconds and every timer (PX4's offboard loss, heartbeat timeouts, auto-disarm) is
//! measured exactly; the vehicle runs the same message handling, flight logic and
//! telemetry as a simulator's vehicle behind its UDP socket.

use super::station::GroundStation;
use skein_mavlink::{Frame, MavMessage};
use skein_sim::{SimConfig, VirtualVehicle};
use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// A setpoint stream sent from inside the virtual clock's steps.
struct Stream {
    period: Duration,
    next_due: Instant,
    started: Instant,
    setpoint: Box<dyn FnMut(f64) -> MavMessage>,
}

/// A ground station on a virtual vehicle (sysid 1).
pub struct VirtualClient {
    /// The vehicle: its truth and counters.
    pub vehicle: VirtualVehicle,
    queue: VecDeque<Frame>,
    stream: Option<Stream>,
}

/// A virtual vehicle configured as [`super::start`] configures the simulator's (EKF fix
/// after 0.2 s), then by `tweak`.
pub fn start_virtual(tweak: impl FnOnce(&mut SimConfig)) -> VirtualClient {
    let mut cfg = SimConfig::with_vehicles(Vec::new());
    cfg.ekf_fix_delay_s = 0.2;
    tweak(&mut cfg);
    VirtualClient {
        vehicle: VirtualVehicle::new(&cfg),
        queue: VecDeque::new(),
        stream: None,
    }
}

impl VirtualClient {
    /// One tick of the virtual clock: the stream's setpoint when due, then the vehicle's
    /// step; everything the vehicle sends is queued for [`GroundStation::next`].
    pub fn step(&mut self) {
        let now = self.vehicle.now();
        if let Some(s) = &mut self.stream
            && now >= s.next_due
        {
            let msg = (s.setpoint)(now.duration_since(s.started).as_secs_f64());
            s.next_due += s.period;
            let answers = self.vehicle.send_frames(&msg);
            self.queue.extend(answers);
        }
        let sent = self.vehicle.step_frames();
        self.queue.extend(sent);
    }

    /// Lets `duration` of virtual time pass (frames sent meanwhile stay queued).
    pub fn run_for(&mut self, duration: Duration) {
        let end = self.vehicle.now() + duration;
        while self.vehicle.now() < end {
            self.step();
        }
    }

    /// Steps until `cond` holds, at most `timeout` of virtual time; true if it held.
    pub fn run_until(
        &mut self,
        timeout: Duration,
        mut cond: impl FnMut(&VirtualVehicle) -> bool,
    ) -> bool {
        let end = self.vehicle.now() + timeout;
        while !cond(&self.vehicle) {
            if self.vehicle.now() >= end {
                return false;
            }
            self.step();
        }
        true
    }

    /// Drops the frames received so far.
    pub fn clear(&mut self) {
        self.queue.clear();
    }

    /// Streams `setpoint(seconds since the stream started)` at `rate_hz`, from the next
    /// step on, replacing any stream.
    pub fn stream_fn(&mut self, rate_hz: f64, setpoint: impl FnMut(f64) -> MavMessage + 'static) {
        let now = self.vehicle.now();
        self.stream = Some(Stream {
            period: Duration::from_secs_f64(1.0 / rate_hz),
            next_due: now,
            started: now,
            setpoint: Box::new(setpoint),
        });
    }

    /// Streams `msg` at `rate_hz` (see [`VirtualClient::stream_fn`]).
    pub fn stream(&mut self, msg: MavMessage, rate_hz: f64) {
        self.stream_fn(rate_hz, move |_| msg.clone());
    }

    /// Stops the stream.
    pub fn stop_stream(&mut self) {
        self.stream = None;
    }

    /// Virtual time since the stream started (zero without a stream).
    pub fn stream_age(&self) -> Duration {
        self.stream.as_ref().map_or(Duration::ZERO, |s| {
            self.vehicle.now().duration_since(s.started)
        })
    }
}

impl GroundStation for VirtualClient {
    fn sysid(&self) -> u8 {
        1
    }

    fn now(&self) -> Instant {
        self.vehicle.now()
    }

    async fn send(&mut self, msg: &MavMessage) {
        let answers = self.vehicle.send_frames(msg);
        self.queue.extend(answers);
    }

    async fn next(&mut self, deadline: Instant) -> Option<Frame> {
        loop {
            if let Some(f) = self.queue.pop_front() {
                return Some(f);
            }
            if self.vehicle.now() >= deadline {
                return None;
            }
            self.step();
        }
    }
}
