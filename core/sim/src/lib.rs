//! skein's embedded multicopter simulator: N simulated PX4 v1.16 vehicles that behave like
//! PX4 SITL on the wire (MAVLink 2 over UDP), so that third-party clients (pymavlink,
//! MAVSDK, QGroundControl) and skein's own link fly them exactly as they would fly PX4.
//!
//! Each vehicle has one UDP socket (PX4 SITL convention: sysid i+1 binds 14580+i and sends
//! to 14540+i), locks onto the first client that talks to it, streams PX4's onboard-mode
//! telemetry at PX4's rates (or a reduced swarm profile), and implements PX4's arming,
//! modes (`custom_mode` encoding), takeoff, land, RTL, hold, reposition, offboard control
//! with PX4's `type_mask` semantics and offboard-loss failsafe, the command protocol
//! (COMMAND_LONG/INT, ACKs, retransmissions) and parameters (bytewise integer encoding).
//! Each armed flight is logged as a PX4 ULog, listed and downloaded over MAVLink's log
//! protocol ([`FlightLog`], [`Simulator::flight_logs`]). PX4's events interface (`EVENT`,
//! the health and arming check report, [`px4_events`]) and its component metadata
//! served over MAVLink FTP ([`component_metadata`], [`ftp_server`]) are there as PX4
//! v1.16 has them.
//! Dynamics are a point mass per vehicle under a PX4-like position controller with speed
//! and acceleration limits, wind and gusts, GPS noise, ground contact and a draining
//! battery. Each vehicle spawns at its own place with its own local NED origin. Its GNSS
//! receiver takes RTK corrections (GPS_RTCM_DATA) as PX4 does and goes from a 3D fix to
//! RTK float and fixed, with an optional position error of each state
//! ([`SimConfig::gnss_wander`]).
//!
//! The simulator is also skein's test peer: [`Simulator`] exposes ground truth, counters
//! and fault injection (link cut, reboot, kill) in-process, and [`cli`] exposes the same
//! over a line-based TCP stats socket for tests and benchmarks in other processes.
#![warn(missing_docs)]
#![forbid(unsafe_code)]

mod arrival;
pub mod cli;
pub mod client;
pub mod component_metadata;
mod config;
pub mod ftp_server;
mod histogram;
mod impairment;
pub mod intruders;
pub mod px4_events;
pub mod px4_params;
mod report;
mod runtime;
mod signing;
mod ulog;
mod vehicle;
pub mod virtual_vehicle;

pub use config::{
    MAX_SHARED_SYSIDS, PX4_LISTEN_BASE_PORT, PX4_SITL_HOME, PX4_TARGET_BASE_PORT, SimConfig,
    SimVehicleConfig, TelemetryProfile, WindConfig, instance_sysid,
};
pub use histogram::{IntervalBucket, IntervalHistogram, IntervalSummary};
pub use report::{
    SimSummary, SimTruth, SimVehicleInfo, SimVehicleStats, TelemetryStreamInfo, telemetry_streams,
};
use report::{decode_delta, truth_of};
pub use vehicle::gnss::{
    CONVERGE_TAU_S, EKF_GNSS_LAG_S, FixFigures, GPS_DRIVER_CYCLE, GPS_RTCM_DATA_LEN, GnssFix,
    GnssTruth, INJECT_QUEUE_LENGTH, RTK_MAX_BASELINE_M, RtcmCounts, RtkTiming,
};
pub use vehicle::{FLIGHT_LOG_STORAGE_BYTES, FLIGHT_LOGS_KEPT, FlightLog, PX4_FLIGHT_SW_VERSION};
pub use virtual_vehicle::VirtualVehicle;

use impairment::Impairment;
use runtime::{Cell, SHARD_SIZE, Silence, Slot};
use skein_mavlink::{DecodeCounts, DecodeStats, Encoder};
use skein_model::geo::{GeoPoint, Ned, NedFrame};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::task::JoinHandle;
use vehicle::{Environment, Vehicle};

/// Seed of vehicle `index`'s link-loss generator (distinct from its physics generator).
fn link_seed(seed: u64, index: usize) -> u64 {
    (seed ^ 0x5EED_11C0_0000_0000).wrapping_mul(0xD1B5_4A32_D192_ED03) ^ index as u64
}

