//! One simulated PX4 multicopter, without I/O: the MAVLink message handling (commands,
//! parameters, setpoints, heartbeats, the mission and log protocols), PX4's mode and
//! arming logic, failsafes, a point-mass model with a PX4-like position controller, land
//! detection, a battery, the GNSS receiver with its RTK corrections and the flight log.
//!
//! Inputs arrive through [`Vehicle::handle_frame`]; the simulation advances with
//! [`Vehicle::step`] at a fixed `dt`; everything the vehicle sends goes through an
//! [`Outbox`]. Protocol timers (setpoint gaps, heartbeat timeouts, auto-disarm) run on the
//! wall clock passed in as `now`; physics runs on the fixed step, so the same seed and the
//! same inputs give the same trajectory.

// PX4 v1.16 still speaks PING, SET_MODE, BODY_NED frames, GET_HOME_POSITION … which
// the current MAVLink spec marks deprecated: the simulator must handle them anyway.
#![allow(deprecated)]

use crate::config::WindConfig;
use crate::histogram::IntervalHistogram;
use crate::px4_params::{PARAM_COUNT, Param, ParamValue, Params};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use skein_mavlink::dialect::*;
use skein_mavlink::{Encoder, Frame, MavMessage};
use skein_model::geo::{GeoPoint, Ned, NedFrame, wrap_pi};
use skein_model::px4::{FORCE_ARM_DISARM_MAGIC, LandedState, Px4Mode, type_mask};
use std::collections::VecDeque;
use std::time::{Duration, Instant};
use telemetry::Streams;

pub(crate) mod telemetry;

pub use telemetry::PX4_FLIGHT_SW_VERSION;
mod battery;
mod commander;
mod dynamics;
mod events;
#[cfg(test)]
mod events_tests;
mod flight_log;
mod ftp;
mod geofence;
pub(crate) mod gnss;
mod health_report;
mod land_detector;
mod log_handler;
mod mavlink_receiver;
mod mission;
mod navigator;
mod position_control;
#[cfg(test)]
mod test_harness;
#[cfg(test)]
mod tests;

pub(crate) use battery::Battery;
pub(crate) use flight_log::FlightLogStore;
pub use flight_log::{FLIGHT_LOG_STORAGE_BYTES, FLIGHT_LOGS_KEPT, FlightLog};
use log_handler::LogHandler;
use mavlink_receiver::{Command, LastCommand};
pub(crate) use mission::MissionStore;
pub(crate) use navigator::RtlPhase;
use position_control::PositionControl;

/// Standard gravity, m/s².
pub(crate) const GRAVITY_M_S2: f64 = 9.806_65;
/// STATUSTEXT is sent only while a GCS heartbeat arrived this recently (px4.md).
const STATUSTEXT_GCS_WINDOW: Duration = Duration::from_millis(2500);
/// PX4's per-MAV_TYPE heartbeat timeout.
const HEARTBEAT_TIMEOUT: Duration = Duration::from_millis(1500);
/// With a minimum stream age configured, the stream must have no gap longer than this
/// (> 2 Hz, as PX4's documentation states).
const OFFBOARD_MAX_GAP: Duration = Duration::from_millis(500);
/// A resend (`confirmation` > 0) of the last command within this window is answered
/// again without executing it twice.
const COMMAND_DEDUP_WINDOW: Duration = Duration::from_secs(5);
/// Mixed into a vehicle's seed for its GNSS receiver's generators (distinct from its
/// physics generator, so the wander leaves the gusts' and the estimator's draws alone).
const GNSS_SEED_MIX: u64 = 0x6E55_0000_0000_0000;
/// Gust and estimator-noise time constants, s.
const GUST_TAU_S: f64 = 2.0;
const EST_NOISE_TAU_S: f64 = 5.0;
/// Land detector: time at ground contact before "landed", s (PX4's ground-contact,
/// maybe-landed and landed stages plus the estimate settling; fitted to landing.csv).
const LAND_DETECT_S: f64 = 4.0;
/// Height above ground at which a take-off is detected, m.
const TAKEOFF_DETECT_M: f64 = 0.15;

