//! Builders of every telemetry message from the vehicle state (PX4's field conventions:
//! frames, units, `custom_mode`, SYS_STATUS sensor bits), for streams and on request:
//! one method per message, the sensors' in [`super::sensors`].

#![allow(deprecated)]

use super::PX4_FLIGHT_SW_VERSION;
use super::scheduler::Stream;
use crate::vehicle::{Outbox, Vehicle};
use skein_mavlink::MavMessage;
use skein_mavlink::dialect::*;
use skein_model::geo::{Ned, wrap_pi};
use skein_model::px4::Px4Mode;
use std::time::{Instant, SystemTime, UNIX_EPOCH};

/// Quaternion (w, x, y, z) of ZYX Euler angles (rad): body FRD to NED.
pub(crate) fn quaternion(roll: f64, pitch: f64, yaw: f64) -> [f32; 4] {
    let (sr, cr) = (roll * 0.5).sin_cos();
    let (sp, cp) = (pitch * 0.5).sin_cos();
    let (sy, cy) = (yaw * 0.5).sin_cos();
    [
        (cr * cp * cy + sr * sp * sy) as f32,
        (sr * cp * cy - cr * sp * sy) as f32,
        (cr * sp * cy + sr * cp * sy) as f32,
        (cr * cp * sy - sr * sp * cy) as f32,
    ]
}

/// Rotates a NED vector into the body frame (FRD) of ZYX Euler angles.
pub(super) fn ned_to_body(v: Ned, roll: f64, pitch: f64, yaw: f64) -> [f64; 3] {
    let (sr, cr) = roll.sin_cos();
    let (sp, cp) = pitch.sin_cos();
    let (sy, cy) = yaw.sin_cos();
    // R (body → NED) = Rz(yaw) Ry(pitch) Rx(roll); body = Rᵀ v.
    let r = [
        [cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy],
        [cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy],
        [-sp, sr * cp, cr * cp],
    ];
    let n = [v.north_m, v.east_m, v.down_m];
    let mut b = [0.0; 3];
    for (j, out) in b.iter_mut().enumerate() {
        *out = r[0][j] * n[0] + r[1][j] * n[1] + r[2][j] * n[2];
    }
    b
}

/// Heading of `yaw_rad` in [0, 360) degrees.
pub(super) fn heading_deg(yaw_rad: f64) -> f64 {
    let d = yaw_rad.to_degrees().rem_euclid(360.0);
    if d >= 360.0 { 0.0 } else { d }
}

/// When a stream's message is built, and the estimate it reports.
#[derive(Debug, Clone, Copy)]
pub(super) struct Stamp {
    /// Now.
    pub(super) now: Instant,
    /// Milliseconds since boot.
    pub(super) time_boot_ms: u32,
    /// Microseconds since boot.
    pub(super) time_usec: u64,
    /// The estimated position, local NED, m.
    pub(super) est: Ned,
    /// The estimated velocity, NED, m/s.
    pub(super) vel: Ned,
}

impl Vehicle {
    pub(super) fn autopilot_version(&self) -> MavMessage {
        let caps = MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT
            | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_INT
            | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_COMMAND_INT
            // MAVLink FTP (PX4's `mavlink_main.cpp` always says so): the metadata.
            | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_FTP
            | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE
            | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET
            | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
            | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
            | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_FLIGHT_TERMINATION
            | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MAVLINK2;
        let mut uid2 = [0u8; 18];
        uid2[0] = self.sysid;
        MavMessage::AUTOPILOT_VERSION(AUTOPILOT_VERSION_DATA {
            capabilities: caps,
            uid: 0x534B_454E_0000_0000 | u64::from(self.sysid),
            flight_sw_version: PX4_FLIGHT_SW_VERSION,
            middleware_sw_version: PX4_FLIGHT_SW_VERSION,
            os_sw_version: 0,
            board_version: 0,
            vendor_id: 0,
            product_id: 0,
            flight_custom_version: *b"skeinsim",
            middleware_custom_version: [0; 8],
            os_custom_version: [0; 8],
            uid2,
        })
    }