struct Inner {
    cells: Vec<Arc<Cell>>,
    /// The simulator's home (the first vehicle's spawn point): the intruders' frame.
    home: GeoPoint,
    intruders: std::sync::OnceLock<intruders::Intruders>,
    tasks: Mutex<Vec<JoinHandle<()>>>,
    stop: Arc<AtomicBool>,
}

impl Drop for Inner {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self
            .tasks
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .drain(..)
        {
            t.abort();
        }
        for cell in &self.cells {
            if let Some(t) = cell
                .recv_task
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .take()
            {
                t.abort();
            }
        }
    }
}

/// A running simulator. Cheap to clone; the simulation stops when the last clone is
/// dropped or [`Simulator::shutdown`] is called.
#[derive(Clone)]
pub struct Simulator {
    inner: Arc<Inner>,
}

impl std::fmt::Debug for Simulator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Simulator")
            .field("vehicles", &self.inner.cells.len())
            .finish()
    }
}

/// Refuses no vehicles, a zero system id, or two vehicles with the same system id and
/// the same target (see [`Simulator::start`]).
fn check_vehicles(cfg: &SimConfig) -> std::io::Result<()> {
    use std::io::{Error, ErrorKind};
    if cfg.vehicles.is_empty() {
        return Err(Error::new(
            ErrorKind::InvalidInput,
            "no vehicles configured",
        ));
    }
    let mut seen = std::collections::HashSet::new();
    for v in &cfg.vehicles {
        if v.sysid == 0 || !seen.insert((v.sysid, v.target)) {
            return Err(Error::new(
                ErrorKind::InvalidInput,
                format!(
                    "invalid system id {} or duplicate (sysid, target) ({}, {})",
                    v.sysid, v.sysid, v.target
                ),
            ));
        }
    }
    Ok(())
}

/// Vehicle `i` of `cfg`: its socket bound (with kernel receive timestamps where the
/// kernel has them), its place on the spawn grid, and its cell.
fn vehicle_cell(
    cfg: &SimConfig,
    i: usize,
    env: &Environment,
    now: Instant,
) -> std::io::Result<(Arc<Cell>, Arc<tokio::net::UdpSocket>)> {
    let vc = &cfg.vehicles[i];
    let n = cfg.vehicles.len();
    let std_socket = std::net::UdpSocket::bind(vc.bind).map_err(|e| {
        std::io::Error::new(
            e.kind(),
            format!("sysid {}: bind {}: {e}", vc.sysid, vc.bind),
        )
    })?;
    std_socket.set_nonblocking(true)?;
    if let Err(e) = arrival::stamp_arrivals(&std_socket) {
        tracing::warn!(
            sysid = vc.sysid,
            "no kernel receive timestamps ({e}): setpoint intervals are measured \
             when the simulator reads them"
        );
    }
    let socket = Arc::new(tokio::net::UdpSocket::from_std(std_socket)?);
    let bound = socket.local_addr()?;
    let (index, cols) = match cfg.grid_columns {
        Some(cols) => (usize::from(vc.sysid.max(1) - 1), cols),
        None => (i, (n as f64).sqrt().ceil() as usize),
    };
    let spawn = spawn_point(cfg.home, index, cols, cfg.spacing_m);
    let vehicle = Vehicle::new(vc.sysid, spawn, env.clone(), now);
    let signing = signing::SimSigning::with_key(cfg.signing_key.clone());
    let mut encoder = Encoder::new(vc.sysid, 1);
    encoder.set_signing(signing.current.clone());
    let cell = Arc::new(Cell {
        sysid: vc.sysid,
        bound,
        target: vc.target,
        slot: Mutex::new(Slot {
            vehicle,
            encoder,
            peer: None,
            silence: Silence::Off,
            killed: false,
            socket: Some(socket.clone()),
            out: Vec::with_capacity(4096),
            net: Default::default(),
            decode_baseline: DecodeCounts::default(),
            impair: Impairment::new(link_seed(cfg.seed, i)),
            signing,
        }),
        decode_stats: Arc::new(DecodeStats::default()),
        recv_task: Mutex::new(None),
    });
    Ok((cell, socket))
}

/// Spawn point of vehicle `index` on a grid around `home`: `cols` columns east, rows
/// north, `spacing_m` apart.
fn spawn_point(home: GeoPoint, index: usize, cols: usize, spacing_m: f64) -> GeoPoint {
    NedFrame::new(home).to_geo(spawn_offset(index, cols, spacing_m))
}

