//! Builders of the simulated sensors' telemetry (IMU, GPS, barometer, range finder,
//! altitude, battery, vibration) from the vehicle state, in PX4's field conventions; the
//! other messages are in [`super::messages`].

#![allow(deprecated)]

use super::messages::{Stamp, heading_deg, ned_to_body};
use crate::vehicle::gnss::GnssFix;
use crate::vehicle::{GRAVITY_M_S2, Goal, Vehicle};
use skein_mavlink::MavMessage;
use skein_mavlink::dialect::*;
use skein_model::geo::Ned;

/// The receiver's HDOP × 100 (`GPS_RAW_INT.eph` as PX4 fills it): the sky's geometry,
/// the same in every fix state (PX4 SIH's 0.7).
const GNSS_HDOP_X100: u16 = 70;
/// The receiver's VDOP × 100 (`GPS_RAW_INT.epv`; PX4 SIH's 1.1).
const GNSS_VDOP_X100: u16 = 110;
/// Without the error model, a 3D fix reports what PX4 SIH's GPS reports (`Sih::gps_fix`:
/// `eph` 0.9 m, `epv` 1.78 m), as `GPS_RAW_INT.h_acc` / `v_acc`, mm: a PX4 SITL client
/// sees the same accuracy from the simulator as from SIH.
const SIH_3D_ACC_MM: (u32, u32) = (900, 1780);
/// Satellites used in the fix (`GPS_RAW_INT.satellites_visible` is PX4's
/// `satellites_used`).
const GNSS_SATELLITES_USED: u8 = 12;

/// ISA static pressure at `alt_m` AMSL, hPa.
fn pressure_hpa(alt_m: f64) -> f64 {
    1013.25 * (1.0 - 2.255_77e-5 * alt_m).max(0.0).powf(5.255_88)
}

/// ISA temperature at `alt_m` AMSL, °C.
fn temperature_c(alt_m: f64) -> f64 {
    15.0 - 0.0065 * alt_m
}

impl Vehicle {
    /// `HIGHRES_IMU`: specific force and Earth's field in the body frame, rates, ISA pressure.
    pub(super) fn highres_imu(&self, s: &Stamp) -> MavMessage {
        let Stamp { time_usec, est, .. } = *s;
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

    /// `ALTITUDE`: AMSL, local, above home and above the ground.
    pub(super) fn altitude(&self, s: &Stamp) -> MavMessage {
        let Stamp { time_usec, est, .. } = *s;
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

    /// `DISTANCE_SENSOR`: a downward laser range finder (10 cm to 40 m), tilt-corrected.
    pub(super) fn distance_sensor(&self, s: &Stamp) -> MavMessage {
        let Stamp { time_boot_ms, .. } = *s;
        let tilt = self.roll_rad.cos() * self.pitch_rad.cos();
        let range_cm =
            ((-self.pos.down_m).max(0.0) / tilt.max(0.2) * 100.0 + 10.0).clamp(10.0, 4000.0);
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

    /// `GPS_RAW_INT` as PX4's stream fills it from the receiver (none before the EKF's
    /// first fix): the fix type of the RTK state, the receiver's position (truth plus its
    /// error and white noise with `gnss_wander`, plus the configured GPS noise), `eph` /
    /// `epv` the DOPs × 100, `h_acc` / `v_acc` the accuracy the receiver reports in its
    /// state (mm; without the error model a 3D fix reports PX4 SIH's figures),
    /// `satellites_visible` the satellites used.
    pub(super) fn gps_raw_int(&mut self, s: &Stamp) -> MavMessage {
        let Stamp {
            now,
            time_usec,
            vel,
            ..
        } = *s;
        let fix = self.ekf_ok(now);
        let mut position = self.pos + self.est_noise + self.gps_white_noise();
        if self.gnss.wanders() {
            position = position + self.gnss.fix_error();
        }
        let geo = self.geo_of(position);
        let (lat, lon, alt) = if fix { geo.to_mavlink() } else { (0, 0, 0) };
        let speed = vel.horizontal_norm();
        let figures = self.gnss.figures();
        let (h_acc, v_acc) = if !self.gnss.wanders() && self.gnss.fix() == GnssFix::Fix3d {
            SIH_3D_ACC_MM
        } else {
            (figures.h_acc_mm(), figures.v_acc_mm())
        };
        MavMessage::GPS_RAW_INT(GPS_RAW_INT_DATA {
            time_usec,
            lat,
            lon,
            alt,
            eph: if fix { GNSS_HDOP_X100 } else { u16::MAX },
            epv: if fix { GNSS_VDOP_X100 } else { u16::MAX },
            vel: (speed * 100.0).round() as u16,
            cog: if speed > 0.5 {
                (heading_deg(vel.east_m.atan2(vel.north_m)) * 100.0)
                    .round()
                    .min(35999.0) as u16
            } else {
                u16::MAX
            },
            fix_type: if fix {
                self.gnss.fix().fix_type()
            } else {
                GpsFixType::GPS_FIX_TYPE_NO_FIX
            },
            satellites_visible: if fix { GNSS_SATELLITES_USED } else { 3 },
            // Geoid separation near Zurich: about 47 m.
            alt_ellipsoid: if fix { alt + 47_000 } else { 0 },
            h_acc: if fix { h_acc } else { u32::MAX },
            v_acc: if fix { v_acc } else { u32::MAX },
            vel_acc: if fix { 200 } else { u32::MAX },
            hdg_acc: 0,
            yaw: 0,
        })
    }

    /// `SCALED_PRESSURE`: ISA pressure and temperature at the true altitude.
    pub(super) fn scaled_pressure(&self, s: &Stamp) -> MavMessage {
        let Stamp { time_boot_ms, .. } = *s;
        let alt = self.origin.origin.alt_amsl_m - self.pos.down_m;
        MavMessage::SCALED_PRESSURE(SCALED_PRESSURE_DATA {
            time_boot_ms,
            press_abs: pressure_hpa(alt) as f32,
            press_diff: 0.0,
            temperature: (temperature_c(alt) * 100.0).round() as i16,
            temperature_press_diff: 0,
        })
    }

    /// `BATTERY_STATUS`: voltage, current, consumption, time left, charge state.
    pub(super) fn battery_status(&self) -> MavMessage {
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

    /// `VIBRATION`: levels of a flying or resting airframe.
    pub(super) fn vibration(&self, s: &Stamp) -> MavMessage {
        let Stamp { time_usec, .. } = *s;
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
}
