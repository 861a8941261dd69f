//! The offboard setpoint stream of one vehicle.
//!
//! PX4 accepts OFFBOARD only after setpoints have streamed for more than a second, and
//! fails safe after `COM_OF_LOSS_T` (1 s) without one. The stream is therefore not part
//! of any actor's message loop: it is a task that lives with the vehicle's link handle
//! and sends the latest setpoint at a fixed rate whatever the actors are doing, so a
//! restarting actor never opens a gap. Actors only replace the setpoint.
//!
//! Every stream runs on one thread of its own (`skein-setpoints`, a tokio runtime with one
//! worker), not on the process's worker threads: a handler that keeps a worker busy (a
//! plugin call, a large JSON body, a debug build's image processing) or a starved worker
//! queue cannot delay a setpoint. The thread mostly sleeps, so the kernel wakes it
//! promptly even when every core is busy. Sending never blocks (`try_send_to`).
//!
//! A setpoint not refreshed for [`STALE_AFTER`] loses its velocity feed-forward: the
//! vehicle holds the last position instead of flying on along a stale velocity while its
//! owner is away.

use crate::endpoint::Endpoint;
use serde::Serialize;
use skein_mavlink::MavMessage;
use skein_mavlink::dialect::{
    MavFrame, PositionTargetTypemask, SET_POSITION_TARGET_LOCAL_NED_DATA,
};
use skein_model::geo::Ned;
use skein_model::px4::type_mask;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};
use tokio::runtime::Runtime;
use tokio::sync::watch;
use tokio::task::JoinHandle;

/// A setpoint in the vehicle's own local NED frame, as `SET_POSITION_TARGET_LOCAL_NED`
/// carries it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LocalSetpoint {
    /// Position, local NED metres (ignored if `type_mask` says so).
    pub position: Ned,
    /// Velocity, NED m/s (feed-forward with a position, or the command alone).
    pub velocity: Ned,
    /// Acceleration feed-forward, NED m/s² (sent only when `type_mask` asks for it).
    pub acceleration: Ned,
    /// Yaw, radians clockwise from north.
    pub yaw_rad: f64,
    /// Yaw rate, rad/s.
    pub yaw_rate_rad_s: f64,
    /// `POSITION_TARGET_TYPEMASK` bits (see [`skein_model::px4::type_mask`]).
    pub type_mask: u16,
}

impl LocalSetpoint {
    /// Position + yaw (`type_mask` 2552).
    pub fn position(position: Ned, yaw_rad: f64) -> Self {
        LocalSetpoint {
            position,
            velocity: Ned::ZERO,
            acceleration: Ned::ZERO,
            yaw_rad,
            yaw_rate_rad_s: 0.0,
            type_mask: type_mask::POSITION_YAW,
        }
    }

    /// Position + velocity feed-forward + yaw (`type_mask` 2496).
    pub fn position_velocity(position: Ned, velocity: Ned, yaw_rad: f64) -> Self {
        LocalSetpoint {
            position,
            velocity,
            acceleration: Ned::ZERO,
            yaw_rad,
            yaw_rate_rad_s: 0.0,
            type_mask: type_mask::POSITION_VELOCITY_YAW,
        }
    }

    /// Position + velocity and acceleration feed-forward + yaw (`type_mask` 2048).
    pub fn position_velocity_acceleration(
        position: Ned,
        velocity: Ned,
        acceleration: Ned,
        yaw_rad: f64,
    ) -> Self {
        LocalSetpoint {
            position,
            velocity,
            acceleration,
            yaw_rad,
            yaw_rate_rad_s: 0.0,
            type_mask: type_mask::POSITION_VELOCITY_ACCELERATION_YAW,
        }
    }

    /// Velocity + yaw rate (`type_mask` 1479).
    pub fn velocity(velocity: Ned, yaw_rate_rad_s: f64) -> Self {
        LocalSetpoint {
            position: Ned::ZERO,
            velocity,
            acceleration: Ned::ZERO,
            yaw_rad: 0.0,
            yaw_rate_rad_s,
            type_mask: type_mask::VELOCITY_YAW_RATE,
        }
    }

