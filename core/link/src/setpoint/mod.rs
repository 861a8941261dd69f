//! The offboard setpoint stream of one vehicle.
//!
//! PX4 accepts OFFBOARD only after setpoints have streamed for more than a second, and
//! fails safe after `COM_OF_LOSS_T` (1 s) without one. The stream is therefore not part
//! of any actor's message loop: it lives with the vehicle's link handle and the latest
//! setpoint is sent at a fixed rate whatever the actors are doing, so a restarting actor
//! never opens a gap. Actors only replace the setpoint.
//!
//! Every stream is sent from one thread of its own (`skein-setpoints`, a tokio runtime
//! with one worker), not from the process's worker threads (on a byte stream, `tcpout:`
//! or `serial:`, it hands the frame to the endpoint's writer thread, which is not one of
//! them either: `crate::endpoint::stream`): a handler that keeps a worker
//! busy (a plugin call, a large JSON body, a debug build's image processing) or a starved
//! worker queue cannot delay a setpoint. The thread mostly sleeps, so the kernel wakes it
//! promptly even when every core is busy, and it asks for a higher priority than the
//! process's other threads ([`crate::priority`]). Sending never blocks: the socket is
//! non-blocking, and the thread never waits for a lock another thread may hold (a starved
//! process can be descheduled anywhere). That includes the allocator's: glibc's malloc
//! locks an arena that several threads share, and a starved thread descheduled inside
//! `malloc` keeps that lock for as long as it waits for its CPU, so once its streams run
//! the thread allocates nothing (its buffers keep their capacity from tick to tick; a
//! unit test counts its allocations).
//!
//! All streams of one rate share one clock on that thread: every quarter period it sends
//! the setpoints of a quarter of the streams. A thousand vehicles at 50 Hz cost 200 timer
//! wake-ups a second, not 50 000, and the datagrams leave in four small bursts a period.
//!
//! A setpoint not refreshed for [`STALE_AFTER`] loses its velocity feed-forward: the
//! vehicle holds the last position instead of flying on along a stale velocity while its
//! owner is away.

