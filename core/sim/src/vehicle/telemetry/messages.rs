//! Builders of every telemetry message from the vehicle state (PX4's field conventions:
//! frames, units, `custom_mode`, SYS_STATUS sensor bits), for streams and on request.

#![allow(deprecated)]

use super::PX4_FLIGHT_SW_VERSION;
use super::scheduler::Stream;
use crate::vehicle::{GRAVITY_M_S2, Goal, Outbox, Vehicle};
use skein_mavlink::MavMessage;
use skein_mavlink::dialect::*;
use skein_model::geo::{Ned, wrap_pi};
use skein_model::px4::Px4Mode;
use std::time::{Instant, SystemTime, UNIX_EPOCH};

/// Quaternion (w, x, y, z) of ZYX Euler angles.
fn quaternion(roll: f64, pitch: f64, yaw: f64) -> [f32; 4] {
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
fn ned_to_body(v: Ned, roll: f64, pitch: f64, yaw: f64) -> [f64; 3] {
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

/// ISA static pressure at `alt_m` AMSL, hPa.
fn pressure_hpa(alt_m: f64) -> f64 {
    1013.25 * (1.0 - 2.255_77e-5 * alt_m).max(0.0).powf(5.255_88)
}

/// ISA temperature at `alt_m` AMSL, °C.
fn temperature_c(alt_m: f64) -> f64 {
    15.0 - 0.0065 * alt_m
}

fn heading_deg(yaw_rad: f64) -> f64 {
    let d = yaw_rad.to_degrees().rem_euclid(360.0);
    if d >= 360.0 { 0.0 } else { d }
}

impl Vehicle {
    pub(super) fn autopilot_version(&self) -> MavMessage {
        let caps = MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT
            | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_INT
            | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_COMMAND_INT
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
        let time_boot_ms = self.time_boot_ms(now);
        let time_usec = self.time_boot_us(now);
        let est = self.est_pos();
        let vel = self.est_vel();
        let msg = match stream {
            Stream::Heartbeat => MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                custom_mode: self.mode.custom_mode(),
                mavtype: MavType::MAV_TYPE_QUADROTOR,
                autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
                base_mode: self.base_mode(),
                system_status: self.system_status(now),
                mavlink_version: 3,
            }),
            Stream::Attitude => MavMessage::ATTITUDE(ATTITUDE_DATA {
                time_boot_ms,
                roll: self.roll_rad as f32,
                pitch: self.pitch_rad as f32,
                yaw: self.yaw_rad as f32,
                rollspeed: self.roll_rate_rad_s as f32,
                pitchspeed: self.pitch_rate_rad_s as f32,
                yawspeed: self.yaw_rate_rad_s as f32,
            }),
            Stream::AttitudeQuaternion => {
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
            Stream::GlobalPositionInt => {
                if !self.ekf_ok(now) {
                    return; // PX4 sends no global position before the EKF has one
                }
                let (lat, lon, alt) = self.geo_of(est).to_mavlink();
                MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
                    time_boot_ms,
                    lat,
                    lon,
                    alt,
                    relative_alt: ((self.home_local.down_m - est.down_m) * 1000.0).round() as i32,
                    vx: (vel.north_m * 100.0).round() as i16,
                    vy: (vel.east_m * 100.0).round() as i16,
                    vz: (vel.down_m * 100.0).round() as i16,
                    hdg: (heading_deg(self.yaw_rad) * 100.0).round().min(35999.0) as u16,
                })
            }
            Stream::HighresImu => {
                let specific_force = Ned::new(
                    self.thrust_acc.north_m,
                    self.thrust_acc.east_m,
                    self.thrust_acc.down_m,
                );
                let acc = if self.armed && !matches!(self.goal, Goal::Idle) {
                    ned_to_body(specific_force, self.roll_rad, self.pitch_rad, self.yaw_rad)
                } else if matches!(self.goal, Goal::FreeFall) {
                    [0.0, 0.0, 0.0]
                } else {
                    [0.0, 0.0, -GRAVITY_M_S2]
                };
                // Earth field near Zurich, gauss (NED).
                let mag = ned_to_body(
                    Ned::new(0.21, 0.01, 0.43),
                    self.roll_rad,
                    self.pitch_rad,
                    self.yaw_rad,
                );
                let alt = self.origin.origin.alt_amsl_m - est.down_m;
                MavMessage::HIGHRES_IMU(HIGHRES_IMU_DATA {
                    time_usec,
                    xacc: acc[0] as f32,
                    yacc: acc[1] as f32,
                    zacc: acc[2] as f32,
                    xgyro: self.roll_rate_rad_s as f32,
                    ygyro: self.pitch_rate_rad_s as f32,
                    zgyro: self.yaw_rate_rad_s as f32,
                    xmag: mag[0] as f32,
                    ymag: mag[1] as f32,
                    zmag: mag[2] as f32,
                    abs_pressure: pressure_hpa(alt) as f32,
                    diff_pressure: 0.0,
                    pressure_alt: alt as f32,
                    temperature: temperature_c(alt) as f32,
                    fields_updated: HighresImuUpdatedFlags::from_bits_retain(0x1fff),
                    id: 0,
                })
            }
            Stream::LocalPositionNed => MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
                time_boot_ms,
                x: est.north_m as f32,
                y: est.east_m as f32,
                z: est.down_m as f32,
                vx: vel.north_m as f32,
                vy: vel.east_m as f32,
                vz: vel.down_m as f32,
            }),
            Stream::Odometry => {
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
            Stream::Timesync => MavMessage::TIMESYNC(TIMESYNC_DATA {
                tc1: 0,
                ts1: time_usec as i64 * 1000,
                target_system: 0,
                target_component: 0,
            }),
            Stream::Altitude => {
                let amsl = (self.origin.origin.alt_amsl_m - est.down_m) as f32;
                MavMessage::ALTITUDE(ALTITUDE_DATA {
                    time_usec,
                    altitude_monotonic: amsl,
                    altitude_amsl: amsl,
                    altitude_local: -est.down_m as f32,
                    altitude_relative: (self.home_local.down_m - est.down_m) as f32,
                    altitude_terrain: f32::NAN,
                    bottom_clearance: (-self.pos.down_m).max(0.0) as f32,
                })
            }
            Stream::DistanceSensor => {
                let tilt = self.roll_rad.cos() * self.pitch_rad.cos();
                let range_cm = ((-self.pos.down_m).max(0.0) / tilt.max(0.2) * 100.0 + 10.0)
                    .clamp(10.0, 4000.0);
                MavMessage::DISTANCE_SENSOR(DISTANCE_SENSOR_DATA {
                    time_boot_ms,
                    min_distance: 10,
                    max_distance: 4000,
                    current_distance: range_cm.round() as u16,
                    mavtype: MavDistanceSensor::MAV_DISTANCE_SENSOR_LASER,
                    id: 0,
                    orientation: MavSensorOrientation::MAV_SENSOR_ROTATION_PITCH_270,
                    covariance: 0,
                    horizontal_fov: 0.0,
                    vertical_fov: 0.0,
                    quaternion: [0.0; 4],
                    signal_quality: 100,
                })
            }
            Stream::AttitudeTarget => MavMessage::ATTITUDE_TARGET(ATTITUDE_TARGET_DATA {
                time_boot_ms,
                q: quaternion(self.roll_rad, self.pitch_rad, self.ctrl_yaw_sp),
                body_roll_rate: self.roll_rate_rad_s as f32,
                body_pitch_rate: self.pitch_rate_rad_s as f32,
                body_yaw_rate: self.yaw_rate_rad_s as f32,
                thrust: self.thrust_norm() as f32,
                type_mask: AttitudeTargetTypemask::empty(),
            }),
            Stream::PositionTargetLocalNed => {
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
            Stream::ServoOutputRaw => {
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
            Stream::VfrHud => {
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
            Stream::GpsRawInt => {
                let fix = self.ekf_ok(now);
                let noisy = self.pos + self.est_noise + self.gps_white_noise();
                let geo = self.geo_of(noisy);
                let (lat, lon, alt) = if fix { geo.to_mavlink() } else { (0, 0, 0) };
                let speed = vel.horizontal_norm();
                MavMessage::GPS_RAW_INT(GPS_RAW_INT_DATA {
                    time_usec,
                    lat,
                    lon,
                    alt,
                    eph: if fix { 80 } else { u16::MAX },
                    epv: if fix { 120 } else { u16::MAX },
                    vel: (speed * 100.0).round() as u16,
                    cog: if speed > 0.5 {
                        (heading_deg(vel.east_m.atan2(vel.north_m)) * 100.0)
                            .round()
                            .min(35999.0) as u16
                    } else {
                        u16::MAX
                    },
                    fix_type: if fix {
                        GpsFixType::GPS_FIX_TYPE_3D_FIX
                    } else {
                        GpsFixType::GPS_FIX_TYPE_NO_FIX
                    },
                    satellites_visible: if fix { 12 } else { 3 },
                    // Geoid separation near Zurich: about 47 m.
                    alt_ellipsoid: if fix { alt + 47_000 } else { 0 },
                    h_acc: if fix { 500 } else { u32::MAX },
                    v_acc: if fix { 800 } else { u32::MAX },
                    vel_acc: if fix { 200 } else { u32::MAX },
                    hdg_acc: 0,
                    yaw: 0,
                })
            }
            Stream::ExtendedSysState => MavMessage::EXTENDED_SYS_STATE(EXTENDED_SYS_STATE_DATA {
                vtol_state: MavVtolState::MAV_VTOL_STATE_UNDEFINED,
                landed_state: match self.landed_state() {
                    skein_model::px4::LandedState::Undefined => {
                        MavLandedState::MAV_LANDED_STATE_UNDEFINED
                    }
                    skein_model::px4::LandedState::OnGround => {
                        MavLandedState::MAV_LANDED_STATE_ON_GROUND
                    }
                    skein_model::px4::LandedState::InAir => MavLandedState::MAV_LANDED_STATE_IN_AIR,
                    skein_model::px4::LandedState::Takeoff => {
                        MavLandedState::MAV_LANDED_STATE_TAKEOFF
                    }
                    skein_model::px4::LandedState::Landing => {
                        MavLandedState::MAV_LANDED_STATE_LANDING
                    }
                },
            }),
            Stream::SysStatus => self.sys_status(now),
            Stream::EstimatorStatus => {
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
            Stream::Ping => {
                self.ping_seq = self.ping_seq.wrapping_add(1);
                MavMessage::PING(PING_DATA {
                    time_usec,
                    seq: self.ping_seq,
                    target_system: 0,
                    target_component: 0,
                })
            }
            Stream::SystemTime => MavMessage::SYSTEM_TIME(SYSTEM_TIME_DATA {
                time_unix_usec: SystemTime::now()
                    .duration_since(UNIX_EPOCH)
                    .map(|d| d.as_micros() as u64)
                    .unwrap_or(0),
                time_boot_ms,
            }),
            Stream::ScaledPressure => {
                let alt = self.origin.origin.alt_amsl_m - self.pos.down_m;
                MavMessage::SCALED_PRESSURE(SCALED_PRESSURE_DATA {
                    time_boot_ms,
                    press_abs: pressure_hpa(alt) as f32,
                    press_diff: 0.0,
                    temperature: (temperature_c(alt) * 100.0).round() as i16,
                    temperature_press_diff: 0,
                })
            }
            Stream::MissionCurrent => MavMessage::MISSION_CURRENT(MISSION_CURRENT_DATA {
                seq: 0,
                total: 0,
                mission_state: MissionState::MISSION_STATE_NO_MISSION,
                mission_mode: u8::from(self.mode == Px4Mode::Mission),
                mission_id: 0,
                fence_id: 0,
                rally_points_id: 0,
            }),
            Stream::LinkNodeStatus => MavMessage::LINK_NODE_STATUS(LINK_NODE_STATUS_DATA {
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
            }),
            Stream::BatteryStatus => {
                let b = self.battery;
                let mut voltages = [u16::MAX; 10];
                voltages[0] = (b.voltage_v * 1000.0).round() as u16;
                let remaining_pct = (b.remaining * 100.0).round() as i8;
                MavMessage::BATTERY_STATUS(BATTERY_STATUS_DATA {
                    current_consumed: b.consumed_mah.round() as i32,
                    energy_consumed: -1,
                    temperature: i16::MAX,
                    voltages,
                    current_battery: (b.current_a * 100.0).round() as i16,
                    id: 0,
                    battery_function: MavBatteryFunction::MAV_BATTERY_FUNCTION_ALL,
                    mavtype: MavBatteryType::MAV_BATTERY_TYPE_LIPO,
                    battery_remaining: remaining_pct,
                    time_remaining: {
                        let capacity = self.params.get(crate::px4_params::Param::BAT1_CAPACITY);
                        let left_mah = (capacity - b.consumed_mah).max(0.0);
                        (left_mah / b.current_a.max(0.1) * 3.6).round() as i32
                    },
                    charge_state: if remaining_pct > 30 {
                        MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_OK
                    } else if remaining_pct > 15 {
                        MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_LOW
                    } else {
                        MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_CRITICAL
                    },
                    voltages_ext: [0; 4],
                    mode: MavBatteryMode::MAV_BATTERY_MODE_UNKNOWN,
                    fault_bitmask: MavBatteryFault::empty(),
                })
            }
            Stream::CurrentMode => MavMessage::CURRENT_MODE(CURRENT_MODE_DATA {
                custom_mode: self.mode.custom_mode(),
                intended_custom_mode: self.mode.custom_mode(),
                standard_mode: self.standard_mode(),
            }),
            Stream::HomePosition => {
                if !self.has_fix {
                    return; // PX4 has no home before its first global position
                }
                let (latitude, longitude, altitude) = self.home.to_mavlink();
                MavMessage::HOME_POSITION(HOME_POSITION_DATA {
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
                })
            }
            Stream::Vibration => {
                let level = if self.armed && !self.landed {
                    0.03
                } else {
                    0.002
                };
                MavMessage::VIBRATION(VIBRATION_DATA {
                    time_usec,
                    vibration_x: level,
                    vibration_y: level,
                    vibration_z: level * 1.5,
                    clipping_0: 0,
                    clipping_1: 0,
                    clipping_2: 0,
                })
            }
        };
        out.push(&msg);
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