    fn base_mode(&self) -> MavModeFlag {
        let mut f = MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED;
        if self.armed {
            f |= MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
        }
        let auto = MavModeFlag::MAV_MODE_FLAG_AUTO_ENABLED
            | MavModeFlag::MAV_MODE_FLAG_STABILIZE_ENABLED
            | MavModeFlag::MAV_MODE_FLAG_GUIDED_ENABLED;
        f |= match self.mode {
            Px4Mode::Manual | Px4Mode::Acro => MavModeFlag::MAV_MODE_FLAG_MANUAL_INPUT_ENABLED,
            Px4Mode::Stabilized | Px4Mode::Altctl => {
                MavModeFlag::MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
                    | MavModeFlag::MAV_MODE_FLAG_STABILIZE_ENABLED
            }
            Px4Mode::Posctl => {
                MavModeFlag::MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
                    | MavModeFlag::MAV_MODE_FLAG_STABILIZE_ENABLED
                    | MavModeFlag::MAV_MODE_FLAG_GUIDED_ENABLED
            }
            Px4Mode::Unknown(_) => MavModeFlag::empty(),
            _ => auto,
        };
        f
    }

    fn system_status(&self, now: Instant) -> MavState {
        if !self.ekf_ok(now) && !self.armed {
            MavState::MAV_STATE_STANDBY
        } else if self.armed && self.failsafe {
            MavState::MAV_STATE_CRITICAL
        } else if self.armed {
            MavState::MAV_STATE_ACTIVE
        } else {
            MavState::MAV_STATE_STANDBY
        }
    }

    fn standard_mode(&self) -> MavStandardMode {
        match self.mode {
            Px4Mode::Posctl => MavStandardMode::MAV_STANDARD_MODE_POSITION_HOLD,
            Px4Mode::Altctl => MavStandardMode::MAV_STANDARD_MODE_ALTITUDE_HOLD,
            Px4Mode::Rtl => MavStandardMode::MAV_STANDARD_MODE_SAFE_RECOVERY,
            Px4Mode::Mission => MavStandardMode::MAV_STANDARD_MODE_MISSION,
            Px4Mode::Land => MavStandardMode::MAV_STANDARD_MODE_LAND,
            Px4Mode::Takeoff => MavStandardMode::MAV_STANDARD_MODE_TAKEOFF,
            _ => MavStandardMode::MAV_STANDARD_MODE_NON_STANDARD,
        }
    }

    fn sys_status(&self, now: Instant) -> MavMessage {
        use MavSysStatusSensor as S;
        let sensors = S::MAV_SYS_STATUS_SENSOR_3D_GYRO
            | S::MAV_SYS_STATUS_SENSOR_3D_ACCEL
            | S::MAV_SYS_STATUS_SENSOR_3D_MAG
            | S::MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE;
        let control = S::MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
            | S::MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
            | S::MAV_SYS_STATUS_SENSOR_YAW_POSITION
            | S::MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
            | S::MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
            | S::MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS;
        let present = sensors
            | control
            | S::MAV_SYS_STATUS_SENSOR_GPS
            | S::MAV_SYS_STATUS_AHRS
            | S::MAV_SYS_STATUS_LOGGING
            | S::MAV_SYS_STATUS_SENSOR_BATTERY
            | S::MAV_SYS_STATUS_PREARM_CHECK;
        let mut enabled = sensors
            | S::MAV_SYS_STATUS_SENSOR_GPS
            | S::MAV_SYS_STATUS_AHRS
            | S::MAV_SYS_STATUS_SENSOR_BATTERY
            | S::MAV_SYS_STATUS_PREARM_CHECK;
        if self.armed {
            enabled |= control;
        }
        let mut health = sensors
            | control
            | S::MAV_SYS_STATUS_AHRS
            | S::MAV_SYS_STATUS_LOGGING
            | S::MAV_SYS_STATUS_SENSOR_BATTERY;
        if self.ekf_ok(now) {
            health |= S::MAV_SYS_STATUS_SENSOR_GPS;
        }
        if self.prearm_ok(now) {
            health |= S::MAV_SYS_STATUS_PREARM_CHECK;
        }
        MavMessage::SYS_STATUS(SYS_STATUS_DATA {
            onboard_control_sensors_present: present,
            onboard_control_sensors_enabled: enabled,
            onboard_control_sensors_health: health,
            load: if self.armed { 320 } else { 250 },
            voltage_battery: (self.battery.voltage_v * 1000.0) as u16,
            current_battery: (self.battery.current_a * 100.0) as i16,
            drop_rate_comm: 0,
            errors_comm: self.link.rx_parse_errors.min(u64::from(u16::MAX)) as u16,
            errors_count1: 0,
            errors_count2: 0,
            errors_count3: 0,
            errors_count4: 0,
            battery_remaining: (self.battery.remaining * 100.0).round() as i8,
            onboard_control_sensors_present_extended: MavSysStatusSensorExtended::empty(),
            onboard_control_sensors_enabled_extended: MavSysStatusSensorExtended::empty(),
            onboard_control_sensors_health_extended: MavSysStatusSensorExtended::empty(),
        })
    }