use crate::endpoint::{Endpoint, Outgoing, Peer};
use serde::Serialize;
use skein_mavlink::MavMessage;
use skein_mavlink::dialect::{
    MavFrame, PositionTargetTypemask, SET_POSITION_TARGET_LOCAL_NED_DATA,
};
use skein_model::geo::Ned;
use skein_model::px4::type_mask;
use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock, Weak};
use std::time::{Duration, Instant};
use tokio::runtime::Runtime;

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

    /// The `SET_POSITION_TARGET_LOCAL_NED` (`MAV_FRAME_LOCAL_NED`) carrying this setpoint
    /// to `target_system`/`target_component`, stamped `time_boot_ms`: what the stream
    /// sends (and what a rehearsal sends a simulated vehicle).
    pub fn to_mavlink(
        self,
        time_boot_ms: u32,
        target_system: u8,
        target_component: u8,
    ) -> MavMessage {
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

/// What the owner of one stream wants sent, and since when.
#[derive(Clone, Copy)]
struct Current {
    setpoint: Option<LocalSetpoint>,
    /// When the owner last replaced the setpoint.
    updated: Instant,
}

/// One vehicle's stream as its clock sees it.
///
/// The owner (a vehicle's control loop, on a worker thread) and the clock (on the
/// setpoint thread) share only `current`, and the clock never waits for it: if the owner
/// holds it at the instant of a send (a starved process may deschedule a thread anywhere),
/// the clock sends its own copy of what it sent last.
struct Stream {
    endpoint: Arc<Endpoint>,
    /// The endpoint's record of `sysid` (its address), kept rather than looked up at
    /// every send.
    peer: Arc<Peer>,
    sysid: u8,
    compid: u8,
    /// `time_boot_ms` and the instants below count from here.
    start: Instant,
    current: Mutex<Current>,
    /// The last successful send of this streaming run, µs since `start` + 1 (0: stopped).
    last_sent_us: AtomicU64,
    /// Since when setpoints have streamed without interruption, µs since `start` + 1.
    since_us: AtomicU64,
    counters: Counters,
}

impl Stream {
    fn stamp(&self, t: Instant) -> u64 {
        t.duration_since(self.start).as_micros() as u64 + 1
    }

    fn instant(&self, stamp: u64) -> Option<Instant> {
        (stamp != 0).then(|| self.start + Duration::from_micros(stamp - 1))
    }

    /// The frame that sends `current` at `now` (`None`, and the run ends, when it holds no
    /// setpoint; `None` too when it has nowhere to go, counted as a send error).
    fn prepare(&self, current: Current, now: Instant) -> Option<Outgoing> {
        let Some(mut sp) = current.setpoint else {
            self.last_sent_us.store(0, Ordering::Relaxed);
            self.since_us.store(0, Ordering::Relaxed);
            return None;
        };
        if now.duration_since(current.updated) > STALE_AFTER {
            let hold = sp.as_hold();
            if hold != sp {
                self.counters.stale_holds.fetch_add(1, Ordering::Relaxed);
                sp = hold;
            }
        }
        let time_boot_ms = now.duration_since(self.start).as_millis() as u32;
        let msg = sp.to_mavlink(time_boot_ms, self.sysid, self.compid);
        match self.endpoint.prepare(Some(&self.peer), self.sysid, &msg) {
            Ok(out) => Some(out),
            Err(_) => {
                self.counters.send_errors.fetch_add(1, Ordering::Relaxed);
                None
            }
        }
    }

    /// Counts the outcome of the frame [`Stream::prepare`] made at `now`.
    fn sent(&self, ok: bool, now: Instant) {
        if !ok {
            self.counters.send_errors.fetch_add(1, Ordering::Relaxed);
            return;
        }
        self.counters.sent.fetch_add(1, Ordering::Relaxed);
        let stamp = self.stamp(now);
        match self.last_sent_us.swap(stamp, Ordering::Relaxed) {
            0 => self.since_us.store(stamp, Ordering::Relaxed),
            prev => {
                let gap = stamp.saturating_sub(prev);
                self.counters.max_gap_us.fetch_max(gap, Ordering::Relaxed);
            }
        }
    }
}

/// A running setpoint stream (see module docs). Dropping it stops the stream.
pub struct SetpointStream {
    stream: Arc<Stream>,
    rate_hz: f64,
}

impl SetpointStream {
    /// Starts streaming to `sysid`/`compid` through `endpoint` at `rate_hz` (PX4 needs
    /// more than 2 Hz; 20–50 Hz is usual). Nothing is sent until [`SetpointStream::set`]
    /// gives a setpoint.
    pub fn start(endpoint: Arc<Endpoint>, sysid: u8, compid: u8, rate_hz: f64) -> Self {
        let stream = SetpointStream::idle(endpoint, sysid, compid, rate_hz);
        clock_of(rate_hz).join(&stream.stream);
        stream
    }

    /// The stream, on no clock yet.
    fn idle(endpoint: Arc<Endpoint>, sysid: u8, compid: u8, rate_hz: f64) -> Self {
        let now = Instant::now();
        let stream = Arc::new(Stream {
            peer: endpoint.peer(sysid),
            endpoint,
            sysid,
            compid,
            start: now,
            current: Mutex::new(Current {
                setpoint: None,
                updated: now,
            }),
            last_sent_us: AtomicU64::new(0),
            since_us: AtomicU64::new(0),
            counters: Counters::default(),
        });
        SetpointStream { stream, rate_hz }
    }

    /// Replaces the streamed setpoint; `None` stops streaming (only after PX4 has been
    /// switched out of OFFBOARD). The clock sends it at its next tick.
    pub fn set(&self, setpoint: Option<LocalSetpoint>) {
        *self
            .stream
            .current
            .lock()
            .unwrap_or_else(|p| p.into_inner()) = Current {
            setpoint,
            updated: Instant::now(),
        };
    }

    /// The setpoint being streamed.
    pub fn current(&self) -> Option<LocalSetpoint> {
        self.stream
            .current
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .setpoint
    }

    /// Since when setpoints have been streaming without interruption (`None` if stopped).
    pub fn streaming_since(&self) -> Option<Instant> {
        let s = &self.stream;
        s.instant(s.since_us.load(Ordering::Relaxed))
    }

    /// The stream rate, Hz.
    pub fn rate_hz(&self) -> f64 {
        self.rate_hz
    }

    /// Counters.
    pub fn counts(&self) -> StreamCounts {
        let c = &self.stream.counters;
        StreamCounts {
            sent: c.sent.load(Ordering::Relaxed),
            send_errors: c.send_errors.load(Ordering::Relaxed),
            max_gap_ms: c.max_gap_us.load(Ordering::Relaxed) as f64 / 1000.0,
            stale_holds: c.stale_holds.load(Ordering::Relaxed),
        }
    }
}

/// One stream on its clock, with the clock's own copy of what it sent last.
struct Entry {
    stream: Weak<Stream>,
    last: Option<Current>,
}

/// The clock of every stream of one rate: one task on the setpoint thread that sends each
/// stream's setpoint every period, instead of a task and a timer per vehicle (see the
/// module docs).
struct Clock {
    /// Streams started since the last tick (the clock takes them in at its next tick).
    joining: Mutex<Vec<Weak<Stream>>>,
}

impl Clock {
    fn join(&self, stream: &Arc<Stream>) {
        self.joining
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .push(Arc::downgrade(stream));
    }

    async fn run(self: Arc<Self>, period: Duration) {
        // The streams are dealt into SLICES groups sent a sub-period apart: each stream is
        // still sent once a period, and the datagrams leave in small bursts, not one
        // burst of the whole swarm that its receivers must take in at once.
        let mut ticker = tokio::time::interval(period / SLICES as u32);
        ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        let mut state = Ticks::default();
        loop {
            ticker.tick().await;
            self.tick(&mut state);
        }
    }

    /// One sub-period: takes in the streams that joined, then sends the next slice's
    /// setpoints. Allocates nothing once every buffer in `state` has grown to its size (a
    /// thread descheduled inside the allocator could hold its lock: see the module
    /// docs), but when a stream joins or its last owner is gone.
    fn tick(&self, state: &mut Ticks) {
        state.tick = state.tick.wrapping_add(1);
        let slices = &mut state.slices;
        // New streams join without making the senders wait for a round of sends.
        if let Ok(mut joining) = self.joining.try_lock() {
            for weak in joining.drain(..) {
                let Some(stream) = weak.upgrade() else {
                    continue; // dropped before it was ever sent
                };
                let smallest = slices
                    .iter_mut()
                    .min_by_key(|s| s.len())
                    .expect("SLICES > 0");
                // Next to the streams of its endpoint, so that a tick's frames come out
                // grouped by endpoint without sorting them.
                let at = smallest
                    .iter()
                    .rposition(|e| {
                        e.stream
                            .upgrade()
                            .is_some_and(|s| Arc::ptr_eq(&s.endpoint, &stream.endpoint))
                    })
                    .map_or(smallest.len(), |i| i + 1);
                smallest.insert(
                    at,
                    Entry {
                        stream: weak,
                        last: None,
                    },
                );
            }
        }
        let now = Instant::now();
        let batch = &mut state.batch;
        slices[state.tick % SLICES].retain_mut(|e| {
            let Some(stream) = e.stream.upgrade() else {
                return false; // its owner dropped it
            };
            let current = match stream.current.try_lock() {
                Ok(c) => Some(*c),
                Err(std::sync::TryLockError::Poisoned(p)) => Some(*p.into_inner()),
                // The owner is writing it right now: send what was sent last.
                Err(std::sync::TryLockError::WouldBlock) => e.last,
            };
            if let Some(c) = current {
                e.last = Some(c);
                if let Some(out) = stream.prepare(c, now) {
                    batch.push((stream, out));
                }
            }
            true
        });
        send_batch(batch, now);
    }
}

/// What a [`Clock`] keeps from one tick to the next: its streams in slices, the frames of
/// a tick (grouped by endpoint before they are sent; the capacity is kept), the tick count.
#[derive(Default)]
struct Ticks {
    slices: [Vec<Entry>; SLICES],
    batch: Vec<(Arc<Stream>, Outgoing)>,
    tick: usize,
}

/// Hands the frames of one tick to their endpoints, each run of frames of one endpoint
/// in one call ([`Endpoint::write_batch`]: one `sendmmsg` for a shared port), counts each
/// stream's outcome and leaves `batch` empty (its capacity kept for the next tick).
///
/// The clock keeps the streams of an endpoint together in its slices, so a run is every
/// frame of that endpoint; the frames are not sorted here (an encoded frame is some 300
/// bytes, and moving them cost more than the sends' system calls saved).
fn send_batch(batch: &mut Vec<(Arc<Stream>, Outgoing)>, now: Instant) {
    for group in batch.chunk_by(|a, b| Arc::ptr_eq(&a.0.endpoint, &b.0.endpoint)) {
        group[0].0.endpoint.write_batch(
            group,
            |(_, out)| out,
            |(stream, _), ok| stream.sent(ok, now),
        );
    }
    batch.clear();
}

/// Groups of streams a clock sends a sub-period apart (see [`Clock::run`]).
const SLICES: usize = 4;

/// The clock of `rate_hz` (at least 1 Hz), started on first use on the setpoint thread.
fn clock_of(rate_hz: f64) -> Arc<Clock> {
    static CLOCKS: OnceLock<Mutex<HashMap<u64, Arc<Clock>>>> = OnceLock::new();
    let period = Duration::from_secs_f64(1.0 / rate_hz.max(1.0));
    let mut clocks = CLOCKS
        .get_or_init(Mutex::default)
        .lock()
        .unwrap_or_else(|p| p.into_inner());
    clocks
        .entry(period.as_micros() as u64)
        .or_insert_with(|| {
            let clock = Arc::new(Clock {
                joining: Mutex::new(Vec::new()),
            });
            stream_runtime().spawn(clock.clone().run(period));
            clock
        })
        .clone()
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
            .on_thread_start(crate::priority::raise_setpoint_thread)
            .enable_time()
            .build()
            .expect("the setpoint stream thread")
    })
}

#[cfg(test)]
mod tests;
