//! One simulated PX4 multicopter, without I/O: the MAVLink message handling (commands,
//! parameters, setpoints, heartbeats), PX4's mode and arming logic, failsafes, a point-mass
//! model with a PX4-like position controller, land detection and a battery.
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
use crate::params::{PARAM_COUNT, Param, ParamValue, Params};
use crate::telemetry::Streams;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use skein_mavlink::dialect::*;
use skein_mavlink::{Encoder, Frame, MavMessage};
use skein_model::geo::{GeoPoint, Ned, NedFrame, wrap_pi};
use skein_model::px4::{FORCE_ARM_DISARM_MAGIC, LandedState, Px4Mode, type_mask};
use std::time::{Duration, Instant};

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
/// Aerodynamic drag per unit of air-relative velocity, 1/s.
const DRAG_PER_S: f64 = 0.1;
/// Gust and estimator-noise time constants, s.
const GUST_TAU_S: f64 = 2.0;
const EST_NOISE_TAU_S: f64 = 5.0;
/// Velocity-loop gains (PX4 MPC_XY_VEL_P/I_ACC, MPC_Z_VEL_P/I_ACC defaults).
const VEL_P_XY: f64 = 1.8;
const VEL_I_XY: f64 = 0.4;
const VEL_P_Z: f64 = 4.0;
const VEL_I_Z: f64 = 2.0;
/// Land detector: time at ground contact before "landed", s.
const LAND_DETECT_S: f64 = 0.5;
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
    pub yaw_rad: Option<f64>,
    pub yaw_rate_rad_s: Option<f64>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum RtlPhase {
    Climb,
    Return,
    Land,
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
    pub xy_max_m_s: f64,
    pub up_max_m_s: f64,
    pub down_max_m_s: f64,
    pub yaw: YawGoal,
    pub yaw_rate_max_rad_s: f64,
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
    pub commands_received: u64,
    pub statustexts_sent: u64,
    pub statustexts_suppressed: u64,
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

/// A simple LiPo pack.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Battery {
    pub consumed_mah: f64,
    pub current_a: f64,
    pub voltage_v: f64,
    pub remaining: f64,
}

/// The command fields common to COMMAND_LONG and COMMAND_INT.
#[derive(Debug, Clone, Copy)]
struct Command {
    command: MavCmd,
    params: [f32; 7],
    /// COMMAND_INT's frame and integer x/y (degE7 for global frames).
    int_xy: Option<(MavFrame, i32, i32)>,
    confirmation: u8,
    src_sysid: u8,
    src_compid: u8,
}

#[derive(Debug, Clone, Copy)]
struct LastCommand {
    command: MavCmd,
    src: (u8, u8),
    at: Instant,
    acks: [Option<MavResult>; 2],
}

/// What a command asks for after its ACK(s).
#[derive(Debug, Clone, Copy)]
enum Followup {
    Message(u32),
    MessageInterval(u32),
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

    // Controller.
    vel_sp_smooth: Ned,
    vel_int: Ned,
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
            vel_sp_smooth: Ned::ZERO,
            vel_int: Ned::ZERO,
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

    /// PX4 reboot: everything but the counters starts over (state, boot time, streams).
    pub fn reboot(&mut self, now: Instant) {
        let counters = self.counters;
        let intervals = std::mem::take(&mut self.setpoint_intervals);
        let fresh = Vehicle::new(self.sysid, self.origin.origin, self.env.clone(), now);
        *self = fresh;
        self.counters = counters;
        self.setpoint_intervals = intervals;
    }

    // ---------------------------------------------------------------- queries

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

    /// The estimated (reported) local position: truth plus estimator noise.
    pub fn est_pos(&self) -> Ned {
        self.pos + self.est_noise
    }

    /// Geodetic position of a local NED point.
    pub fn geo_of(&self, local: Ned) -> GeoPoint {
        self.origin.to_geo(local)
    }

    /// Height above home, m (positive up).
    pub fn height_above_home_m(&self) -> f64 {
        self.home_local.down_m - self.pos.down_m
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

    fn gcs_recent(&self, now: Instant) -> bool {
        self.heartbeats
            .gcs
            .is_some_and(|t| now.saturating_duration_since(t) <= STATUSTEXT_GCS_WINDOW)
    }

    /// True while a GCS heartbeat arrived within PX4's 1.5 s heartbeat timeout.
    pub fn gcs_connected(&self, now: Instant) -> bool {
        self.heartbeats
            .gcs
            .is_some_and(|t| now.saturating_duration_since(t) <= HEARTBEAT_TIMEOUT)
    }

    /// True while an onboard-controller heartbeat arrived within 1.5 s.
    pub fn onboard_controller_connected(&self, now: Instant) -> bool {
        self.heartbeats
            .onboard_controller
            .is_some_and(|t| now.saturating_duration_since(t) <= HEARTBEAT_TIMEOUT)
    }

    /// PX4's "offboard available": the last setpoint is younger than COM_OF_LOSS_T
    /// (PX4 v1.16 `offboardCheck.cpp`); with [`Environment::offboard_min_stream`] set,
    /// the stream must also have run that long at > 2 Hz (the rule PX4's docs state).
    pub fn offboard_available(&self, now: Instant) -> bool {
        let loss = Duration::from_secs_f64(self.params.get(Param::COM_OF_LOSS_T).max(0.0));
        let Some(last) = self.setpoint_last else {
            return false;
        };
        let age = now.saturating_duration_since(last);
        if age >= loss {
            return false;
        }
        if self.env.offboard_min_stream.is_zero() {
            return true;
        }
        age <= OFFBOARD_MAX_GAP
            && self
                .setpoint_stream_start
                .is_some_and(|s| now.saturating_duration_since(s) >= self.env.offboard_min_stream)
    }

    fn arming_denied_reason(&self, now: Instant) -> Option<&'static str> {
        if !self.ekf_ok(now) {
            return Some("Arming denied: no valid global position");
        }
        match self.mode {
            Px4Mode::Land | Px4Mode::Precland => {
                Some("Arming denied: Land mode does not allow arming")
            }
            Px4Mode::Rtl => Some("Arming denied: Return mode does not allow arming"),
            Px4Mode::Mission => Some("Arming denied: no valid mission"),
            Px4Mode::Offboard if !self.offboard_available(now) => {
                Some("Arming denied: no offboard signal")
            }
            Px4Mode::Unknown(_) | Px4Mode::FollowTarget | Px4Mode::Ready => {
                Some("Arming denied: mode not available")
            }
            _ => None,
        }
    }

    /// True when PX4's pre-arm checks pass in the current state (SYS_STATUS PREARM_CHECK).
    pub fn prearm_ok(&self, now: Instant) -> bool {
        self.armed || self.arming_denied_reason(now).is_none()
    }