    /// The same setpoint as a pure position hold (velocity feed-forward dropped); a
    /// velocity-only setpoint becomes "stop" (zero velocity).
    pub fn as_hold(&self) -> Self {
        if self.type_mask & type_mask::IGNORE_POSITION == type_mask::IGNORE_POSITION {
            LocalSetpoint::velocity(Ned::ZERO, 0.0)
        } else {
            LocalSetpoint::position(self.position, self.yaw_rad)
        }
    }

    fn to_mavlink(self, time_boot_ms: u32, target_system: u8, target_component: u8) -> MavMessage {
        MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
            time_boot_ms,
            x: self.position.north_m as f32,
            y: self.position.east_m as f32,
            z: self.position.down_m as f32,
            vx: self.velocity.north_m as f32,
            vy: self.velocity.east_m as f32,
            vz: self.velocity.down_m as f32,
            afx: self.acceleration.north_m as f32,
            afy: self.acceleration.east_m as f32,
            afz: self.acceleration.down_m as f32,
            yaw: self.yaw_rad as f32,
            yaw_rate: self.yaw_rate_rad_s as f32,
            type_mask: PositionTargetTypemask::from_bits_truncate(self.type_mask),
            target_system,
            target_component,
            coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
        })
    }
}

/// A setpoint older than this is streamed as a pure hold (see module docs).
pub const STALE_AFTER: Duration = Duration::from_millis(500);

/// Counters of one stream.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct StreamCounts {
    /// Setpoints sent.
    pub sent: u64,
    /// Sends that failed (socket full, no address).
    pub send_errors: u64,
    /// Largest interval between two consecutive sends while streaming, ms.
    pub max_gap_ms: f64,
    /// Times a stale setpoint was downgraded to a hold.
    pub stale_holds: u64,
}

#[derive(Default)]
struct Counters {
    sent: AtomicU64,
    send_errors: AtomicU64,
    max_gap_us: AtomicU64,
    stale_holds: AtomicU64,
}

#[derive(Clone, Copy)]
struct Current {
    setpoint: Option<LocalSetpoint>,
    updated: Instant,
}

/// A running setpoint stream (see module docs). Dropping it stops the task.
pub struct SetpointStream {
    tx: watch::Sender<Current>,
    counters: Arc<Counters>,
    since: Arc<Mutex<Option<Instant>>>,
    rate_hz: f64,
    task: JoinHandle<()>,
}

impl Drop for SetpointStream {
    fn drop(&mut self) {
        self.task.abort();
    }
}

impl SetpointStream {
    /// Starts streaming to `sysid`/`compid` through `endpoint` at `rate_hz` (PX4 needs
    /// more than 2 Hz; 20–50 Hz is usual). Nothing is sent until [`SetpointStream::set`]
    /// gives a setpoint.
    pub fn start(endpoint: Arc<Endpoint>, sysid: u8, compid: u8, rate_hz: f64) -> Self {
        let (tx, rx) = watch::channel(Current {
            setpoint: None,
            updated: Instant::now(),
        });
        let counters = Arc::new(Counters::default());
        let since = Arc::new(Mutex::new(None));
        let task = stream_runtime().spawn(run(
            endpoint,
            sysid,
            compid,
            rate_hz,
            rx,
            counters.clone(),
            since.clone(),
        ));
        SetpointStream {
            tx,
            counters,
            since,
            rate_hz,
            task,
        }
    }

    /// Replaces the streamed setpoint; `None` stops streaming (only after PX4 has been
    /// switched out of OFFBOARD).
    pub fn set(&self, setpoint: Option<LocalSetpoint>) {
        self.tx.send_replace(Current {
            setpoint,
            updated: Instant::now(),
        });
    }