/// Environment shared by every vehicle of a run.
#[derive(Debug, Clone)]
pub(crate) struct Environment {
    pub wind: WindConfig,
    pub gps_noise_m: f64,
    pub ekf_fix_delay: Duration,
    pub params: Vec<(String, f64)>,
    pub seed: u64,
    pub profile: crate::config::TelemetryProfile,
    pub offboard_min_stream: Duration,
    /// Seeded estimator noise (PX4 SIH's hover wander) on.
    pub estimator_noise: bool,
    /// The GNSS receiver's RTK timing.
    pub rtk: gnss::RtkTiming,
    /// The GNSS receiver's error model on (`--gnss-wander`).
    pub gnss_wander: bool,
}

impl Environment {
    /// The environment `cfg` describes.
    pub fn of(cfg: &crate::config::SimConfig) -> Environment {
        Environment {
            wind: cfg.wind,
            gps_noise_m: cfg.gps_noise_m.max(0.0),
            ekf_fix_delay: Duration::from_secs_f64(cfg.ekf_fix_delay_s.max(0.0)),
            params: cfg.params.clone(),
            seed: cfg.seed,
            profile: cfg.telemetry,
            offboard_min_stream: Duration::from_secs_f64(cfg.offboard_min_stream_s.max(0.0)),
            estimator_noise: cfg.estimator_noise,
            rtk: cfg.rtk,
            gnss_wander: cfg.gnss_wander,
        }
    }
}

/// Collects the frames a vehicle sends during one input or tick (batched into datagrams by
/// the runtime).
pub(crate) struct Outbox<'a> {
    pub enc: &'a mut Encoder,
    pub buf: &'a mut Vec<u8>,
    pub frames: u64,
}

impl Outbox<'_> {
    /// Encodes `msg` as the vehicle's next frame.
    pub fn push(&mut self, msg: &MavMessage) {
        self.enc.encode_into(msg, self.buf);
        self.frames += 1;
    }
}

/// An offboard setpoint in the vehicle's local NED frame; `None` = ignored by type_mask.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Setpoint {
    pub pos: [Option<f64>; 3],
    pub vel: [Option<f64>; 3],
    /// Acceleration feed-forward, NED m/s² (type_mask bits 64/128/256 clear and FORCE
    /// 512 clear), added to the velocity controller's output as PX4 does.
    pub acc: [Option<f64>; 3],
    pub yaw_rad: Option<f64>,
    pub yaw_rate_rad_s: Option<f64>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum YawGoal {
    /// Hold/turn to this heading, rad.
    Heading(f64),
    /// Turn at this rate, rad/s.
    Rate(f64),
}

/// What the controller tracks this tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Goal {
    /// Motors idle on the ground (disarmed, or armed and not taking off).
    Idle,
    /// Motors off in the air (killed): ballistic.
    FreeFall,
    /// Position / velocity tracking with speed limits.
    Track(Track),
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Track {
    pub pos: [Option<f64>; 3],
    pub vel: [Option<f64>; 3],
    /// Acceleration feed-forward, NED m/s² (offboard only).
    pub acc: [Option<f64>; 3],
    pub xy_max_m_s: f64,
    pub up_max_m_s: f64,
    pub down_max_m_s: f64,
    pub yaw: YawGoal,
    pub yaw_rate_max_rad_s: f64,
    /// True in auto modes: the setpoint moves to the target within the speed and
    /// acceleration limits (PX4's flight tasks); false in offboard (raw setpoints).
    pub smooth: bool,
}