/// Where vehicle `index` of a simulator's grid spawns from its `home`, NED metres:
/// `cols` columns (at least 1) going east, rows going north, `spacing_m` apart (see
/// [`SimConfig::spacing_m`], [`SimConfig::grid_columns`]).
pub fn spawn_offset(index: usize, cols: usize, spacing_m: f64) -> Ned {
    let cols = cols.max(1);
    Ned::new(
        (index / cols) as f64 * spacing_m,
        (index % cols) as f64 * spacing_m,
        0.0,
    )
}

impl Simulator {
    /// [`Simulator::start`] on worker threads of the simulator's own (`skein-sim`, two
    /// workers, kept for the life of the process), for a simulator embedded in a process
    /// that also flies the vehicles (`skein up --sim`): like a PX4 in a process of its
    /// own, its clocks, receive timestamps and failsafe timers are then not held up by
    /// the embedding process's busy workers, so a setpoint gap it measures is a gap on
    /// the wire. Errors as [`Simulator::start`].
    pub async fn start_on_own_threads(cfg: SimConfig) -> std::io::Result<Simulator> {
        static RUNTIME: std::sync::OnceLock<std::io::Result<tokio::runtime::Runtime>> =
            std::sync::OnceLock::new();
        let runtime = RUNTIME
            .get_or_init(|| {
                tokio::runtime::Builder::new_multi_thread()
                    .worker_threads(2)
                    .thread_name("skein-sim")
                    .enable_all()
                    .build()
            })
            .as_ref()
            .map_err(|e| std::io::Error::new(e.kind(), format!("simulator runtime: {e}")))?;
        runtime
            .spawn(Simulator::start(cfg))
            .await
            .map_err(std::io::Error::other)?
    }

    /// Binds every vehicle's socket and starts the simulation on the current tokio
    /// runtime. Fails on a bind error, no vehicles, a zero system id, or two vehicles
    /// with the same system id *and* the same target (a receiver could not tell them
    /// apart). The same system id on different targets is allowed (identity is
    /// (link, sysid): that is how more than 255 vehicles run in one process); the methods
    /// taking a `sysid` then address the first vehicle with it.
    pub async fn start(cfg: SimConfig) -> std::io::Result<Simulator> {
        check_vehicles(&cfg)?;
        let env = Environment::of(&cfg);
        let now = Instant::now();
        let mut cells = Vec::with_capacity(cfg.vehicles.len());
        let mut sockets = Vec::with_capacity(cfg.vehicles.len());
        for i in 0..cfg.vehicles.len() {
            let (cell, socket) = vehicle_cell(&cfg, i, &env, now)?;
            cells.push(cell);
            sockets.push(socket);
        }
        for (cell, socket) in cells.iter().zip(sockets) {
            let handle = tokio::spawn(runtime::recv_loop(cell.clone(), socket));
            *cell.recv_task.lock().unwrap_or_else(|e| e.into_inner()) = Some(handle);
        }
        let stop = Arc::new(AtomicBool::new(false));
        let period = Duration::from_secs_f64(1.0 / cfg.telemetry.tick_rate_hz());
        let shards: Vec<Vec<Arc<Cell>>> = cells.chunks(SHARD_SIZE).map(|c| c.to_vec()).collect();
        let n_shards = shards.len() as u32;
        let mut tasks = Vec::with_capacity(shards.len());
        for (k, shard) in shards.into_iter().enumerate() {
            let phase = period * k as u32 / n_shards;
            tasks.push(tokio::spawn(runtime::shard_loop(
                shard,
                period,
                phase,
                stop.clone(),
            )));
        }
        Ok(Simulator {
            inner: Arc::new(Inner {
                cells,
                home: cfg.home,
                intruders: std::sync::OnceLock::new(),
                tasks: Mutex::new(tasks),
                stop,
            }),
        })
    }

    fn cell(&self, sysid: u8) -> Option<&Arc<Cell>> {
        self.inner.cells.iter().find(|c| c.sysid == sysid)
    }

    /// Every vehicle's system id and endpoints, in configuration order.
    pub fn vehicles(&self) -> Vec<SimVehicleInfo> {
        self.inner
            .cells
            .iter()
            .map(|c| SimVehicleInfo {
                sysid: c.sysid,
                bound: c.bound,
                target: c.target,
            })
            .collect()
    }