    /// The setpoint being streamed.
    pub fn current(&self) -> Option<LocalSetpoint> {
        self.tx.borrow().setpoint
    }

    /// Since when setpoints have been streaming without interruption (`None` if stopped).
    pub fn streaming_since(&self) -> Option<Instant> {
        *self.since.lock().expect("since lock")
    }

    /// The stream rate, Hz.
    pub fn rate_hz(&self) -> f64 {
        self.rate_hz
    }

    /// Counters.
    pub fn counts(&self) -> StreamCounts {
        StreamCounts {
            sent: self.counters.sent.load(Ordering::Relaxed),
            send_errors: self.counters.send_errors.load(Ordering::Relaxed),
            max_gap_ms: self.counters.max_gap_us.load(Ordering::Relaxed) as f64 / 1000.0,
            stale_holds: self.counters.stale_holds.load(Ordering::Relaxed),
        }
    }
}

/// The runtime of every setpoint stream (see the module docs): one worker thread,
/// started on first use, kept for the life of the process.
///
/// # Panics
/// When the OS refuses a thread (nothing could fly then).
fn stream_runtime() -> &'static Runtime {
    static RUNTIME: OnceLock<Runtime> = OnceLock::new();
    RUNTIME.get_or_init(|| {
        tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("skein-setpoints")
            .enable_time()
            .build()
            .expect("the setpoint stream thread")
    })
}

async fn run(
    endpoint: Arc<Endpoint>,
    sysid: u8,
    compid: u8,
    rate_hz: f64,
    mut rx: watch::Receiver<Current>,
    counters: Arc<Counters>,
    since: Arc<Mutex<Option<Instant>>>,
) {
    let period = Duration::from_secs_f64(1.0 / rate_hz.max(1.0));
    let mut ticker = tokio::time::interval(period);
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let start = Instant::now();
    let mut last_sent: Option<Instant> = None;
    loop {
        tokio::select! {
            _ = ticker.tick() => {}
            changed = rx.changed() => {
                if changed.is_err() { return; }
                // A new setpoint after a pause starts streaming at once; otherwise keep
                // the fixed rate.
                if last_sent.is_some() { continue; }
            }
        }
        let current = *rx.borrow_and_update();
        let Some(mut sp) = current.setpoint else {
            last_sent = None;
            *since.lock().expect("since lock") = None;
            continue;
        };
        let now = Instant::now();
        if now.duration_since(current.updated) > STALE_AFTER {
            let hold = sp.as_hold();
            if hold != sp {
                counters.stale_holds.fetch_add(1, Ordering::Relaxed);
                sp = hold;
            }
        }
        let msg = sp.to_mavlink(now.duration_since(start).as_millis() as u32, sysid, compid);
        match endpoint.send(sysid, &msg) {
            Ok(()) => {
                counters.sent.fetch_add(1, Ordering::Relaxed);
                if let Some(prev) = last_sent {
                    let gap = now.duration_since(prev).as_micros() as u64;
                    counters.max_gap_us.fetch_max(gap, Ordering::Relaxed);
                } else {
                    *since.lock().expect("since lock") = Some(now);
                }
                last_sent = Some(now);
            }
            Err(_) => {
                counters.send_errors.fetch_add(1, Ordering::Relaxed);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hold_drops_feed_forward() {
        let sp = LocalSetpoint::position_velocity(
            Ned::new(1.0, 2.0, -3.0),
            Ned::new(4.0, 0.0, 0.0),
            0.5,
        );
        let h = sp.as_hold();
        assert_eq!(h.type_mask, type_mask::POSITION_YAW);
        assert_eq!(h.position, sp.position);
        assert_eq!(h.velocity, Ned::ZERO);
        let v = LocalSetpoint::velocity(Ned::new(3.0, 0.0, 0.0), 0.1).as_hold();
        assert_eq!(v.velocity, Ned::ZERO);
        assert_eq!(v.type_mask, type_mask::VELOCITY_YAW_RATE);
    }
}