    pub(super) fn build_stream(&mut self, stream: Stream, now: Instant, out: &mut Outbox) {
        let stamp = Stamp {
            now,
            time_boot_ms: self.time_boot_ms(now),
            time_usec: self.time_boot_us(now),
            est: self.est_pos(),
            vel: self.est_vel(),
        };
        if let Some(msg) = self.stream_message(stream, &stamp) {
            out.push(&msg);
        }
    }

    /// The message of `stream` now, `None` where PX4 sends none yet.
    fn stream_message(&mut self, stream: Stream, s: &Stamp) -> Option<MavMessage> {
        match stream {
            Stream::Heartbeat => Some(self.heartbeat(s)),
            Stream::Attitude => Some(self.attitude(s)),
            Stream::AttitudeQuaternion => Some(self.attitude_quaternion(s)),
            Stream::GlobalPositionInt => self.global_position_int(s),
            Stream::HighresImu => Some(self.highres_imu(s)),
            Stream::LocalPositionNed => Some(self.local_position_ned(s)),
            Stream::Odometry => Some(self.odometry(s)),
            Stream::Timesync => Some(self.timesync(s)),
            Stream::Altitude => Some(self.altitude(s)),
            Stream::DistanceSensor => Some(self.distance_sensor(s)),
            Stream::AttitudeTarget => Some(self.attitude_target(s)),
            Stream::PositionTargetLocalNed => Some(self.position_target_local_ned(s)),
            Stream::ServoOutputRaw => Some(self.servo_output_raw(s)),
            Stream::VfrHud => Some(self.vfr_hud(s)),
            Stream::GpsRawInt => Some(self.gps_raw_int(s)),
            Stream::ExtendedSysState => Some(self.extended_sys_state()),
            Stream::SysStatus => Some(self.sys_status(s.now)),
            Stream::EstimatorStatus => Some(self.estimator_status(s)),
            Stream::Ping => Some(self.ping(s)),
            Stream::SystemTime => Some(self.system_time(s)),
            Stream::ScaledPressure => Some(self.scaled_pressure(s)),
            Stream::MissionCurrent => Some(self.mission_current()),
            Stream::LinkNodeStatus => Some(self.link_node_status(s)),
            Stream::BatteryStatus => Some(self.battery_status()),
            Stream::CurrentMode => Some(self.current_mode()),
            Stream::HomePosition => self.home_position(s),
            Stream::Vibration => Some(self.vibration(s)),
        }
    }