    fn mode_denied_reason(&self, now: Instant, mode: Px4Mode) -> Option<&'static str> {
        match mode {
            Px4Mode::Offboard if !self.offboard_available(now) => {
                Some("Switching to Offboard is currently not available")
            }
            Px4Mode::Mission => Some("Switching to Mission is currently not available"),
            Px4Mode::FollowTarget | Px4Mode::Ready | Px4Mode::Unknown(_) => {
                Some("Switching to this mode is currently not available")
            }
            Px4Mode::Hold | Px4Mode::Takeoff | Px4Mode::Rtl | Px4Mode::Posctl
                if !self.ekf_ok(now) =>
            {
                Some("No valid global position")
            }
            _ => None,
        }
    }

    // ---------------------------------------------------------------- output helpers

    fn statustext(&mut self, now: Instant, severity: MavSeverity, text: &str, out: &mut Outbox) {
        if !self.gcs_recent(now) {
            self.counters.statustexts_suppressed += 1;
            return;
        }
        self.counters.statustexts_sent += 1;
        out.push(&MavMessage::STATUSTEXT(STATUSTEXT_DATA {
            severity,
            text: text.into(),
            id: 0,
            chunk_seq: 0,
        }));
    }

    fn ack(&self, cmd: &Command, result: MavResult, out: &mut Outbox) {
        out.push(&MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command: cmd.command,
            result,
            progress: 0,
            result_param2: 0,
            target_system: cmd.src_sysid,
            target_component: cmd.src_compid,
        }));
    }

    fn param_value(&self, index: usize, out: &mut Outbox) {
        let (Some(name), Some(value)) = (Params::name_at(index), self.params.value_at(index))
        else {
            return;
        };
        let (param_value, param_type) = value.to_wire();
        out.push(&MavMessage::PARAM_VALUE(PARAM_VALUE_DATA {
            param_value,
            param_count: PARAM_COUNT as u16,
            param_index: index as u16,
            param_id: name.into(),
            param_type,
        }));
    }

    fn targets_me(&self, target_system: u8, target_component: u8) -> bool {
        (target_system == 0 || target_system == self.sysid)
            && (target_component == 0 || target_component == 1)
    }

    // ---------------------------------------------------------------- input

    /// Handles one received frame.
    pub fn handle_frame(&mut self, now: Instant, frame: &Frame, out: &mut Outbox) {
        self.counters.frames_received += 1;
        self.link.rx_frames += 1;
        if frame.sysid == self.sysid && frame.compid == 1 {
            return; // our own frames echoed back
        }
        match &frame.msg {
            MavMessage::HEARTBEAT(hb) => self.on_heartbeat(now, hb),
            MavMessage::COMMAND_LONG(c) if self.targets_me(c.target_system, c.target_component) => {
                let cmd = Command {
                    command: c.command,
                    params: [
                        c.param1, c.param2, c.param3, c.param4, c.param5, c.param6, c.param7,
                    ],
                    int_xy: None,
                    confirmation: c.confirmation,
                    src_sysid: frame.sysid,
                    src_compid: frame.compid,
                };
                self.on_command(now, cmd, out);
            }
            MavMessage::COMMAND_INT(c) if self.targets_me(c.target_system, c.target_component) => {
                let cmd = Command {
                    command: c.command,
                    params: [
                        c.param1, c.param2, c.param3, c.param4, c.x as f32, c.y as f32, c.z,
                    ],
                    int_xy: Some((c.frame, c.x, c.y)),
                    confirmation: 0,
                    src_sysid: frame.sysid,
                    src_compid: frame.compid,
                };
                self.on_command(now, cmd, out);
            }
            MavMessage::SET_POSITION_TARGET_LOCAL_NED(sp) => self.on_setpoint_local(now, sp),
            MavMessage::SET_POSITION_TARGET_GLOBAL_INT(sp) => self.on_setpoint_global(now, sp),
            MavMessage::PARAM_REQUEST_READ(r)
                if self.targets_me(r.target_system, r.target_component) =>
            {
                let index = if r.param_index >= 0 {
                    Some(r.param_index as usize).filter(|&i| i < PARAM_COUNT)
                } else {
                    r.param_id.to_str().ok().and_then(Params::index_of)
                };
                if let Some(i) = index {
                    self.param_value(i, out);
                }
            }
            MavMessage::PARAM_REQUEST_LIST(r)
                if self.targets_me(r.target_system, r.target_component) =>
            {
                for i in 0..PARAM_COUNT {
                    self.param_value(i, out);
                }
            }
            MavMessage::PARAM_SET(s) if self.targets_me(s.target_system, s.target_component) => {
                self.on_param_set(now, s, out);
            }
            MavMessage::PING(p) if p.target_system == 0 && p.target_component == 0 => {
                // A ping request: answer it, addressed to the requester.
                out.push(&MavMessage::PING(PING_DATA {
                    time_usec: p.time_usec,
                    seq: p.seq,
                    target_system: frame.sysid,
                    target_component: frame.compid,
                }));
            }
            MavMessage::TIMESYNC(t) if t.tc1 == 0 => {
                // A timesync request: tc1 = our time (ns), ts1 echoed.
                out.push(&MavMessage::TIMESYNC(TIMESYNC_DATA {
                    tc1: self.time_boot_us(now) as i64 * 1000,
                    ts1: t.ts1,
                    target_system: frame.sysid,
                    target_component: frame.compid,
                }));
            }
            MavMessage::SET_MODE(m)
                if m.target_system == self.sysid
                    && m.base_mode
                        .contains(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED) =>
            {
                let mode = Px4Mode::from_custom_mode(m.custom_mode);
                if let Err(reason) = self.request_mode(now, mode) {
                    self.statustext(now, MavSeverity::MAV_SEVERITY_CRITICAL, reason, out);
                }
            }
            MavMessage::MISSION_REQUEST_LIST(m)
                if self.targets_me(m.target_system, m.target_component) =>
            {
                // No mission: an empty list, so ground stations finish their download.
                out.push(&MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
                    count: 0,
                    target_system: frame.sysid,
                    target_component: frame.compid,
                    mission_type: m.mission_type,
                    opaque_id: 0,
                }));
            }
            _ => {}
        }
    }

    fn on_heartbeat(&mut self, now: Instant, hb: &HEARTBEAT_DATA) {
        match hb.mavtype {
            MavType::MAV_TYPE_GCS => {
                self.heartbeats.gcs = Some(now);
                self.gcs_lost = false;
            }
            MavType::MAV_TYPE_ONBOARD_CONTROLLER => {
                self.heartbeats.onboard_controller = Some(now);
            }
            MavType::MAV_TYPE_GIMBAL => self.heartbeats.gimbal = Some(now),
            MavType::MAV_TYPE_CAMERA => self.heartbeats.camera = Some(now),
            _ => {}
        }
    }

    fn on_param_set(&mut self, now: Instant, s: &PARAM_SET_DATA, out: &mut Outbox) {
        let Some(index) = s.param_id.to_str().ok().and_then(Params::index_of) else {
            return; // PX4 ignores unknown parameters
        };
        let Some(current) = self.params.value_at(index) else {
            return;
        };
        let new = current.with_wire_value(s.param_value);
        let valid = match new {
            ParamValue::Real32(f) => f.is_finite(),
            ParamValue::Int32(_) => true,
        };
        if valid {
            self.params.set_at(index, new);
            // PX4 answers a PARAM_SET right away and again when the change notification
            // goes round: two PARAM_VALUEs.
            self.param_value(index, out);
            self.param_value(index, out);
        } else {
            self.statustext(
                now,
                MavSeverity::MAV_SEVERITY_WARNING,
                "Parameter value rejected",
                out,
            );
            self.param_value(index, out);
        }
    }

    fn record_setpoint(&mut self, now: Instant, sp: Setpoint) {
        self.counters.setpoints_received += 1;
        match self.setpoint_last {
            Some(last) => {
                let gap = now.saturating_duration_since(last);
                self.setpoint_intervals.record(gap);
                self.counters.setpoint_max_gap = self.counters.setpoint_max_gap.max(gap);
                if self.mode == Px4Mode::Offboard {
                    self.counters.setpoint_max_gap_offboard =
                        self.counters.setpoint_max_gap_offboard.max(gap);
                }
                if gap > OFFBOARD_MAX_GAP {
                    self.setpoint_stream_start = Some(now);
                }
            }
            None => self.setpoint_stream_start = Some(now),
        }
        self.setpoint_last = Some(now);
        self.setpoint = Some(sp);
    }

    fn on_setpoint_local(&mut self, now: Instant, sp: &SET_POSITION_TARGET_LOCAL_NED_DATA) {
        if !self.targets_me(sp.target_system, sp.target_component) {
            return;
        }
        let mask = sp.type_mask.bits();
        let field = |bit: u16, v: f32| (mask & bit == 0 && v.is_finite()).then_some(f64::from(v));
        let mut pos = [
            field(type_mask::IGNORE_PX, sp.x),
            field(type_mask::IGNORE_PY, sp.y),
            field(type_mask::IGNORE_PZ, sp.z),
        ];
        let mut vel = [
            field(type_mask::IGNORE_VX, sp.vx),
            field(type_mask::IGNORE_VY, sp.vy),
            field(type_mask::IGNORE_VZ, sp.vz),
        ];
        match sp.coordinate_frame {
            MavFrame::MAV_FRAME_LOCAL_NED => {}
            MavFrame::MAV_FRAME_LOCAL_OFFSET_NED => {
                for (i, p) in pos.iter_mut().enumerate() {
                    *p = p.map(|d| d + axis(&self.pos, i));
                }
            }
            MavFrame::MAV_FRAME_BODY_NED | MavFrame::MAV_FRAME_BODY_OFFSET_NED => {
                let rot = |v: [Option<f64>; 3]| -> [Option<f64>; 3] {
                    let r = Ned::new(v[0].unwrap_or(0.0), v[1].unwrap_or(0.0), 0.0)
                        .rotated_yaw(self.yaw_rad);
                    let both = v[0].is_some() || v[1].is_some();
                    [both.then_some(r.north_m), both.then_some(r.east_m), v[2]]
                };
                vel = rot(vel);
                pos = rot(pos);
                for (i, p) in pos.iter_mut().enumerate() {
                    *p = p.map(|d| d + axis(&self.pos, i));
                }
            }
            _ => return, // PX4 ignores other frames for multicopters
        }
        let setpoint = Setpoint {
            pos,
            vel,
            yaw_rad: field(type_mask::IGNORE_YAW, sp.yaw),
            yaw_rate_rad_s: field(type_mask::IGNORE_YAW_RATE, sp.yaw_rate),
        };
        self.record_setpoint(now, setpoint);
    }

    fn on_setpoint_global(&mut self, now: Instant, sp: &SET_POSITION_TARGET_GLOBAL_INT_DATA) {
        if !self.targets_me(sp.target_system, sp.target_component) {
            return;
        }
        let mask = sp.type_mask.bits();
        let ignore_pos = mask & type_mask::IGNORE_POSITION == type_mask::IGNORE_POSITION;
        let alt_amsl = match sp.coordinate_frame {
            MavFrame::MAV_FRAME_GLOBAL_INT | MavFrame::MAV_FRAME_GLOBAL => f64::from(sp.alt),
            MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
            | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT
            | MavFrame::MAV_FRAME_GLOBAL_TERRAIN_ALT_INT
            | MavFrame::MAV_FRAME_GLOBAL_TERRAIN_ALT => self.home.alt_amsl_m + f64::from(sp.alt),
            _ => return,
        };
        let local = if ignore_pos {
            Ned::ZERO
        } else {
            self.origin.to_ned(&GeoPoint::new(
                f64::from(sp.lat_int) * 1e-7,
                f64::from(sp.lon_int) * 1e-7,
                alt_amsl,
            ))
        };
        let field = |bit: u16, v: f64| (mask & bit == 0 && v.is_finite()).then_some(v);
        let setpoint = Setpoint {
            pos: [
                field(type_mask::IGNORE_PX, local.north_m),
                field(type_mask::IGNORE_PY, local.east_m),
                field(type_mask::IGNORE_PZ, local.down_m),
            ],
            vel: [
                field(type_mask::IGNORE_VX, f64::from(sp.vx)),
                field(type_mask::IGNORE_VY, f64::from(sp.vy)),
                field(type_mask::IGNORE_VZ, f64::from(sp.vz)),
            ],
            yaw_rad: field(type_mask::IGNORE_YAW, f64::from(sp.yaw)),
            yaw_rate_rad_s: field(type_mask::IGNORE_YAW_RATE, f64::from(sp.yaw_rate)),
        };
        self.record_setpoint(now, setpoint);
    }

    // ---------------------------------------------------------------- commands

    fn on_command(&mut self, now: Instant, cmd: Command, out: &mut Outbox) {
        self.counters.commands_received += 1;
        if cmd.confirmation > 0
            && let Some(last) = self.last_command
            && last.command == cmd.command
            && last.src == (cmd.src_sysid, cmd.src_compid)
            && now.saturating_duration_since(last.at) <= COMMAND_DEDUP_WINDOW
        {
            // A retransmission of a command already executed: answer again, do not
            // execute twice.
            for result in last.acks.into_iter().flatten() {
                self.ack(&cmd, result, out);
            }
            return;
        }
        let (first, second, followup) = self.execute(now, &cmd, out);
        self.ack(&cmd, first, out);
        if let Some(second) = second {
            self.ack(&cmd, second, out);
        }
        self.last_command = Some(LastCommand {
            command: cmd.command,
            src: (cmd.src_sysid, cmd.src_compid),
            at: now,
            acks: [Some(first), second],
        });
        match followup {
            Some(Followup::Message(id)) => {
                self.send_message_now(now, id, out);
            }
            Some(Followup::MessageInterval(id)) => {
                let interval_us = self.streams.interval_report_us(id);
                out.push(&MavMessage::MESSAGE_INTERVAL(MESSAGE_INTERVAL_DATA {
                    interval_us,
                    message_id: id as u16,
                }));
            }
            None => {}
        }
    }

    fn execute(
        &mut self,
        now: Instant,
        cmd: &Command,
        out: &mut Outbox,
    ) -> (MavResult, Option<MavResult>, Option<Followup>) {
        use MavResult::*;
        let p = cmd.params;
        match cmd.command {
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM => {
                let force = (p[1] - FORCE_ARM_DISARM_MAGIC).abs() < 0.5;
                (self.arm_disarm(now, p[0] > 0.5, force, out), None, None)
            }
            MavCmd::MAV_CMD_DO_SET_MODE => {
                // PX4 acknowledges twice: ACCEPTED first, then the real result.
                let second = if (p[0] as u32) & 1 == 0 {
                    MAV_RESULT_DENIED
                } else {
                    match Px4Mode::from_main_sub(p[1] as u8, p[2] as u8) {
                        None => MAV_RESULT_DENIED,
                        Some(mode) => match self.request_mode(now, mode) {
                            Ok(()) => MAV_RESULT_ACCEPTED,
                            Err(reason) => {
                                self.statustext(
                                    now,
                                    MavSeverity::MAV_SEVERITY_CRITICAL,
                                    reason,
                                    out,
                                );
                                MAV_RESULT_TEMPORARILY_REJECTED
                            }
                        },
                    }
                };
                (MAV_RESULT_ACCEPTED, Some(second), None)
            }
            MavCmd::MAV_CMD_NAV_TAKEOFF => (self.takeoff(now, p[6], out), None, None),
            MavCmd::MAV_CMD_NAV_LAND => (self.mode_command(now, Px4Mode::Land, out), None, None),
            MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH => {
                (self.mode_command(now, Px4Mode::Rtl, out), None, None)
            }
            MavCmd::MAV_CMD_NAV_LOITER_UNLIM => {
                (self.mode_command(now, Px4Mode::Hold, out), None, None)
            }
            MavCmd::MAV_CMD_DO_REPOSITION => (self.reposition(now, cmd, out), None, None),
            MavCmd::MAV_CMD_DO_CHANGE_SPEED => {
                if p[1] > 0.0 && p[1].is_finite() {
                    self.auto_speed_m_s = Some(f64::from(p[1]));
                }
                (MAV_RESULT_ACCEPTED, None, None)
            }
            MavCmd::MAV_CMD_DO_SET_HOME => {
                if p[0] > 0.5 {
                    self.set_home_here(now, out);
                } else if p[4].is_finite() && p[5].is_finite() && p[6].is_finite() {
                    let (lat, lon) = match cmd.int_xy {
                        Some((_, x, y)) => (f64::from(x) * 1e-7, f64::from(y) * 1e-7),
                        None => (f64::from(p[4]), f64::from(p[5])),
                    };
                    self.home = GeoPoint::new(lat, lon, f64::from(p[6]));
                    self.home_local = self.origin.to_ned(&self.home);
                    self.streams
                        .force(crate::telemetry::Stream::HomePosition, now);
                } else {
                    return (MAV_RESULT_DENIED, None, None);
                }
                (MAV_RESULT_ACCEPTED, None, None)
            }
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL => {
                let id = p[0] as u32;
                let result = if self.streams.set_interval(id, p[1], now) {
                    MAV_RESULT_ACCEPTED
                } else {
                    MAV_RESULT_DENIED
                };
                (result, None, None)
            }
            MavCmd::MAV_CMD_GET_MESSAGE_INTERVAL => (
                MAV_RESULT_ACCEPTED,
                None,
                Some(Followup::MessageInterval(p[0] as u32)),
            ),
            MavCmd::MAV_CMD_REQUEST_MESSAGE => {
                let id = p[0] as u32;
                if self.can_send_message(now, id) {
                    (MAV_RESULT_ACCEPTED, None, Some(Followup::Message(id)))
                } else if crate::telemetry::is_known_message(id) {
                    (MAV_RESULT_TEMPORARILY_REJECTED, None, None)
                } else {
                    (MAV_RESULT_UNSUPPORTED, None, None)
                }
            }
            MavCmd::MAV_CMD_GET_HOME_POSITION => {
                if self.has_fix {
                    (
                        MAV_RESULT_ACCEPTED,
                        None,
                        Some(Followup::Message(crate::telemetry::HOME_POSITION_ID)),
                    )
                } else {
                    (MAV_RESULT_TEMPORARILY_REJECTED, None, None)
                }
            }
            MavCmd::MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES => (
                MAV_RESULT_ACCEPTED,
                None,
                Some(Followup::Message(crate::telemetry::AUTOPILOT_VERSION_ID)),
            ),
            MavCmd::MAV_CMD_REQUEST_PROTOCOL_VERSION => (
                MAV_RESULT_ACCEPTED,
                None,
                Some(Followup::Message(crate::telemetry::PROTOCOL_VERSION_ID)),
            ),
            MavCmd::MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN => {
                if p[0].round() as i32 == 1 {
                    if self.armed {
                        (MAV_RESULT_DENIED, None, None)
                    } else {
                        self.reboot_requested = true;
                        (MAV_RESULT_ACCEPTED, None, None)
                    }
                } else {
                    (MAV_RESULT_UNSUPPORTED, None, None)
                }
            }
            MavCmd::MAV_CMD_DO_FLIGHTTERMINATION => {
                if p[0] > 0.5 {
                    self.disarm(now, "Flight termination", out);
                }
                (MAV_RESULT_ACCEPTED, None, None)
            }
            MavCmd::MAV_CMD_MISSION_START => {
                self.statustext(
                    now,
                    MavSeverity::MAV_SEVERITY_CRITICAL,
                    "Mission start denied: no valid mission",
                    out,
                );
                (MAV_RESULT_DENIED, None, None)
            }
            _ => (MAV_RESULT_UNSUPPORTED, None, None),
        }
    }

    fn mode_command(&mut self, now: Instant, mode: Px4Mode, out: &mut Outbox) -> MavResult {
        match self.request_mode(now, mode) {
            Ok(()) => MavResult::MAV_RESULT_ACCEPTED,
            Err(reason) => {
                self.statustext(now, MavSeverity::MAV_SEVERITY_CRITICAL, reason, out);
                MavResult::MAV_RESULT_TEMPORARILY_REJECTED
            }
        }
    }

    fn arm_disarm(&mut self, now: Instant, arm: bool, force: bool, out: &mut Outbox) -> MavResult {
        if arm {
            if self.armed {
                return MavResult::MAV_RESULT_ACCEPTED;
            }
            if !force && let Some(reason) = self.arming_denied_reason(now) {
                self.statustext(now, MavSeverity::MAV_SEVERITY_CRITICAL, reason, out);
                return MavResult::MAV_RESULT_TEMPORARILY_REJECTED;
            }
            self.arm(now, out);
            MavResult::MAV_RESULT_ACCEPTED
        } else {
            if !self.armed {
                return MavResult::MAV_RESULT_ACCEPTED;
            }
            if !self.landed && !force {
                self.statustext(
                    now,
                    MavSeverity::MAV_SEVERITY_CRITICAL,
                    "Disarming denied: not landed",
                    out,
                );
                return MavResult::MAV_RESULT_DENIED;
            }
            self.disarm(now, "Disarmed by external command", out);
            MavResult::MAV_RESULT_ACCEPTED
        }
    }

    fn arm(&mut self, now: Instant, out: &mut Outbox) {
        self.armed = true;
        self.armed_at = now;
        self.took_off = false;
        self.landed_at = None;
        self.vel_int = Ned::ZERO;
        self.vel_sp_smooth = self.vel;
        if self.landed {
            // PX4 sets home where it arms.
            self.set_home_here(now, out);
        }
        if matches!(
            self.mode,
            Px4Mode::Hold
                | Px4Mode::Posctl
                | Px4Mode::Altctl
                | Px4Mode::Manual
                | Px4Mode::Stabilized
                | Px4Mode::Acro
        ) {
            self.hold_pos = self.pos;
        }
        self.statustext(
            now,
            MavSeverity::MAV_SEVERITY_INFO,
            "Armed by external command",
            out,
        );
    }

    fn disarm(&mut self, now: Instant, reason: &str, out: &mut Outbox) {
        self.armed = false;
        self.failsafe = false;
        self.statustext(now, MavSeverity::MAV_SEVERITY_INFO, reason, out);
    }

    fn set_home_here(&mut self, now: Instant, out: &mut Outbox) {
        let _ = out;
        self.home_local = self.pos;
        self.home = self.origin.to_geo(self.pos);
        self.home_yaw_rad = self.yaw_rad;
        self.streams
            .force(crate::telemetry::Stream::HomePosition, now);
    }

    /// Switches mode if PX4 would allow it; `Err` carries PX4's refusal text.
    fn request_mode(&mut self, now: Instant, mode: Px4Mode) -> Result<(), &'static str> {
        if let Some(reason) = self.mode_denied_reason(now, mode) {
            return Err(reason);
        }
        if mode != self.mode || self.failsafe {
            self.enter_mode(mode);
        }
        self.failsafe = false;
        Ok(())
    }

    fn braking_point(&self) -> Ned {
        if self.landed {
            return self.pos;
        }
        let acc_h = self.params.get(Param::MPC_ACC_HOR).max(0.5);
        let vh = self.vel.horizontal_norm();
        let k = vh / (2.0 * acc_h);
        let vz = self.vel.down_m;
        let dz = vz * vz.abs() / (2.0 * 3.0);
        Ned::new(
            self.pos.north_m + self.vel.north_m * k,
            self.pos.east_m + self.vel.east_m * k,
            (self.pos.down_m + dz).min(0.0),
        )
    }

    fn enter_mode(&mut self, mode: Px4Mode) {
        self.mode = mode;
        match mode {
            Px4Mode::Takeoff => {
                self.takeoff_z = self.home_local.down_m - self.params.get(Param::MIS_TAKEOFF_ALT);
                self.hold_pos = self.pos;
                self.hold_yaw = YawGoal::Heading(self.yaw_rad);
            }
            Px4Mode::Land | Px4Mode::Precland => {
                self.land_xy = (self.pos.north_m, self.pos.east_m);
                self.hold_yaw = YawGoal::Heading(self.yaw_rad);
            }
            Px4Mode::Rtl => {
                self.rtl_phase = RtlPhase::Climb;
                let return_z = self.home_local.down_m - self.params.get(Param::RTL_RETURN_ALT);
                self.rtl_z = return_z.min(self.pos.down_m);
                self.rtl_start = self.pos;
                self.hold_yaw = YawGoal::Heading(self.yaw_rad);
            }
            Px4Mode::Offboard => {
                self.hold_pos = self.pos;
                self.hold_yaw = YawGoal::Heading(self.yaw_rad);
            }
            _ => {
                self.hold_pos = self.braking_point();
                self.hold_yaw = YawGoal::Heading(self.yaw_rad);
                self.auto_speed_m_s = None;
            }
        }
    }

    fn takeoff(&mut self, now: Instant, alt_amsl_m: f32, out: &mut Outbox) -> MavResult {
        if let Some(reason) = self.mode_denied_reason(now, Px4Mode::Takeoff) {
            self.statustext(now, MavSeverity::MAV_SEVERITY_CRITICAL, reason, out);
            return MavResult::MAV_RESULT_TEMPORARILY_REJECTED;
        }
        self.enter_mode(Px4Mode::Takeoff);
        self.failsafe = false;
        if alt_amsl_m.is_finite() {
            self.takeoff_z = -(f64::from(alt_amsl_m) - self.origin.origin.alt_amsl_m);
        }
        MavResult::MAV_RESULT_ACCEPTED
    }

    fn reposition(&mut self, now: Instant, cmd: &Command, out: &mut Outbox) -> MavResult {
        if let Some(reason) = self.mode_denied_reason(now, Px4Mode::Hold) {
            self.statustext(now, MavSeverity::MAV_SEVERITY_CRITICAL, reason, out);
            return MavResult::MAV_RESULT_TEMPORARILY_REJECTED;
        }
        let p = cmd.params;
        let current = self.origin.to_geo(self.pos);
        let (lat, lon, alt) = match cmd.int_xy {
            Some((frame, x, y)) => {
                let alt = match frame {
                    MavFrame::MAV_FRAME_GLOBAL | MavFrame::MAV_FRAME_GLOBAL_INT => f64::from(p[6]),
                    MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT
                    | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT => {
                        self.home.alt_amsl_m + f64::from(p[6])
                    }
                    _ => return MavResult::MAV_RESULT_UNSUPPORTED,
                };
                let unset = |v: i32| v == i32::MAX || (x == 0 && y == 0);
                (
                    if unset(x) {
                        current.lat_deg
                    } else {
                        f64::from(x) * 1e-7
                    },
                    if unset(y) {
                        current.lon_deg
                    } else {
                        f64::from(y) * 1e-7
                    },
                    alt,
                )
            }
            None => (f64::from(p[4]), f64::from(p[5]), f64::from(p[6])),
        };
        let target = GeoPoint::new(
            if lat.is_finite() {
                lat
            } else {
                current.lat_deg
            },
            if lon.is_finite() {
                lon
            } else {
                current.lon_deg
            },
            if alt.is_finite() {
                alt
            } else {
                current.alt_amsl_m
            },
        );
        let mut local = self.origin.to_ned(&target);
        local.down_m = local.down_m.min(0.0);
        self.enter_mode(Px4Mode::Hold);
        self.failsafe = false;
        if self.armed && !self.landed {
            self.hold_pos = local;
            self.auto_speed_m_s = (p[0] > 0.0 && p[0].is_finite()).then_some(f64::from(p[0]));
            let to = local - self.pos;
            self.hold_yaw = if p[3].is_finite() {
                YawGoal::Heading(f64::from(p[3]).to_radians())
            } else if to.horizontal_norm() > 2.0 {
                YawGoal::Heading(to.east_m.atan2(to.north_m))
            } else {
                YawGoal::Heading(self.yaw_rad)
            };
        }
        MavResult::MAV_RESULT_ACCEPTED
    }

    // ---------------------------------------------------------------- simulation

    /// Advances the vehicle by `dt_s` (fixed step) at wall time `now`.
    pub fn step(&mut self, now: Instant, dt_s: f64, out: &mut Outbox) {
        if !self.has_fix && self.ekf_ok(now) {
            self.has_fix = true;
            self.set_home_here(now, out);
        }
        self.check_links(now, out);
        self.check_offboard_loss(now, out);
        self.update_navigation(now, out);
        self.goal = self.compute_goal();
        self.physics(dt_s);
        self.land_detector(now, dt_s, out);
        self.auto_disarm(now, out);
        self.update_battery(dt_s);
        self.update_noise(dt_s);
        self.link.update_rates(now);
    }

    fn failsafe_to(&mut self, mode: Px4Mode) {
        self.enter_mode(mode);
        self.failsafe = true;
    }

    fn check_offboard_loss(&mut self, now: Instant, out: &mut Outbox) {
        if self.mode != Px4Mode::Offboard || !self.armed {
            return;
        }
        let loss = Duration::from_secs_f64(self.params.get(Param::COM_OF_LOSS_T).max(0.0));
        let lost = self
            .setpoint_last
            .is_none_or(|t| now.saturating_duration_since(t) > loss);
        if !lost {
            return;
        }
        self.counters.offboard_loss_failsafes += 1;
        let (mode, text) = match self.params.get(Param::COM_OBL_RC_ACT) as i32 {
            3 => (Px4Mode::Rtl, "Failsafe: no offboard signal, returning"),
            5 => (Px4Mode::Hold, "Failsafe: no offboard signal, holding"),
            // 0 Position, 1 Altitude, 2 Manual: without RC PX4 falls back to landing.
            _ => (Px4Mode::Land, "Failsafe: no offboard signal, landing"),
        };
        self.failsafe_to(mode);
        self.statustext(now, MavSeverity::MAV_SEVERITY_CRITICAL, text, out);
    }

    fn check_links(&mut self, now: Instant, out: &mut Outbox) {
        let Some(last) = self.heartbeats.gcs else {
            return;
        };
        if self.gcs_lost {
            return;
        }
        let timeout = Duration::from_secs_f64(self.params.get(Param::COM_DL_LOSS_T).max(0.0));
        if now.saturating_duration_since(last) <= timeout {
            return;
        }
        self.gcs_lost = true;
        if !self.armed {
            return;
        }
        let action = match self.params.get(Param::NAV_DLL_ACT) as i32 {
            1 => Some((Px4Mode::Hold, "Failsafe: GCS connection lost, holding")),
            2 => Some((Px4Mode::Rtl, "Failsafe: GCS connection lost, returning")),
            3 => Some((Px4Mode::Land, "Failsafe: GCS connection lost, landing")),
            5 | 6 => {
                self.counters.gcs_loss_failsafes += 1;
                self.disarm(now, "Failsafe: GCS connection lost, terminating", out);
                None
            }
            _ => None,
        };
        if let Some((mode, text)) = action {
            self.counters.gcs_loss_failsafes += 1;
            self.failsafe_to(mode);
            self.statustext(now, MavSeverity::MAV_SEVERITY_CRITICAL, text, out);
        }
    }

    fn update_navigation(&mut self, now: Instant, out: &mut Outbox) {
        if !self.armed || self.landed {
            return;
        }
        match self.mode {
            Px4Mode::Takeoff
                if (self.pos.down_m - self.takeoff_z).abs() < 0.2
                    || self.pos.down_m < self.takeoff_z =>
            {
                let target = Ned::new(self.hold_pos.north_m, self.hold_pos.east_m, self.takeoff_z);
                let yaw = self.hold_yaw;
                self.enter_mode(Px4Mode::Hold);
                self.hold_pos = target;
                self.hold_yaw = yaw;
                self.statustext(now, MavSeverity::MAV_SEVERITY_INFO, "Takeoff complete", out);
            }
            Px4Mode::Rtl => match self.rtl_phase {
                RtlPhase::Climb => {
                    if self.pos.down_m <= self.rtl_z + 0.5 {
                        self.rtl_phase = RtlPhase::Return;
                        let to = self.home_local - self.pos;
                        if to.horizontal_norm() > 2.0 {
                            self.hold_yaw = YawGoal::Heading(to.east_m.atan2(to.north_m));
                        }
                    }
                }
                RtlPhase::Return => {
                    let to = self.home_local - self.pos;
                    if to.horizontal_norm() < 1.0 && self.vel.horizontal_norm() < 1.0 {
                        self.rtl_phase = RtlPhase::Land;
                        self.land_xy = (self.home_local.north_m, self.home_local.east_m);
                        self.hold_yaw = YawGoal::Heading(self.home_yaw_rad);
                    }
                }
                RtlPhase::Land => {}
            },
            _ => {}
        }
    }

    /// Descent speed PX4 uses when landing at `height_m` above home.
    fn land_speed_m_s(&self, height_m: f64) -> f64 {
        let slow = self.params.get(Param::MPC_LAND_SPEED);
        let fast = self.params.get(Param::MPC_Z_V_AUTO_DN).max(slow);
        let alt1 = self.params.get(Param::MPC_LAND_ALT1);
        let alt2 = self.params.get(Param::MPC_LAND_ALT2).min(alt1);
        if height_m >= alt1 {
            fast
        } else if height_m <= alt2 || alt1 <= alt2 {
            slow
        } else {
            slow + (fast - slow) * (height_m - alt2) / (alt1 - alt2)
        }
    }

    fn offboard_wants_takeoff(&self) -> bool {
        let Some(sp) = self.setpoint else {
            return false;
        };
        sp.pos[2].is_some_and(|z| z < self.pos.down_m - TAKEOFF_DETECT_M)
            || sp.vel[2].is_some_and(|vz| vz < -0.05)
    }

    fn compute_goal(&self) -> Goal {
        if !self.armed {
            return if self.landed {
                Goal::Idle
            } else {
                Goal::FreeFall
            };
        }
        let p = &self.params;
        let cruise = p
            .get(Param::MPC_XY_CRUISE)
            .min(p.get(Param::MPC_XY_VEL_MAX));
        let auto_xy = self
            .auto_speed_m_s
            .unwrap_or(cruise)
            .min(p.get(Param::MPC_XY_VEL_MAX));
        let auto_up = p.get(Param::MPC_Z_V_AUTO_UP);
        let auto_dn = p.get(Param::MPC_Z_V_AUTO_DN);
        let auto_yaw_rate = p.get(Param::MPC_YAWRAUTO_MAX).to_radians();
        let hold = |pos: Ned, yaw: YawGoal| {
            Goal::Track(Track {
                pos: [Some(pos.north_m), Some(pos.east_m), Some(pos.down_m)],
                vel: [None; 3],
                xy_max_m_s: auto_xy,
                up_max_m_s: auto_up,
                down_max_m_s: auto_dn,
                yaw,
                yaw_rate_max_rad_s: auto_yaw_rate,
            })
        };
        let land_at = |x: f64, y: f64, yaw: YawGoal| {
            Goal::Track(Track {
                pos: [Some(x), Some(y), None],
                vel: [
                    None,
                    None,
                    Some(self.land_speed_m_s(self.height_above_home_m())),
                ],
                xy_max_m_s: auto_xy,
                up_max_m_s: auto_up,
                down_max_m_s: auto_dn.max(p.get(Param::MPC_LAND_SPEED)),
                yaw,
                yaw_rate_max_rad_s: auto_yaw_rate,
            })
        };
        let wants_takeoff = match self.mode {
            Px4Mode::Takeoff => self.takeoff_z < self.pos.down_m - TAKEOFF_DETECT_M,
            Px4Mode::Offboard => self.offboard_wants_takeoff(),
            _ => false,
        };
        if self.landed && !wants_takeoff {
            return Goal::Idle;
        }
        match self.mode {
            Px4Mode::Takeoff => Goal::Track(Track {
                pos: [
                    Some(self.hold_pos.north_m),
                    Some(self.hold_pos.east_m),
                    Some(self.takeoff_z),
                ],
                vel: [None; 3],
                xy_max_m_s: auto_xy,
                up_max_m_s: p.get(Param::MPC_TKO_SPEED),
                down_max_m_s: auto_dn,
                yaw: self.hold_yaw,
                yaw_rate_max_rad_s: auto_yaw_rate,
            }),
            Px4Mode::Land | Px4Mode::Precland => {
                land_at(self.land_xy.0, self.land_xy.1, self.hold_yaw)
            }
            Px4Mode::Rtl => match self.rtl_phase {
                RtlPhase::Climb => hold(
                    Ned::new(self.rtl_start.north_m, self.rtl_start.east_m, self.rtl_z),
                    self.hold_yaw,
                ),
                RtlPhase::Return => hold(
                    Ned::new(self.home_local.north_m, self.home_local.east_m, self.rtl_z),
                    self.hold_yaw,
                ),
                RtlPhase::Land => land_at(self.land_xy.0, self.land_xy.1, self.hold_yaw),
            },
            Px4Mode::Offboard => {
                let sp = self.setpoint.unwrap_or(Setpoint {
                    pos: [
                        Some(self.hold_pos.north_m),
                        Some(self.hold_pos.east_m),
                        Some(self.hold_pos.down_m),
                    ],
                    ..Setpoint::default()
                });
                let yaw = match (sp.yaw_rad, sp.yaw_rate_rad_s) {
                    (Some(y), _) => YawGoal::Heading(y),
                    (None, Some(r)) => YawGoal::Rate(r),
                    (None, None) => YawGoal::Rate(0.0),
                };
                Goal::Track(Track {
                    pos: sp.pos,
                    vel: sp.vel,
                    xy_max_m_s: p.get(Param::MPC_XY_VEL_MAX),
                    up_max_m_s: p.get(Param::MPC_Z_VEL_MAX_UP),
                    down_max_m_s: p.get(Param::MPC_Z_VEL_MAX_DN),
                    yaw,
                    yaw_rate_max_rad_s: p.get(Param::MC_YAWRATE_MAX).to_radians(),
                })
            }
            _ => hold(self.hold_pos, self.hold_yaw),
        }
    }

    fn wind_now(&self) -> Ned {
        Ned::new(
            self.env.wind.north_m_s + self.gust.north_m,
            self.env.wind.east_m_s + self.gust.east_m,
            0.0,
        )
    }

    fn physics(&mut self, dt: f64) {
        let prev_roll = self.roll_rad;
        let prev_pitch = self.pitch_rad;
        match self.goal {
            Goal::Idle => {
                self.vel = Ned::ZERO;
                self.pos.down_m = 0.0;
                self.thrust_acc = Ned::new(0.0, 0.0, -GRAVITY_M_S2);
                self.yaw_rate_rad_s = 0.0;
                self.vel_int = Ned::ZERO;
                self.vel_sp_smooth = Ned::ZERO;
                self.ctrl_pos_sp = self.pos;
                self.ctrl_vel_sp = Ned::ZERO;
                self.ctrl_yaw_sp = self.yaw_rad;
            }
            Goal::FreeFall => {
                let drag = (self.wind_now() - self.vel) * DRAG_PER_S;
                let acc = Ned::new(drag.north_m, drag.east_m, GRAVITY_M_S2 + drag.down_m);
                self.vel = self.vel + acc * dt;
                self.pos = self.pos + self.vel * dt;
                self.thrust_acc = Ned::ZERO;
                self.ctrl_vel_sp = Ned::ZERO;
            }
            Goal::Track(t) => self.track(t, dt),
        }
        // Ground contact (flat ground at the local origin's altitude).
        if self.pos.down_m >= 0.0 {
            self.pos.down_m = 0.0;
            if self.vel.down_m > 0.0 {
                self.vel.down_m = 0.0;
            }
            if !matches!(self.goal, Goal::Track(_)) || self.vel_sp_smooth.down_m >= -0.05 {
                self.vel.north_m = 0.0;
                self.vel.east_m = 0.0;
            }
        }
        // Attitude from the thrust vector and the heading.
        let on_ground_idle = !matches!(self.goal, Goal::Track(_)) && self.pos.down_m >= 0.0;
        if on_ground_idle || matches!(self.goal, Goal::FreeFall) {
            self.roll_rad = 0.0;
            self.pitch_rad = 0.0;
        } else {
            let a = self.thrust_acc;
            let (s, c) = self.yaw_rad.sin_cos();
            let fwd = c * a.north_m + s * a.east_m;
            let right = -s * a.north_m + c * a.east_m;
            let up = -a.down_m;
            self.pitch_rad = (-fwd).atan2(up.max(0.1));
            self.roll_rad = right.atan2(up.max(0.1).hypot(fwd));
        }
        if dt > 0.0 {
            self.roll_rate_rad_s = (self.roll_rad - prev_roll) / dt;
            self.pitch_rate_rad_s = (self.pitch_rad - prev_pitch) / dt;
        }
    }

    fn track(&mut self, t: Track, dt: f64) {
        let p = &self.params;
        let kp = [
            p.get(Param::MPC_XY_P),
            p.get(Param::MPC_XY_P),
            p.get(Param::MPC_Z_P),
        ];
        let mut vel_sp = Ned::ZERO;
        let mut pos_sp = self.pos;
        for (i, k) in kp.into_iter().enumerate() {
            let v = match (t.pos[i], t.vel[i]) {
                (Some(target), ff) => {
                    set_axis(&mut pos_sp, i, target);
                    k * (target - axis(&self.pos, i)) + ff.unwrap_or(0.0)
                }
                (None, Some(v)) => v,
                (None, None) => 0.0,
            };
            set_axis(&mut vel_sp, i, v);
        }
        limit_horizontal(&mut vel_sp, t.xy_max_m_s.max(0.0));
        vel_sp.down_m = vel_sp
            .down_m
            .clamp(-t.up_max_m_s.max(0.0), t.down_max_m_s.max(0.0));
        // Acceleration-limited velocity setpoint (PX4's trajectory smoothing, simplified).
        let acc_hor = p.get(Param::MPC_ACC_HOR).max(0.1);
        let acc_up = p.get(Param::MPC_ACC_UP_MAX).max(0.1);
        let acc_dn = p.get(Param::MPC_ACC_DOWN_MAX).max(0.1);
        let mut dv = vel_sp - self.vel_sp_smooth;
        limit_horizontal(&mut dv, acc_hor * dt);
        dv.down_m = dv.down_m.clamp(-acc_up * dt, acc_dn * dt);
        self.vel_sp_smooth = self.vel_sp_smooth + dv;
        let acc_ff = if dt > 0.0 { dv * (1.0 / dt) } else { Ned::ZERO };
        // Velocity PI with drag compensation; wind is the unknown disturbance.
        let err = self.vel_sp_smooth - self.vel;
        self.vel_int = self.vel_int
            + Ned::new(
                err.north_m * VEL_I_XY,
                err.east_m * VEL_I_XY,
                err.down_m * VEL_I_Z,
            ) * dt;
        limit_horizontal(&mut self.vel_int, 3.0);
        self.vel_int.down_m = self.vel_int.down_m.clamp(-3.0, 3.0);
        let mut acc_sp = Ned::new(
            err.north_m * VEL_P_XY,
            err.east_m * VEL_P_XY,
            err.down_m * VEL_P_Z,
        ) + self.vel_int
            + acc_ff
            + self.vel * DRAG_PER_S;
        limit_horizontal(
            &mut acc_sp,
            p.get(Param::MPC_ACC_HOR_MAX).max(acc_hor) + 1.0,
        );
        acc_sp.down_m = acc_sp.down_m.clamp(-(acc_up + 2.0), acc_dn + 2.0);
        let drag = (self.wind_now() - self.vel) * DRAG_PER_S;
        let acc = acc_sp + drag;
        self.vel = self.vel + acc * dt;
        self.pos = self.pos + self.vel * dt;
        self.thrust_acc = Ned::new(acc_sp.north_m, acc_sp.east_m, acc_sp.down_m - GRAVITY_M_S2);
        // Yaw.
        let rate = match t.yaw {
            YawGoal::Heading(target) => {
                self.ctrl_yaw_sp = target;
                (2.0 * wrap_pi(target - self.yaw_rad))
                    .clamp(-t.yaw_rate_max_rad_s, t.yaw_rate_max_rad_s)
            }
            YawGoal::Rate(r) => {
                self.ctrl_yaw_sp = self.yaw_rad;
                r.clamp(-t.yaw_rate_max_rad_s, t.yaw_rate_max_rad_s)
            }
        };
        self.yaw_rate_rad_s = rate;
        self.yaw_rad = wrap_pi(self.yaw_rad + rate * dt);
        self.ctrl_pos_sp = pos_sp;
        self.ctrl_vel_sp = vel_sp;
    }

    fn land_detector(&mut self, now: Instant, dt: f64, out: &mut Outbox) {
        if self.landed {
            if self.armed && self.pos.down_m < -TAKEOFF_DETECT_M {
                self.landed = false;
                self.took_off = true;
                self.landed_at = None;
                self.ground_contact_s = 0.0;
                self.statustext(now, MavSeverity::MAV_SEVERITY_INFO, "Takeoff detected", out);
            }
            return;
        }
        let contact = self.pos.down_m >= -0.05 && self.vel.down_m.abs() < 0.3;
        if !self.armed {
            if self.pos.down_m >= 0.0 {
                // Motors off: it fell; it lies on the ground now.
                self.landed = true;
                self.landed_at = Some(now);
                self.vel = Ned::ZERO;
            }
            return;
        }
        let not_climbing = self.vel_sp_smooth.down_m >= -0.05;
        if contact && not_climbing {
            self.ground_contact_s += dt;
            if self.ground_contact_s >= LAND_DETECT_S {
                self.landed = true;
                self.landed_at = Some(now);
                self.ground_contact_s = 0.0;
                self.vel = Ned::ZERO;
                self.statustext(now, MavSeverity::MAV_SEVERITY_INFO, "Landing detected", out);
            }
        } else {
            self.ground_contact_s = 0.0;
        }
    }

    fn auto_disarm(&mut self, now: Instant, out: &mut Outbox) {
        if !self.armed || !self.landed {
            return;
        }
        let prflt = self.params.get(Param::COM_DISARM_PRFLT);
        let land = self.params.get(Param::COM_DISARM_LAND);
        if !self.took_off {
            if prflt > 0.0 && now.saturating_duration_since(self.armed_at).as_secs_f64() >= prflt {
                self.disarm(now, "Disarmed by auto preflight disarming", out);
            }
        } else if let Some(at) = self.landed_at
            && land > 0.0
            && now.saturating_duration_since(at).as_secs_f64() >= land
        {
            self.disarm(now, "Disarmed by landing", out);
        }
    }

    fn update_battery(&mut self, dt: f64) {
        let current = if !self.armed {
            0.4
        } else if self.landed {
            2.0
        } else {
            12.0 + 0.6 * self.vel.horizontal_norm() + 2.0 * self.vel.down_m.abs()
        };
        let capacity = self.params.get(Param::BAT1_CAPACITY).max(1.0);
        self.battery.current_a = current;
        self.battery.consumed_mah += current * dt / 3.6;
        let remaining = (1.0 - self.battery.consumed_mah / capacity).clamp(0.0, 1.0);
        self.battery.remaining = remaining;
        let cells = self.params.get(Param::BAT1_N_CELLS).max(1.0);
        let full = self.params.get(Param::BAT1_V_CHARGED);
        let empty = self.params.get(Param::BAT1_V_EMPTY);
        let internal_resistance_ohm = 0.005 * cells;
        self.battery.voltage_v =
            cells * (empty + (full - empty) * remaining) - internal_resistance_ohm * current;
    }

    fn update_noise(&mut self, dt: f64) {
        if self.env.wind.gust_m_s > 0.0 {
            let a = (-dt / GUST_TAU_S).exp();
            let s = self.env.wind.gust_m_s * (1.0 - a * a).sqrt();
            self.gust = Ned::new(
                self.gust.north_m * a + s * gaussian(&mut self.rng),
                self.gust.east_m * a + s * gaussian(&mut self.rng),
                0.0,
            );
        }
        if self.env.gps_noise_m > 0.0 {
            // The EKF smooths GPS: a slow random walk of about half the GPS noise.
            let a = (-dt / EST_NOISE_TAU_S).exp();
            let s = 0.5 * self.env.gps_noise_m * (1.0 - a * a).sqrt();
            self.est_noise = Ned::new(
                self.est_noise.north_m * a + s * gaussian(&mut self.rng),
                self.est_noise.east_m * a + s * gaussian(&mut self.rng),
                self.est_noise.down_m * a + 1.5 * s * gaussian(&mut self.rng),
            );
        }
    }

    /// White GPS receiver noise on top of the estimator error, m (GPS_RAW_INT only).
    pub fn gps_white_noise(&mut self) -> Ned {
        if self.env.gps_noise_m > 0.0 {
            let s = 0.5 * self.env.gps_noise_m;
            Ned::new(
                s * gaussian(&mut self.rng),
                s * gaussian(&mut self.rng),
                1.5 * s * gaussian(&mut self.rng),
            )
        } else {
            Ned::ZERO
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{PX4_SITL_HOME, TelemetryProfile};
    use skein_mavlink::Decoder;

    fn env(wind: WindConfig, gps_noise_m: f64, seed: u64) -> Environment {
        Environment {
            wind,
            gps_noise_m,
            ekf_fix_delay: Duration::ZERO,
            params: Vec::new(),
            seed,
            profile: TelemetryProfile::Swarm,
            offboard_min_stream: Duration::ZERO,
        }
    }

    /// A vehicle driven on a synthetic clock (100 Hz steps), with a MAVLink client.
    struct Harness {
        v: Vehicle,
        enc: Encoder,
        buf: Vec<u8>,
        now: Instant,
    }

    impl Harness {
        fn new(env: Environment) -> Harness {
            let now = Instant::now();
            Harness {
                v: Vehicle::new(1, PX4_SITL_HOME, env, now),
                enc: Encoder::new(1, 1),
                buf: Vec::new(),
                now,
            }
        }

        fn run(&mut self, secs: f64) {
            for _ in 0..(secs * 100.0).round() as usize {
                self.now += Duration::from_millis(10);
                let mut out = Outbox {
                    enc: &mut self.enc,
                    buf: &mut self.buf,
                    frames: 0,
                };
                self.v.step(self.now, 0.01, &mut out);
                self.buf.clear();
            }
        }

        /// Feeds one message from a client; returns the COMMAND_ACK results it caused.
        fn input(&mut self, msg: MavMessage) -> Vec<MavResult> {
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
            let mut acks = Vec::new();
            Decoder::default().decode_datagram(&self.buf, |f| {
                if let MavMessage::COMMAND_ACK(a) = f.msg {
                    acks.push(a.result);
                }
            });
            self.buf.clear();
            acks
        }

        fn command(&mut self, command: MavCmd, p: [f32; 7]) -> Vec<MavResult> {
            self.input(MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
                param1: p[0],
                param2: p[1],
                param3: p[2],
                param4: p[3],
                param5: p[4],
                param6: p[5],
                param7: p[6],
                command,
                target_system: 1,
                target_component: 1,
                confirmation: 0,
            }))
        }

        fn setpoint(&mut self, mask: u16, pos: [f32; 3], vel: [f32; 3]) {
            self.input(MavMessage::SET_POSITION_TARGET_LOCAL_NED(
                SET_POSITION_TARGET_LOCAL_NED_DATA {
                    time_boot_ms: 0,
                    x: pos[0],
                    y: pos[1],
                    z: pos[2],
                    vx: vel[0],
                    vy: vel[1],
                    vz: vel[2],
                    afx: 0.0,
                    afy: 0.0,
                    afz: 0.0,
                    yaw: 0.0,
                    yaw_rate: 0.0,
                    type_mask: PositionTargetTypemask::from_bits_retain(mask),
                    target_system: 1,
                    target_component: 1,
                    coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
                },
            ));
        }

        fn takeoff(&mut self) {
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
            self.run(6.0);
            assert_eq!(self.v.mode, Px4Mode::Hold, "takeoff did not complete");
        }

        /// Streams `sp` at 20 Hz for `secs`.
        fn stream(&mut self, secs: f64, mask: u16, pos: [f32; 3], vel: [f32; 3]) {
            for _ in 0..(secs * 20.0).round() as usize {
                self.setpoint(mask, pos, vel);
                self.run(0.05);
            }
        }
    }

    #[test]
    fn holds_position_against_wind_and_gusts() {
        let wind = WindConfig::from_direction(8.0, 270.0, 2.0);
        let mut h = Harness::new(env(wind, 0.0, 7));
        h.takeoff();
        h.run(10.0);
        let mut worst: f64 = 0.0;
        let mut tilt: f64 = 0.0;
        for _ in 0..200 {
            h.run(0.1);
            worst = worst.max(h.v.pos.horizontal_norm());
            tilt = tilt.max(h.v.roll_rad.abs().max(h.v.pitch_rad.abs()));
        }
        assert!(worst < 0.5, "drifted {worst} m in 8 m/s wind");
        assert!(tilt > 0.03, "not leaning into the wind: {tilt} rad");
        assert!(
            (h.v.pos.down_m + 2.5).abs() < 0.3,
            "altitude {}",
            h.v.pos.down_m
        );
    }

    #[test]
    fn same_seed_same_trajectory_different_seed_different() {
        let wind = WindConfig::from_direction(5.0, 200.0, 1.5);
        let fly = |seed: u64| {
            let mut h = Harness::new(env(wind, 1.0, seed));
            h.takeoff();
            h.run(5.0);
            (h.v.pos, h.v.est_noise)
        };
        assert_eq!(fly(42), fly(42));
        assert_ne!(fly(42), fly(43));
    }

    #[test]
    fn offboard_speed_limits_and_yaw_keep() {
        let mut h = Harness::new(env(WindConfig::default(), 0.0, 0));
        h.run(0.1);
        h.setpoint(type_mask::POSITION_YAW, [0.0, 0.0, -10.0], [0.0; 3]);
        let (main, sub) = Px4Mode::Offboard.main_sub();
        let acks = h.command(
            MavCmd::MAV_CMD_DO_SET_MODE,
            [1.0, f32::from(main), f32::from(sub), 0.0, 0.0, 0.0, 0.0],
        );
        assert_eq!(
            acks,
            vec![
                MavResult::MAV_RESULT_ACCEPTED,
                MavResult::MAV_RESULT_ACCEPTED
            ]
        );
        assert_eq!(
            h.command(
                MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
                [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
            ),
            vec![MavResult::MAV_RESULT_ACCEPTED]
        );
        // Climb: limited to MPC_Z_VEL_MAX_UP (3 m/s).
        let mut max_up: f64 = 0.0;
        for _ in 0..40 {
            h.stream(0.1, type_mask::POSITION_YAW, [0.0, 0.0, -10.0], [0.0; 3]);
            max_up = max_up.max(-h.v.vel.down_m);
        }
        assert!(max_up > 2.8 && max_up <= 3.05, "climb rate {max_up}");
        // 20 m/s asked, MPC_XY_VEL_MAX (12 m/s) flown; yaw ignored → heading kept.
        let yaw0 = h.v.yaw_rad;
        h.stream(
            8.0,
            type_mask::VELOCITY_YAW_RATE | type_mask::IGNORE_YAW_RATE,
            [0.0; 3],
            [20.0, 0.0, 0.0],
        );
        let v = h.v.vel.horizontal_norm();
        assert!((v - 12.0).abs() < 0.2, "speed {v}");
        assert!((h.v.yaw_rad - yaw0).abs() < 1e-9);
        // Acceleration stays around MPC_ACC_HOR.
        assert!(h.v.thrust_acc.horizontal_norm() < 6.5);
    }

    #[test]
    fn forced_disarm_in_air_falls_and_lands() {
        let mut h = Harness::new(env(WindConfig::default(), 0.0, 0));
        h.takeoff();
        let r = h.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [0.0; 7]);
        assert_eq!(
            r,
            vec![MavResult::MAV_RESULT_DENIED],
            "disarm in air must need force"
        );
        let r = h.command(
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            [0.0, FORCE_ARM_DISARM_MAGIC, 0.0, 0.0, 0.0, 0.0, 0.0],
        );
        assert_eq!(r, vec![MavResult::MAV_RESULT_ACCEPTED]);
        h.run(2.0);
        assert!(!h.v.armed && h.v.landed && h.v.pos.down_m == 0.0);
        assert_eq!(h.v.landed_state(), LandedState::OnGround);
    }

    #[test]
    fn battery_drains_faster_in_flight() {
        let mut idle = Harness::new(env(WindConfig::default(), 0.0, 0));
        idle.run(60.0);
        let mut flying = Harness::new(env(WindConfig::default(), 0.0, 0));
        flying.takeoff();
        flying.run(54.0);
        assert!(idle.v.battery.remaining > flying.v.battery.remaining);
        assert!(
            flying.v.battery.consumed_mah > 150.0,
            "{}",
            flying.v.battery.consumed_mah
        );
        assert!(flying.v.battery.voltage_v < idle.v.battery.voltage_v);
    }

    #[test]
    fn land_mode_descends_at_mpc_land_speed_near_the_ground() {
        let mut h = Harness::new(env(WindConfig::default(), 0.0, 0));
        h.takeoff();
        h.command(MavCmd::MAV_CMD_NAV_LAND, [0.0; 7]);
        h.run(1.5);
        assert!(
            (h.v.vel.down_m - 0.7).abs() < 0.05,
            "descent {}",
            h.v.vel.down_m
        );
        h.run(10.0);
        assert!(h.v.landed && !h.v.armed, "not landed and disarmed");
    }

    #[test]
    fn gcs_link_loss_takes_nav_dll_act() {
        let mut e = env(WindConfig::default(), 0.0, 0);
        e.params = vec![("NAV_DLL_ACT".into(), 2.0), ("COM_DL_LOSS_T".into(), 2.0)];
        let mut h = Harness::new(e);
        let gcs = || {
            MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                custom_mode: 0,
                mavtype: MavType::MAV_TYPE_GCS,
                autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
                base_mode: MavModeFlag::empty(),
                system_status: MavState::MAV_STATE_ACTIVE,
                mavlink_version: 3,
            })
        };
        h.input(gcs());
        h.run(0.1);
        let nan = f32::NAN;
        h.command(
            MavCmd::MAV_CMD_NAV_TAKEOFF,
            [0.0, 0.0, 0.0, nan, nan, nan, nan],
        );
        h.command(
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        );
        for _ in 0..10 {
            h.input(gcs());
            h.run(1.0);
        }
        assert_eq!(h.v.mode, Px4Mode::Hold);
        h.run(2.5);
        assert_eq!(h.v.mode, Px4Mode::Rtl, "no failsafe after COM_DL_LOSS_T");
        assert!(h.v.failsafe);
        assert_eq!(h.v.counters.gcs_loss_failsafes, 1);
    }
}