    /// Counters and ground truth of every vehicle.
    pub fn stats(&self) -> Vec<SimVehicleStats> {
        let now = Instant::now();
        self.inner
            .cells
            .iter()
            .map(|c| {
                let decode_now = c.decode_stats.snapshot();
                let mut slot = c.lock();
                let silent = slot.is_silent(now);
                let decode = decode_delta(decode_now, slot.decode_baseline);
                let v = &slot.vehicle;
                SimVehicleStats {
                    sysid: c.sysid,
                    bound: c.bound,
                    target: c.target,
                    peer: slot.peer,
                    silent,
                    killed: slot.killed,
                    setpoints_received: v.counters.setpoints_received,
                    setpoint_max_gap_ms: v.counters.setpoint_max_gap.as_secs_f64() * 1e3,
                    setpoint_max_gap_offboard_ms: v
                        .counters
                        .setpoint_max_gap_offboard
                        .as_secs_f64()
                        * 1e3,
                    setpoint_intervals: v.setpoint_intervals.summary(),
                    offboard_loss_failsafes: v.counters.offboard_loss_failsafes,
                    gcs_loss_failsafes: v.counters.gcs_loss_failsafes,
                    geofence_breaches: v.counters.geofence_breaches,
                    fence_items: v.missions.fence.len(),
                    rally_items: v.missions.rally.len(),
                    commands_received: v.counters.commands_received,
                    frames_received: v.counters.frames_received,
                    malformed_frames: decode.errors(),
                    datagrams_received: slot.net.datagrams_received,
                    datagrams_dropped_silent: slot.net.datagrams_dropped_silent,
                    link_loss_fraction: slot.impair.loss_fraction(),
                    link_latency_ms: slot.impair.latency_ms(),
                    datagrams_dropped_link: slot.impair.counters.dropped,
                    datagrams_dropped_link_inbound: slot.impair.counters.dropped_inbound,
                    link_loss_effective: slot.impair.effective_loss(),
                    link_latency_effective_ms: slot.impair.effective_latency_ms(),
                    link_in_flight: slot.impair.in_flight(),
                    datagrams_sent: slot.net.datagrams_sent,
                    frames_sent: slot.net.frames_sent,
                    bytes_sent: slot.net.bytes_sent,
                    send_drops: slot.net.send_drops,
                    statustexts_sent: v.counters.statustexts_sent,
                    statustexts_suppressed: v.counters.statustexts_suppressed,
                    rtcm: v.counters.rtcm,
                    gcs_connected: v.gcs_connected(now),
                    signing: slot.signing.counts(),
                    signing_key_installed: slot.signing.current.is_some(),
                    onboard_controller_connected: v.onboard_controller_connected(now),
                    decode,
                    truth: truth_of(v, now),
                }
            })
            .collect()
    }

    /// Clears every vehicle's counters (setpoint gaps and intervals, failsafes, commands,
    /// malformed input, traffic, simulated-link drops and delays); the link quality
    /// settings stay.
    pub fn reset_stats(&self) {
        for c in &self.inner.cells {
            let decode_now = c.decode_stats.snapshot();
            let mut slot = c.lock();
            slot.vehicle.counters = Default::default();
            slot.vehicle.setpoint_intervals.clear();
            slot.net = Default::default();
            slot.impair.counters = Default::default();
            slot.decode_baseline = decode_now;
            slot.signing.reset_counts();
        }
    }

    /// Totals over every vehicle (counters since start or the last
    /// [`Simulator::reset_stats`]) with the setpoint intervals of all vehicles in one
    /// histogram: what a benchmark of the whole swarm reads.
    pub fn summary(&self) -> SimSummary {
        let now = Instant::now();
        let mut s = SimSummary::default();
        let mut intervals = IntervalHistogram::new();
        for c in &self.inner.cells {
            let decode_now = c.decode_stats.snapshot();
            let slot = c.lock();
            let v = &slot.vehicle;
            s.vehicles += 1;
            s.killed += usize::from(slot.killed);
            s.armed += usize::from(v.armed);
            *s.modes.entry(v.mode.name()).or_default() += 1;
            s.setpoints_received += v.counters.setpoints_received;
            s.frames_received += v.counters.frames_received;
            s.commands_received += v.counters.commands_received;
            s.offboard_loss_failsafes += v.counters.offboard_loss_failsafes;
            s.gcs_loss_failsafes += v.counters.gcs_loss_failsafes;
            s.geofence_breaches += v.counters.geofence_breaches;
            s.rtcm.add(&v.counters.rtcm);
            s.malformed_frames += decode_delta(decode_now, slot.decode_baseline).errors();
            s.datagrams_received += slot.net.datagrams_received;
            s.datagrams_sent += slot.net.datagrams_sent;
            s.send_drops += slot.net.send_drops;
            s.datagrams_dropped_link += slot.impair.counters.dropped;
            s.gcs_connected += usize::from(v.gcs_connected(now));
            intervals.merge(&v.setpoint_intervals);
        }
        s.setpoint_intervals = intervals.summary();
        s.setpoint_interval_buckets = intervals.buckets();
        s
    }