    /// `HEARTBEAT`: PX4's `custom_mode`, base mode flags and system status.
    fn heartbeat(&self, s: &Stamp) -> MavMessage {
        let Stamp { now, .. } = *s;
        MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: self.mode.custom_mode(),
            mavtype: MavType::MAV_TYPE_QUADROTOR,
            autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
            base_mode: self.base_mode(),
            system_status: self.system_status(now),
            mavlink_version: 3,
        })
    }

    /// `ATTITUDE`: Euler angles and body rates.
    fn attitude(&self, s: &Stamp) -> MavMessage {
        let Stamp { time_boot_ms, .. } = *s;
        MavMessage::ATTITUDE(ATTITUDE_DATA {
            time_boot_ms,
            roll: self.roll_rad as f32,
            pitch: self.pitch_rad as f32,
            yaw: self.yaw_rad as f32,
            rollspeed: self.roll_rate_rad_s as f32,
            pitchspeed: self.pitch_rate_rad_s as f32,
            yawspeed: self.yaw_rate_rad_s as f32,
        })
    }

    /// `ATTITUDE_QUATERNION`: the attitude as a quaternion, and body rates.
    fn attitude_quaternion(&self, s: &Stamp) -> MavMessage {
        let Stamp { time_boot_ms, .. } = *s;
        let q = quaternion(self.roll_rad, self.pitch_rad, self.yaw_rad);
        MavMessage::ATTITUDE_QUATERNION(ATTITUDE_QUATERNION_DATA {
            time_boot_ms,
            q1: q[0],
            q2: q[1],
            q3: q[2],
            q4: q[3],
            rollspeed: self.roll_rate_rad_s as f32,
            pitchspeed: self.pitch_rate_rad_s as f32,
            yawspeed: self.yaw_rate_rad_s as f32,
            repr_offset_q: [0.0; 4],
        })
    }

    /// `GLOBAL_POSITION_INT` of the estimate; none before the EKF has a global position.
    fn global_position_int(&self, s: &Stamp) -> Option<MavMessage> {
        let Stamp {
            now,
            time_boot_ms,
            est,
            vel,
            ..
        } = *s;
        if !self.ekf_ok(now) {
            return None; // PX4 sends no global position before the EKF has one
        }
        let (lat, lon, alt) = self.geo_of(est).to_mavlink();
        Some(MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
            time_boot_ms,
            lat,
            lon,
            alt,
            relative_alt: ((self.home_local.down_m - est.down_m) * 1000.0).round() as i32,
            vx: (vel.north_m * 100.0).round() as i16,
            vy: (vel.east_m * 100.0).round() as i16,
            vz: (vel.down_m * 100.0).round() as i16,
            hdg: (heading_deg(self.yaw_rad) * 100.0).round().min(35999.0) as u16,
        }))
    }

    /// `LOCAL_POSITION_NED` of the estimate.
    fn local_position_ned(&self, s: &Stamp) -> MavMessage {
        let Stamp {
            time_boot_ms,
            est,
            vel,
            ..
        } = *s;
        MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
            time_boot_ms,
            x: est.north_m as f32,
            y: est.east_m as f32,
            z: est.down_m as f32,
            vx: vel.north_m as f32,
            vy: vel.east_m as f32,
            vz: vel.down_m as f32,
        })
    }

    /// `ODOMETRY`: the estimate, velocity in the body frame, fixed covariances.
    fn odometry(&self, s: &Stamp) -> MavMessage {
        let Stamp {
            time_usec,
            est,
            vel,
            ..
        } = *s;
        let vb = ned_to_body(vel, self.roll_rad, self.pitch_rad, self.yaw_rad);
        let mut pose_cov = [0.0f32; 21];
        let mut vel_cov = [0.0f32; 21];
        // Upper-right triangle of a 6x6 matrix: the diagonal is at these indices.
        for (k, &d) in [0usize, 6, 11, 15, 18, 20].iter().enumerate() {
            pose_cov[d] = if k < 3 { 0.25 } else { 0.01 };
            vel_cov[d] = if k < 3 { 0.04 } else { 0.01 };
        }
        MavMessage::ODOMETRY(ODOMETRY_DATA {
            time_usec,
            x: est.north_m as f32,
            y: est.east_m as f32,
            z: est.down_m as f32,
            q: quaternion(self.roll_rad, self.pitch_rad, self.yaw_rad),
            vx: vb[0] as f32,
            vy: vb[1] as f32,
            vz: vb[2] as f32,
            rollspeed: self.roll_rate_rad_s as f32,
            pitchspeed: self.pitch_rate_rad_s as f32,
            yawspeed: self.yaw_rate_rad_s as f32,
            pose_covariance: pose_cov,
            velocity_covariance: vel_cov,
            frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
            child_frame_id: MavFrame::MAV_FRAME_BODY_FRD,
            reset_counter: 0,
            estimator_type: MavEstimatorType::MAV_ESTIMATOR_TYPE_GPS_INS,
            quality: 100,
        })
    }

    /// `TIMESYNC` request (`ts1` in ns of boot time).
    fn timesync(&self, s: &Stamp) -> MavMessage {
        let Stamp { time_usec, .. } = *s;
        MavMessage::TIMESYNC(TIMESYNC_DATA {
            tc1: 0,
            ts1: time_usec as i64 * 1000,
            target_system: 0,
            target_component: 0,
        })
    }

    /// `ATTITUDE_TARGET`: the controller's attitude and rates.
    fn attitude_target(&self, s: &Stamp) -> MavMessage {
        let Stamp { time_boot_ms, .. } = *s;
        MavMessage::ATTITUDE_TARGET(ATTITUDE_TARGET_DATA {
            time_boot_ms,
            q: quaternion(self.roll_rad, self.pitch_rad, self.ctrl_yaw_sp),
            body_roll_rate: self.roll_rate_rad_s as f32,
            body_pitch_rate: self.pitch_rate_rad_s as f32,
            body_yaw_rate: self.yaw_rate_rad_s as f32,
            thrust: self.thrust_norm() as f32,
            type_mask: AttitudeTargetTypemask::empty(),
        })
    }

    /// `POSITION_TARGET_LOCAL_NED`: the position controller's setpoints.
    fn position_target_local_ned(&self, s: &Stamp) -> MavMessage {
        let Stamp { time_boot_ms, .. } = *s;
        MavMessage::POSITION_TARGET_LOCAL_NED(POSITION_TARGET_LOCAL_NED_DATA {
            time_boot_ms,
            x: self.ctrl_pos_sp.north_m as f32,
            y: self.ctrl_pos_sp.east_m as f32,
            z: self.ctrl_pos_sp.down_m as f32,
            vx: self.ctrl_vel_sp.north_m as f32,
            vy: self.ctrl_vel_sp.east_m as f32,
            vz: self.ctrl_vel_sp.down_m as f32,
            afx: f32::NAN,
            afy: f32::NAN,
            afz: f32::NAN,
            yaw: wrap_pi(self.ctrl_yaw_sp) as f32,
            yaw_rate: self.yaw_rate_rad_s as f32,
            type_mask: PositionTargetTypemask::from_bits_retain(
                skein_model::px4::type_mask::IGNORE_ACCELERATION,
            ),
            coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
        })
    }

    /// `SERVO_OUTPUT_RAW`: four motors' PWM from thrust, roll and pitch (900 disarmed).
    fn servo_output_raw(&self, s: &Stamp) -> MavMessage {
        let Stamp { time_usec, .. } = *s;
        let pwm = |k: f64| -> u16 {
            if self.armed {
                (1000.0 + 1000.0 * (self.thrust_norm() + k).clamp(0.0, 1.0)) as u16
            } else {
                900
            }
        };
        let r = 0.05 * self.roll_rad;
        let p = 0.05 * self.pitch_rad;
        MavMessage::SERVO_OUTPUT_RAW(SERVO_OUTPUT_RAW_DATA {
            time_usec: time_usec as u32,
            servo1_raw: pwm(-r + p),
            servo2_raw: pwm(r - p),
            servo3_raw: pwm(r + p),
            servo4_raw: pwm(-r - p),
            servo5_raw: 0,
            servo6_raw: 0,
            servo7_raw: 0,
            servo8_raw: 0,
            port: 0,
            servo9_raw: 0,
            servo10_raw: 0,
            servo11_raw: 0,
            servo12_raw: 0,
            servo13_raw: 0,
            servo14_raw: 0,
            servo15_raw: 0,
            servo16_raw: 0,
        })
    }

    /// `VFR_HUD`: air and ground speed, altitude, climb, heading, throttle.
    fn vfr_hud(&self, s: &Stamp) -> MavMessage {
        let Stamp { est, vel, .. } = *s;
        let wind = Ned::new(self.env.wind.north_m_s, self.env.wind.east_m_s, 0.0);
        MavMessage::VFR_HUD(VFR_HUD_DATA {
            airspeed: (vel - wind).horizontal_norm() as f32,
            groundspeed: vel.horizontal_norm() as f32,
            alt: (self.origin.origin.alt_amsl_m - est.down_m) as f32,
            climb: -vel.down_m as f32,
            heading: heading_deg(self.yaw_rad).round() as i16 % 360,
            throttle: (self.thrust_norm() * 100.0).round() as u16,
        })
    }

    /// `EXTENDED_SYS_STATE`: the landed state.
    fn extended_sys_state(&self) -> MavMessage {
        MavMessage::EXTENDED_SYS_STATE(EXTENDED_SYS_STATE_DATA {
            vtol_state: MavVtolState::MAV_VTOL_STATE_UNDEFINED,
            landed_state: match self.landed_state() {
                skein_model::px4::LandedState::Undefined => {
                    MavLandedState::MAV_LANDED_STATE_UNDEFINED
                }
                skein_model::px4::LandedState::OnGround => {
                    MavLandedState::MAV_LANDED_STATE_ON_GROUND
                }
                skein_model::px4::LandedState::InAir => MavLandedState::MAV_LANDED_STATE_IN_AIR,
                skein_model::px4::LandedState::Takeoff => MavLandedState::MAV_LANDED_STATE_TAKEOFF,
                skein_model::px4::LandedState::Landing => MavLandedState::MAV_LANDED_STATE_LANDING,
            },
        })
    }

    /// `ESTIMATOR_STATUS`: the EKF's flags (constant position until it has a fix).
    fn estimator_status(&self, s: &Stamp) -> MavMessage {
        let Stamp { now, time_usec, .. } = *s;
        use EstimatorStatusFlags as E;
        let flags = if self.ekf_ok(now) {
            E::ESTIMATOR_ATTITUDE
                | E::ESTIMATOR_VELOCITY_HORIZ
                | E::ESTIMATOR_VELOCITY_VERT
                | E::ESTIMATOR_POS_HORIZ_REL
                | E::ESTIMATOR_POS_HORIZ_ABS
                | E::ESTIMATOR_POS_VERT_ABS
                | E::ESTIMATOR_PRED_POS_HORIZ_REL
                | E::ESTIMATOR_PRED_POS_HORIZ_ABS
        } else {
            E::ESTIMATOR_ATTITUDE
                | E::ESTIMATOR_VELOCITY_VERT
                | E::ESTIMATOR_POS_VERT_ABS
                | E::ESTIMATOR_CONST_POS_MODE
        };
        MavMessage::ESTIMATOR_STATUS(ESTIMATOR_STATUS_DATA {
            time_usec,
            vel_ratio: 0.05,
            pos_horiz_ratio: 0.04,
            pos_vert_ratio: 0.03,
            mag_ratio: 0.02,
            hagl_ratio: 0.0,
            tas_ratio: 0.0,
            pos_horiz_accuracy: 0.5,
            pos_vert_accuracy: 0.8,
            flags,
        })
    }

    /// `PING` request, the next sequence number.
    fn ping(&mut self, s: &Stamp) -> MavMessage {
        let Stamp { time_usec, .. } = *s;
        self.ping_seq = self.ping_seq.wrapping_add(1);
        MavMessage::PING(PING_DATA {
            time_usec,
            seq: self.ping_seq,
            target_system: 0,
            target_component: 0,
        })
    }

    /// `SYSTEM_TIME`: the wall clock and boot time.
    fn system_time(&self, s: &Stamp) -> MavMessage {
        let Stamp { time_boot_ms, .. } = *s;
        MavMessage::SYSTEM_TIME(SYSTEM_TIME_DATA {
            time_unix_usec: SystemTime::now()
                .duration_since(UNIX_EPOCH)
                .map(|d| d.as_micros() as u64)
                .unwrap_or(0),
            time_boot_ms,
        })
    }

    /// `MISSION_CURRENT`: no mission; the mission mode flag.
    fn mission_current(&self) -> MavMessage {
        MavMessage::MISSION_CURRENT(MISSION_CURRENT_DATA {
            seq: 0,
            total: 0,
            mission_state: MissionState::MISSION_STATE_NO_MISSION,
            mission_mode: u8::from(self.mode == Px4Mode::Mission),
            mission_id: 0,
            fence_id: 0,
            rally_points_id: 0,
        })
    }

    /// `LINK_NODE_STATUS`: the link's rates and counters.
    fn link_node_status(&self, s: &Stamp) -> MavMessage {
        let Stamp { time_boot_ms, .. } = *s;
        MavMessage::LINK_NODE_STATUS(LINK_NODE_STATUS_DATA {
            timestamp: u64::from(time_boot_ms),
            tx_rate: self.link.tx_rate_bytes_s,
            rx_rate: self.link.rx_rate_bytes_s,
            messages_sent: self.link.tx_frames as u32,
            messages_received: self.link.rx_frames as u32,
            messages_lost: 0,
            rx_parse_err: self.link.rx_parse_errors.min(u64::from(u16::MAX)) as u16,
            tx_overflows: self.link.tx_overflows.min(u64::from(u16::MAX)) as u16,
            rx_overflows: 0,
            tx_buf: 0,
            rx_buf: 0,
        })
    }

    /// `CURRENT_MODE`: PX4's mode and its standard mode.
    fn current_mode(&self) -> MavMessage {
        MavMessage::CURRENT_MODE(CURRENT_MODE_DATA {
            custom_mode: self.mode.custom_mode(),
            intended_custom_mode: self.mode.custom_mode(),
            standard_mode: self.standard_mode(),
        })
    }

    /// `HOME_POSITION`; none before PX4's first global position.
    fn home_position(&self, s: &Stamp) -> Option<MavMessage> {
        let Stamp { time_usec, .. } = *s;
        if !self.has_fix {
            return None; // PX4 has no home before its first global position
        }
        let (latitude, longitude, altitude) = self.home.to_mavlink();
        Some(MavMessage::HOME_POSITION(HOME_POSITION_DATA {
            latitude,
            longitude,
            altitude,
            x: self.home_local.north_m as f32,
            y: self.home_local.east_m as f32,
            z: self.home_local.down_m as f32,
            q: quaternion(0.0, 0.0, self.home_yaw_rad),
            approach_x: 0.0,
            approach_y: 0.0,
            approach_z: 0.0,
            time_usec,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quaternion_of_yaw_only() {
        let q = quaternion(0.0, 0.0, std::f64::consts::FRAC_PI_2);
        assert!((q[0] - 0.70710677).abs() < 1e-6 && (q[3] - 0.70710677).abs() < 1e-6);
    }

    #[test]
    fn body_rotation_of_gravity_when_level() {
        let b = ned_to_body(Ned::new(0.0, 0.0, -9.8), 0.0, 0.0, 1.0);
        assert!(b[0].abs() < 1e-9 && b[1].abs() < 1e-9 && (b[2] + 9.8).abs() < 1e-9);
        // Heading east: a north vector is on the left (−y in FRD).
        let b = ned_to_body(
            Ned::new(1.0, 0.0, 0.0),
            0.0,
            0.0,
            std::f64::consts::FRAC_PI_2,
        );
        assert!(b[0].abs() < 1e-9 && (b[1] + 1.0).abs() < 1e-9);
    }
}