/// Per-vehicle counters reported in the stats.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Counters {
    pub frames_received: u64,
    pub setpoints_received: u64,
    pub setpoint_max_gap: Duration,
    pub setpoint_max_gap_offboard: Duration,
    pub offboard_loss_failsafes: u64,
    pub gcs_loss_failsafes: u64,
    /// Geofence breaches that took `GF_ACTION`.
    pub geofence_breaches: u64,
    pub commands_received: u64,
    pub statustexts_sent: u64,
    pub statustexts_suppressed: u64,
    /// The RTK corrections' path to the GNSS receiver.
    pub rtcm: gnss::RtcmCounts,
}

/// Link counters, fed by the runtime, shown in LINK_NODE_STATUS.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LinkCounters {
    pub tx_frames: u64,
    pub tx_bytes: u64,
    pub rx_frames: u64,
    pub rx_bytes: u64,
    pub rx_parse_errors: u64,
    pub tx_overflows: u64,
    rate_window_start: Instant,
    rate_window_tx: u64,
    rate_window_rx: u64,
    pub tx_rate_bytes_s: u32,
    pub rx_rate_bytes_s: u32,
}

impl LinkCounters {
    fn new(now: Instant) -> Self {
        LinkCounters {
            tx_frames: 0,
            tx_bytes: 0,
            rx_frames: 0,
            rx_bytes: 0,
            rx_parse_errors: 0,
            tx_overflows: 0,
            rate_window_start: now,
            rate_window_tx: 0,
            rate_window_rx: 0,
            tx_rate_bytes_s: 0,
            rx_rate_bytes_s: 0,
        }
    }

    fn update_rates(&mut self, now: Instant) {
        let dt = now.saturating_duration_since(self.rate_window_start);
        if dt >= Duration::from_secs(1) {
            let s = dt.as_secs_f64();
            self.tx_rate_bytes_s = ((self.tx_bytes - self.rate_window_tx) as f64 / s) as u32;
            self.rx_rate_bytes_s = ((self.rx_bytes - self.rate_window_rx) as f64 / s) as u32;
            self.rate_window_start = now;
            self.rate_window_tx = self.tx_bytes;
            self.rate_window_rx = self.rx_bytes;
        }
    }
}

/// Which kinds of peers sent a heartbeat lately (PX4 tracks them per MAV_TYPE).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct PeerHeartbeats {
    pub gcs: Option<Instant>,
    pub onboard_controller: Option<Instant>,
    pub gimbal: Option<Instant>,
    pub camera: Option<Instant>,
}

/// One simulated vehicle.
pub(crate) struct Vehicle {
    pub sysid: u8,
    /// Local NED origin (spawn point on the ground).
    pub origin: NedFrame,
    pub boot: Instant,
    pub params: Params,
    pub env: Environment,
    rng: SmallRng,

    // Truth.
    pub pos: Ned,
    pub vel: Ned,
    /// Acceleration the rotors produce (without gravity and drag), NED m/s².
    pub thrust_acc: Ned,
    pub yaw_rad: f64,
    pub yaw_rate_rad_s: f64,
    pub roll_rad: f64,
    pub pitch_rad: f64,
    pub roll_rate_rad_s: f64,
    pub pitch_rate_rad_s: f64,
    gust: Ned,
    /// Estimator error (GPS noise through the EKF), m.
    pub est_noise: Ned,
    /// Estimator velocity error, m/s.
    pub est_vel_noise: Ned,
    /// Slow bias of the estimated vertical velocity (NED, positive = reads descending),
    /// m/s; not integrated into the position estimate.
    pub est_vz_bias_m_s: f64,
    /// The GNSS receiver: RTK corrections, fix, position error.
    pub gnss: gnss::Gnss,