    /// The setpoint intervals of every vehicle (since start or the last reset) in one
    /// histogram.
    pub fn setpoint_intervals(&self) -> IntervalHistogram {
        let mut all = IntervalHistogram::new();
        for c in &self.inner.cells {
            all.merge(&c.lock().vehicle.setpoint_intervals);
        }
        all
    }

    /// Sets the simulated link quality of vehicle `sysid`: each datagram, in both
    /// directions, is lost with probability `loss_fraction` (0..=1, clamped; drawn from
    /// the run's seed, so reproducible) and delayed by `latency_ms` (one way, ms; a round
    /// trip takes twice that). `(0.0, 0.0)` restores a perfect link (datagrams already
    /// delayed are still delivered, in order). Returns false when no vehicle has that
    /// sysid (with repeated sysids, the first one is set).
    pub fn set_link_quality(&self, sysid: u8, loss_fraction: f64, latency_ms: f64) -> bool {
        match self.cell(sysid) {
            Some(cell) => {
                let mut slot = cell.lock();
                slot.impair.set(loss_fraction, latency_ms);
                // The receive task recomputes its wake-up time.
                slot.impair.wake.notify_one();
                true
            }
            None => false,
        }
    }

    /// Makes every fence and rally upload to vehicle `sysid` end in `fault` (a
    /// `MAV_MISSION_RESULT` error such as `MAV_MISSION_ERROR` or `MAV_MISSION_NO_SPACE`),
    /// as an autopilot that cannot store it; `None` clears the fault. Returns false when
    /// no vehicle has that sysid.
    pub fn set_mission_fault(
        &self,
        sysid: u8,
        fault: Option<skein_mavlink::dialect::MavMissionResult>,
    ) -> bool {
        match self.cell(sysid) {
            Some(cell) => {
                cell.lock().vehicle.missions.fault = fault;
                true
            }
            None => false,
        }
    }

    /// [`Simulator::set_link_quality`] for every vehicle.
    pub fn set_link_quality_all(&self, loss_fraction: f64, latency_ms: f64) {
        for c in &self.inner.cells {
            let mut slot = c.lock();
            slot.impair.set(loss_fraction, latency_ms);
            slot.impair.wake.notify_one();
        }
    }

    /// The flight logs of vehicle `sysid` as a ground station's `LOG_REQUEST_LIST` would
    /// list them now: oldest first (the index is the `LOG_ENTRY` id), the flight being
    /// logged last with what it holds so far. `None` when no vehicle has that sysid.
    pub fn flight_logs(&self, sysid: u8) -> Option<Vec<FlightLog>> {
        let cell = self.cell(sysid)?;
        let slot = cell.lock();
        Some(slot.vehicle.flight_logs.list())
    }

    /// Ground truth of vehicle `sysid`.
    pub fn truth(&self, sysid: u8) -> Option<SimTruth> {
        let cell = self.cell(sysid)?;
        let slot = cell.lock();
        Some(truth_of(&slot.vehicle, Instant::now()))
    }

    /// Starts the intruders of `config` (non-cooperative aircraft with no link, see
    /// [`intruders`]) around the simulator's home; their paths start now. Once per run.
    ///
    /// # Errors
    /// An invalid configuration, or intruders already started.
    pub fn start_intruders(&self, config: intruders::IntruderConfig) -> Result<(), String> {
        let ints = intruders::Intruders::new(self.inner.home, config, Instant::now())?;
        self.inner
            .intruders
            .set(ints)
            .map_err(|_| "intruders already started".to_string())
    }