    // Controller.
    /// Auto-mode trajectory: velocity of the moving setpoint, NED m/s.
    vel_sp_smooth: Ned,
    /// Auto-mode trajectory: position of the moving setpoint, local NED m.
    traj_pos: Ned,
    /// False until the trajectory starts from the current state (reset on mode changes).
    traj_valid: bool,
    /// PX4's position and velocity controller.
    pos_ctrl: PositionControl,
    /// Unit thrust direction ("up" of the body), north and east components.
    tilt_up: [f64; 2],
    /// Low-passed acceleration, NED m/s² (the velocity loop's D term).
    acc_filt: Ned,
    pub goal: Goal,
    /// Last position/velocity setpoint of the controller (POSITION_TARGET_LOCAL_NED).
    pub ctrl_pos_sp: Ned,
    pub ctrl_vel_sp: Ned,
    pub ctrl_yaw_sp: f64,

    // Flight state.
    pub mode: Px4Mode,
    pub armed: bool,
    pub landed: bool,
    pub failsafe: bool,
    pub has_fix: bool,
    armed_at: Instant,
    took_off: bool,
    landed_at: Option<Instant>,
    ground_contact_s: f64,
    pub home: GeoPoint,
    pub home_local: Ned,
    pub home_yaw_rad: f64,
    hold_pos: Ned,
    hold_yaw: YawGoal,
    auto_speed_m_s: Option<f64>,
    takeoff_z: f64,
    land_xy: (f64, f64),
    pub rtl_phase: RtlPhase,
    rtl_z: f64,
    rtl_start: Ned,

    // Offboard.
    pub setpoint: Option<Setpoint>,
    setpoint_last: Option<Instant>,
    setpoint_stream_start: Option<Instant>,

    // Links.
    pub heartbeats: PeerHeartbeats,
    gcs_lost: bool,
    last_command: Option<LastCommand>,
    pub reboot_requested: bool,

    // Plans and the geofence (PX4's dataman: kept across reboots).
    pub missions: MissionStore,
    fence_areas: Vec<geofence::Area>,
    /// Outside the fence since the last check (the breach action was taken).
    pub fence_breached: bool,

    // Flight logs (PX4's SD card: kept across reboots) and the log protocol's state.
    pub flight_logs: FlightLogStore,
    log_handler: LogHandler,

    // PX4's events interface, health report and MAVLink FTP (the component metadata).
    events: events::EventLog,
    health: health_report::HealthReporter,
    ftp: ftp::FtpLink,
    /// `EVENT`s still to lose on the way (a test's loss; they stay in the buffer).
    pub drop_next_events: u32,

    // Telemetry.
    pub streams: Streams,
    pub ping_seq: u32,
    pub battery: Battery,
    pub link: LinkCounters,
    pub counters: Counters,
    /// Intervals between consecutive setpoints (kept across reboots, cleared with the
    /// counters).
    pub setpoint_intervals: IntervalHistogram,
}