    /// Starts the intruders' paths again from their beginning, now: each jumps back to
    /// where it started (a test starts a pass once its cameras are ready).
    ///
    /// # Errors
    /// No intruders were started.
    pub fn restart_intruders(&self) -> Result<(), String> {
        let ints = self
            .inner
            .intruders
            .get()
            .ok_or("no intruders were started")?;
        ints.restart(Instant::now());
        Ok(())
    }

    /// Every intruder leaves the world until the next restart (see
    /// [`intruders::Intruders::leave`]).
    ///
    /// # Errors
    /// No intruders were started.
    pub fn intruders_leave(&self) -> Result<(), String> {
        let ints = self
            .inner
            .intruders
            .get()
            .ok_or("no intruders were started")?;
        ints.leave();
        Ok(())
    }

    /// Ground truth of every intruder now (empty without intruders, or while they are
    /// away).
    pub fn intruders(&self) -> Vec<intruders::IntruderTruth> {
        self.inner
            .intruders
            .get()
            .map(intruders::Intruders::truth)
            .unwrap_or_default()
    }

    /// Cuts (`true`) or restores the vehicle's link: while cut it sends nothing and drops
    /// everything it receives; it keeps flying (and its failsafes keep running).
    pub fn set_silent(&self, sysid: u8, silent: bool) {
        if let Some(cell) = self.cell(sysid) {
            let mut slot = cell.lock();
            slot.silence = if silent {
                Silence::Forever
            } else {
                Silence::Off
            };
        }
    }

    /// Cuts the vehicle's link for `duration`, then restores it.
    pub fn silence_for(&self, sysid: u8, duration: Duration) {
        if let Some(cell) = self.cell(sysid) {
            cell.lock().silence = match Instant::now().checked_add(duration) {
                Some(until) => Silence::Until(until),
                None => Silence::Forever,
            };
        }
    }

    /// Reboots the vehicle like a PX4 SITL restart: state reset (disarmed, HOLD, back on
    /// the ground at its spawn point, parameters to their configured values), boot time
    /// and sequence numbers restart, and it locks onto the next client that talks to it.
    pub fn reboot(&self, sysid: u8) {
        if let Some(cell) = self.cell(sysid) {
            cell.lock().reboot(Instant::now());
        }
    }

    /// MAVLink FTP requests vehicle `sysid` handled since it last booted.
    pub fn ftp_requests(&self, sysid: u8) -> u64 {
        self.cell(sysid)
            .map_or(0, |c| c.lock().vehicle.ftp_requests())
    }

    /// Loses the vehicle's next `n` `EVENT`s on the way (they stay in its buffer and
    /// are answered when requested by sequence): a lossy link, deterministically.
    pub fn drop_next_events(&self, sysid: u8, n: u32) {
        if let Some(cell) = self.cell(sysid) {
            cell.lock().vehicle.drop_next_events = n;
        }
    }

    /// Removes the vehicle for good: its socket is closed, it neither sends nor receives.
    pub fn kill(&self, sysid: u8) {
        if let Some(cell) = self.cell(sysid) {
            {
                let mut slot = cell.lock();
                slot.killed = true;
                slot.socket = None;
            }
            if let Some(t) = cell
                .recv_task
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .take()
            {
                t.abort();
            }
        }
    }

    /// Stops every task and closes every socket.
    pub async fn shutdown(self) {
        self.inner.stop.store(true, Ordering::Relaxed);
        let tasks: Vec<JoinHandle<()>> = self
            .inner
            .tasks
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .drain(..)
            .collect();
        for cell in &self.inner.cells {
            let recv_task = cell
                .recv_task
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .take();
            if let Some(t) = recv_task {
                t.abort();
                let _ = t.await;
            }
            let mut slot = cell.lock();
            slot.socket = None;
            slot.killed = true;
        }
        for t in tasks {
            t.abort();
            let _ = t.await;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spawn_grid_is_spaced() {
        let home = PX4_SITL_HOME;
        let frame = NedFrame::new(home);
        let p0 = frame.to_ned(&spawn_point(home, 0, 2, 5.0));
        let p1 = frame.to_ned(&spawn_point(home, 1, 2, 5.0));
        let p2 = frame.to_ned(&spawn_point(home, 2, 2, 5.0));
        assert!(p0.norm() < 1e-6);
        assert!((p1.east_m - 5.0).abs() < 1e-3 && p1.north_m.abs() < 1e-3);
        assert!((p2.north_m - 5.0).abs() < 1e-3 && p2.east_m.abs() < 1e-3);
    }
}