/// Box-Muller standard normal sample.
fn gaussian(rng: &mut SmallRng) -> f64 {
    let u1: f64 = rng.random::<f64>().max(1e-12);
    let u2: f64 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

fn axis(v: &Ned, i: usize) -> f64 {
    match i {
        0 => v.north_m,
        1 => v.east_m,
        _ => v.down_m,
    }
}

fn set_axis(v: &mut Ned, i: usize, x: f64) {
    match i {
        0 => v.north_m = x,
        1 => v.east_m = x,
        _ => v.down_m = x,
    }
}

fn limit_horizontal(v: &mut Ned, max: f64) {
    let h = v.horizontal_norm();
    if h > max && h > 0.0 {
        let k = max / h;
        v.north_m *= k;
        v.east_m *= k;
    }
}
impl Vehicle {
    /// A freshly booted vehicle standing at `spawn` (its local origin), in HOLD, disarmed.
    pub fn new(sysid: u8, spawn: GeoPoint, env: Environment, now: Instant) -> Vehicle {
        let (params, _unknown) = Params::new(sysid, &env.params);
        let seed = env
            .seed
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .wrapping_add(u64::from(sysid));
        let streams = Streams::new(env.profile, now);
        let gnss = gnss::Gnss::new(
            env.rtk,
            env.gnss_wander,
            spawn.to_ecef(),
            seed ^ GNSS_SEED_MIX,
        );
        let mut v = Vehicle {
            sysid,
            origin: NedFrame::new(spawn),
            boot: now,
            params,
            env,
            rng: SmallRng::seed_from_u64(seed),
            pos: Ned::ZERO,
            vel: Ned::ZERO,
            thrust_acc: Ned::new(0.0, 0.0, -GRAVITY_M_S2),
            yaw_rad: 0.0,
            yaw_rate_rad_s: 0.0,
            roll_rad: 0.0,
            pitch_rad: 0.0,
            roll_rate_rad_s: 0.0,
            pitch_rate_rad_s: 0.0,
            gust: Ned::ZERO,
            est_noise: Ned::ZERO,
            est_vel_noise: Ned::ZERO,
            est_vz_bias_m_s: 0.0,
            gnss,
            vel_sp_smooth: Ned::ZERO,
            traj_pos: Ned::ZERO,
            traj_valid: false,
            pos_ctrl: PositionControl::default(),
            tilt_up: [0.0; 2],
            acc_filt: Ned::ZERO,
            goal: Goal::Idle,
            ctrl_pos_sp: Ned::ZERO,
            ctrl_vel_sp: Ned::ZERO,
            ctrl_yaw_sp: 0.0,
            mode: Px4Mode::Hold,
            armed: false,
            landed: true,
            failsafe: false,
            has_fix: false,
            armed_at: now,
            took_off: false,
            landed_at: None,
            ground_contact_s: 0.0,
            home: spawn,
            home_local: Ned::ZERO,
            home_yaw_rad: 0.0,
            hold_pos: Ned::ZERO,
            hold_yaw: YawGoal::Heading(0.0),
            auto_speed_m_s: None,
            takeoff_z: 0.0,
            land_xy: (0.0, 0.0),
            rtl_phase: RtlPhase::Climb,
            rtl_z: 0.0,
            rtl_start: Ned::ZERO,
            setpoint: None,
            setpoint_last: None,
            setpoint_stream_start: None,
            heartbeats: PeerHeartbeats::default(),
            gcs_lost: false,
            last_command: None,
            reboot_requested: false,
            missions: MissionStore::default(),
            fence_areas: Vec::new(),
            fence_breached: false,
            flight_logs: FlightLogStore::default(),
            log_handler: LogHandler::default(),
            events: events::EventLog::default(),
            health: health_report::HealthReporter::default(),
            ftp: ftp::FtpLink::default(),
            drop_next_events: 0,
            streams,
            ping_seq: 0,
            battery: Battery {
                consumed_mah: 0.0,
                current_a: 0.0,
                voltage_v: 0.0,
                remaining: 1.0,
            },
            link: LinkCounters::new(now),
            counters: Counters::default(),
            setpoint_intervals: IntervalHistogram::new(),
        };
        v.update_battery(0.0);
        v
    }

    /// PX4 reboot: everything but the counters, the stored plans (fence, rally: PX4's
    /// dataman) and the flight logs (PX4's SD card; a flight being logged ends there)
    /// starts over (state, boot time, streams, the log protocol).
    pub fn reboot(&mut self, now: Instant) {
        let counters = self.counters;
        let intervals = std::mem::take(&mut self.setpoint_intervals);
        let missions = std::mem::take(&mut self.missions);
        let mut flight_logs = std::mem::take(&mut self.flight_logs);
        flight_logs.finish();
        let fresh = Vehicle::new(self.sysid, self.origin.origin, self.env.clone(), now);
        *self = fresh;
        self.counters = counters;
        self.setpoint_intervals = intervals;
        self.missions = missions;
        self.flight_logs = flight_logs;
        self.load_fence();
    }

    /// Milliseconds since boot (`time_boot_ms`).
    pub fn time_boot_ms(&self, now: Instant) -> u32 {
        now.saturating_duration_since(self.boot).as_millis() as u32
    }

    /// Microseconds since boot (PX4's `hrt_absolute_time`).
    pub fn time_boot_us(&self, now: Instant) -> u64 {
        now.saturating_duration_since(self.boot).as_micros() as u64
    }

    /// True once the simulated EKF has a global position.
    pub fn ekf_ok(&self, now: Instant) -> bool {
        now.saturating_duration_since(self.boot) >= self.env.ekf_fix_delay
    }

    /// The estimated (reported) local position: truth plus estimator noise, plus the
    /// GNSS receiver's error as the EKF follows it (with `gnss_wander`).
    pub fn est_pos(&self) -> Ned {
        let est = self.pos + self.est_noise;
        if self.gnss.wanders() {
            est + self.gnss.est_error()
        } else {
            est
        }
    }

    /// The position PX4's navigator and commander work with (holds, take-off, land,
    /// RTL, home, offset setpoints): the truth plus the GNSS receiver's error as the EKF
    /// carries it (with `gnss_wander`; the estimator noise is left out, as it always was).
    pub fn nav_pos(&self) -> Ned {
        if self.gnss.wanders() {
            self.pos + self.gnss.est_error()
        } else {
            self.pos
        }
    }

    /// The estimated (reported) velocity, NED m/s: truth plus the estimator's velocity
    /// error and vertical bias.
    pub fn est_vel(&self) -> Ned {
        self.vel + self.est_vel_noise + Ned::new(0.0, 0.0, self.est_vz_bias_m_s)
    }

    /// Geodetic position of a local NED point.
    pub fn geo_of(&self, local: Ned) -> GeoPoint {
        self.origin.to_geo(local)
    }

    /// Height above home, m (positive up).
    pub fn height_above_home_m(&self) -> f64 {
        self.home_local.down_m - self.nav_pos().down_m
    }

    /// `MAV_LANDED_STATE` as PX4 reports it.
    pub fn landed_state(&self) -> LandedState {
        if self.landed {
            return LandedState::OnGround;
        }
        match self.mode {
            Px4Mode::Takeoff => LandedState::Takeoff,
            Px4Mode::Land | Px4Mode::Precland => LandedState::Landing,
            Px4Mode::Rtl if self.rtl_phase == RtlPhase::Land => LandedState::Landing,
            _ => LandedState::InAir,
        }
    }

    /// Collective thrust, normalised so hover is 0.5 (0 when disarmed).
    pub fn thrust_norm(&self) -> f64 {
        if !self.armed {
            return 0.0;
        }
        if self.landed && matches!(self.goal, Goal::Idle) {
            return 0.1;
        }
        let f = Ned::new(
            self.thrust_acc.north_m,
            self.thrust_acc.east_m,
            self.thrust_acc.down_m,
        );
        (f.norm() / (2.0 * GRAVITY_M_S2)).clamp(0.0, 1.0)
    }

    /// Advances the vehicle by `dt_s` (fixed step) at wall time `now`.
    pub fn step(&mut self, now: Instant, dt_s: f64, out: &mut Outbox) {
        if !self.has_fix && self.ekf_ok(now) {
            self.has_fix = true;
            self.set_home_here(now, out);
        }
        self.check_links(now, out);
        self.check_offboard_loss(now, out);
        self.check_geofence(now, out);
        self.mission_timers(now, out);
        self.update_navigation(now, out);
        self.goal = self.compute_goal();
        self.physics(dt_s);
        self.land_detector(now, dt_s, out);
        self.auto_disarm(now, out);
        self.update_battery(dt_s);
        self.update_noise(dt_s);
        self.gnss.step(now, dt_s, &mut self.counters.rtcm);
        self.record_flight_log(now);
        self.log_handler_send(dt_s, out);
        self.health_tick(now, out);
        self.events_tick(now, out);
        self.ftp_send(now, dt_s, out);
        self.link.update_rates(now);
    }
}
