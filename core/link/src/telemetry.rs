//! Telemetry of one vehicle, folded from the MAVLink messages PX4 streams.
//!
//! [`Telemetry::apply`] updates the latest values from one message and says what changed
//! in a way the FSM cares about ([`Change`]); the continuous values (positions, attitude)
//! are read by whoever needs them from the shared snapshot.

use serde::Serialize;
use skein_mavlink::MavMessage;
use skein_mavlink::dialect::{
    HOME_POSITION_DATA, MavModeFlag, MavSeverity, MavSysStatusSensor, MavType,
};
use skein_model::fsm::Observed;
use skein_model::geo::{GeoPoint, Ned, NedFrame};
use skein_model::px4::{LandedState, Px4Mode};
use skein_model::vehicle::{PX4_MESSAGES_KEPT, Px4Message};
use std::collections::VecDeque;
use std::time::Instant;

/// From `HEARTBEAT`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Heartbeat {
    /// `base_mode & MAV_MODE_FLAG_SAFETY_ARMED`.
    pub armed: bool,
    /// Decoded `custom_mode`.
    pub mode: Px4Mode,
    /// `system_status` (`MAV_STATE`) as a number.
    pub system_status: u8,
}

/// From `GLOBAL_POSITION_INT`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GlobalPosition {
    /// Geodetic position (`lat`, `lon`, `alt` AMSL).
    pub geo: GeoPoint,
    /// Height above home, metres (`relative_alt`).
    pub relative_alt_m: f64,
    /// Ground velocity NED, m/s (`vx`, `vy`, `vz`).
    pub velocity_m_s: Ned,
    /// Heading, degrees in `[0, 360)` (`hdg`), `None` when PX4 reports `UINT16_MAX`.
    pub heading_deg: Option<f64>,
    /// Vehicle boot time, ms (`time_boot_ms`).
    pub time_boot_ms: u32,
}

/// From `LOCAL_POSITION_NED` (the vehicle's own local frame).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LocalPosition {
    /// Position in the vehicle's local NED frame, metres.
    pub position: Ned,
    /// Velocity, NED m/s.
    pub velocity_m_s: Ned,
}

/// From `ATTITUDE`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Attitude {
    /// Roll, radians.
    pub roll_rad: f64,
    /// Pitch, radians.
    pub pitch_rad: f64,
    /// Yaw, radians clockwise from north, `(-π, π]`.
    pub yaw_rad: f64,
}

/// From `BATTERY_STATUS` (remaining) and `SYS_STATUS` (voltage).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BatteryTelemetry {
    /// Remaining charge, percent; `None` when unknown (-1).
    pub percent: Option<f64>,
    /// Voltage, volts; `None` when unknown.
    pub voltage_v: Option<f64>,
}

/// From `HOME_POSITION`: the home both as a geodetic point and in local coordinates,
/// which together give the vehicle's local NED origin.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Home {
    /// Geodetic home.
    pub geo: GeoPoint,
    /// Home in the vehicle's local NED frame, metres.
    pub local: Ned,
    /// The local NED frame these two give ([`NedFrame::from_reference`]), worked out once
    /// when the home arrives, not at every use.
    #[serde(skip)]
    pub origin: NedFrame,
}

/// The latest telemetry of one vehicle.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Telemetry {
    /// Last heartbeat from the autopilot.
    pub heartbeat: Option<Heartbeat>,
    /// `EXTENDED_SYS_STATE.landed_state`.
    pub landed_state: LandedState,
    /// Last global position.
    pub global: Option<GlobalPosition>,
    /// Last local position.
    pub local: Option<LocalPosition>,
    /// When the last local position arrived.
    #[serde(skip)]
    pub local_received: Option<Instant>,
    /// Last attitude.
    pub attitude: Option<Attitude>,
    /// Battery.
    pub battery: Option<BatteryTelemetry>,
    /// Home position.
    pub home: Option<Home>,
    /// `GPS_RAW_INT.fix_type` (3 = 3D fix).
    pub gps_fix_type: Option<u8>,
    /// `GPS_RAW_INT.satellites_visible`.
    pub satellites: Option<u8>,
    /// Horizontal position accuracy, metres: `GPS_RAW_INT.h_acc` (mm; PX4 fills it with
    /// the receiver's estimate), or `eph` read as centimetres where `h_acc` is absent or 0
    /// (`eph` is the HDOP × 100 as PX4 fills it, and the accuracy in cm for some older
    /// autopilots); `None`: unknown.
    pub gps_eph_m: Option<f64>,
    /// Vertical position accuracy, metres (`v_acc`, else `epv`, as above).
    pub gps_epv_m: Option<f64>,
    /// `SYS_STATUS`: PX4's arming checks pass (`MAV_SYS_STATUS_PREARM_CHECK` healthy);
    /// `None` while no `SYS_STATUS` said (the bit not present).
    pub prearm_ok: Option<bool>,
    /// The vehicle's latest warnings and errors (`STATUSTEXT`, severity 4 or worse),
    /// oldest first, at most [`PX4_MESSAGES_KEPT`] ([`Telemetry::keep_message`]).
    pub px4_messages: VecDeque<Px4Message>,
    /// The vehicle's Remote ID transmitter's last `OPEN_DRONE_ID_ARM_STATUS`, whichever
    /// of its components sent it.
    pub remote_id: Option<skein_model::vehicle::RemoteIdArmStatus>,
    /// PX4's last health and arming check report (its events), once one arrived.
    #[serde(skip)]
    pub arming_report: Option<crate::events::ArmingReport>,
    /// The vehicle's events: their metadata, how they arrived.
    pub px4_events: crate::events::EventsStatus,
    /// The vehicle's boot clock in the last message that carried one, ms.
    pub boot_ms: Option<u32>,
    /// Messages applied.
    pub messages: u64,
    /// When the last message arrived.
    #[serde(skip)]
    pub last_message_at: Option<Instant>,
}

/// What a message changed that matters to the vehicle's state machine.
#[derive(Debug, Clone, PartialEq)]
pub enum Change {
    /// Nothing the FSM cares about.
    None,
    /// Armed flag, mode or landed state changed (or first heartbeat).
    Observed(Observed),
    /// The vehicle's boot time went backwards: it rebooted.
    Rebooted,
}

/// A boot clock going back by more than this means the autopilot restarted (UDP may
/// reorder a few milliseconds, never this much).
pub const REBOOT_JUMP_MS: u32 = 200;

/// `time_boot_ms` of the messages that carry it (`ATTITUDE`, `GLOBAL_POSITION_INT`,
/// `LOCAL_POSITION_NED`, `SYSTEM_TIME`), milliseconds since the autopilot booted; `None`
/// for the others. [`Telemetry::apply`] compares it across messages to see a reboot, so
/// whoever applies messages must apply all of these in the order they arrived.
pub fn boot_time_ms(msg: &MavMessage) -> Option<u32> {
    match msg {
        MavMessage::ATTITUDE(m) => Some(m.time_boot_ms),
        MavMessage::GLOBAL_POSITION_INT(m) => Some(m.time_boot_ms),
        MavMessage::LOCAL_POSITION_NED(m) => Some(m.time_boot_ms),
        MavMessage::SYSTEM_TIME(m) => Some(m.time_boot_ms),
        _ => None,
    }
}

impl Telemetry {
    /// The armed/mode/landed triple the FSM consumes, once a heartbeat has arrived.
    pub fn observed(&self) -> Option<Observed> {
        self.heartbeat.map(|hb| Observed {
            armed: hb.armed,
            mode: hb.mode,
            landed: self.landed_state,
        })
    }

    /// The vehicle's local NED frame (its EKF origin), recovered from `HOME_POSITION`.
    pub fn local_frame(&self) -> Option<NedFrame> {
        self.home.map(|h| h.origin)
    }

    /// Heading in degrees `[0, 360)`, from `GLOBAL_POSITION_INT.hdg` or `ATTITUDE.yaw`.
    pub fn heading_deg(&self) -> Option<f64> {
        self.global.and_then(|g| g.heading_deg).or_else(|| {
            self.attitude
                .map(|a| skein_model::geo::wrap_deg_360(a.yaw_rad.to_degrees()))
        })
    }

    /// PX4's checks that report a problem, as the last report has them in the current
    /// mode (empty without a report: no events interface, or nothing fails).
    pub fn px4_arming_checks(&self) -> Vec<skein_model::vehicle::Px4ArmingCheck> {
        let mode = self.heartbeat.map(|h| h.mode.custom_mode());
        self.arming_report
            .as_ref()
            .map(|r| r.checks_for(mode))
            .unwrap_or_default()
    }

    /// Folds one message from the autopilot component into the telemetry.
    pub fn apply(&mut self, msg: &MavMessage, now: Instant) -> Change {
        self.messages += 1;
        self.last_message_at = Some(now);
        if self.note_boot_time(msg) {
            return Change::Rebooted;
        }
        let before = self.observed();
        match msg {
            MavMessage::HEARTBEAT(hb) => {
                if matches!(
                    hb.mavtype,
                    MavType::MAV_TYPE_GCS | MavType::MAV_TYPE_ONBOARD_CONTROLLER
                ) {
                    return Change::None;
                }
                self.heartbeat = Some(Heartbeat {
                    armed: hb
                        .base_mode
                        .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED),
                    mode: Px4Mode::from_custom_mode(hb.custom_mode),
                    system_status: hb.system_status as u8,
                });
            }
            MavMessage::EXTENDED_SYS_STATE(s) => {
                self.landed_state = LandedState::from_mavlink(s.landed_state as u8);
            }
            msg => self.apply_state(msg, now),
        }
        match (before, self.observed()) {
            (b, Some(now_obs)) if b != Some(now_obs) => Change::Observed(now_obs),
            _ => Change::None,
        }
    }

    /// Notes the boot time `msg` carries, if any; true when it jumped back (a reboot:
    /// the old home is forgotten, a rebooted EKF may have a new origin, until the
    /// vehicle sends HOME_POSITION again).
    fn note_boot_time(&mut self, msg: &MavMessage) -> bool {
        let Some(boot_ms) = boot_time_ms(msg) else {
            return false;
        };
        let rebooted = self
            .boot_ms
            .is_some_and(|last| boot_ms.saturating_add(REBOOT_JUMP_MS) < last);
        self.boot_ms = Some(boot_ms);
        if rebooted {
            self.home = None;
        }
        rebooted
    }

    /// Folds a message of the vehicle's state (position, attitude, battery, home, GPS)
    /// into the telemetry; any other message is ignored.
    fn apply_state(&mut self, msg: &MavMessage, now: Instant) {
        match msg {
            MavMessage::GLOBAL_POSITION_INT(g) => {
                self.global = Some(GlobalPosition {
                    geo: GeoPoint::from_mavlink(g.lat, g.lon, g.alt),
                    relative_alt_m: f64::from(g.relative_alt) * 1e-3,
                    velocity_m_s: Ned::new(
                        f64::from(g.vx) * 0.01,
                        f64::from(g.vy) * 0.01,
                        f64::from(g.vz) * 0.01,
                    ),
                    heading_deg: (g.hdg != u16::MAX).then(|| f64::from(g.hdg) * 0.01),
                    time_boot_ms: g.time_boot_ms,
                });
            }
            MavMessage::LOCAL_POSITION_NED(l) => {
                self.local_received = Some(now);
                self.local = Some(LocalPosition {
                    position: Ned::new(l.x.into(), l.y.into(), l.z.into()),
                    velocity_m_s: Ned::new(l.vx.into(), l.vy.into(), l.vz.into()),
                });
            }
            MavMessage::ATTITUDE(a) => {
                self.attitude = Some(Attitude {
                    roll_rad: a.roll.into(),
                    pitch_rad: a.pitch.into(),
                    yaw_rad: a.yaw.into(),
                });
            }
            MavMessage::BATTERY_STATUS(b) => {
                let b_pct = (b.battery_remaining >= 0).then(|| f64::from(b.battery_remaining));
                let entry = self.battery.get_or_insert(BatteryTelemetry {
                    percent: None,
                    voltage_v: None,
                });
                entry.percent = b_pct;
                if entry.voltage_v.is_none() && b.voltages[0] != u16::MAX {
                    entry.voltage_v = Some(f64::from(b.voltages[0]) * 1e-3);
                }
            }
            MavMessage::SYS_STATUS(s) => {
                let prearm = MavSysStatusSensor::MAV_SYS_STATUS_PREARM_CHECK;
                self.prearm_ok = s
                    .onboard_control_sensors_present
                    .contains(prearm)
                    .then(|| s.onboard_control_sensors_health.contains(prearm));
                let entry = self.battery.get_or_insert(BatteryTelemetry {
                    percent: None,
                    voltage_v: None,
                });
                if s.voltage_battery != u16::MAX {
                    entry.voltage_v = Some(f64::from(s.voltage_battery) * 1e-3);
                }
                if entry.percent.is_none() && s.battery_remaining >= 0 {
                    entry.percent = Some(f64::from(s.battery_remaining));
                }
            }
            MavMessage::HOME_POSITION(h) => self.apply_home(h),
            MavMessage::GPS_RAW_INT(g) => {
                self.gps_fix_type = Some(g.fix_type as u8);
                self.satellites = Some(g.satellites_visible);
                let metres = |acc_mm: u32, cm: u16| {
                    if acc_mm != 0 && acc_mm != u32::MAX {
                        Some(f64::from(acc_mm) * 1e-3)
                    } else {
                        (cm != u16::MAX).then(|| f64::from(cm) * 0.01)
                    }
                };
                self.gps_eph_m = metres(g.h_acc, g.eph);
                self.gps_epv_m = metres(g.v_acc, g.epv);
            }
            MavMessage::OPEN_DRONE_ID_ARM_STATUS(s) => {
                self.remote_id = Some(skein_model::vehicle::RemoteIdArmStatus {
                    good_to_arm: s.status as u8 == 0,
                    error: s.error.to_str().unwrap_or("<invalid utf-8>").to_string(),
                });
            }
            _ => {}
        }
    }

    /// Keeps a warning or error the vehicle sent (`STATUSTEXT`, chunks joined) at
    /// `unix_ms`, dropping the oldest past [`PX4_MESSAGES_KEPT`]; texts of severity 5
    /// (notice) and above are not kept.
    pub fn keep_message(&mut self, severity: u8, text: &str, unix_ms: u64) {
        if severity > MavSeverity::MAV_SEVERITY_WARNING as u8 {
            return;
        }
        if self.px4_messages.len() == PX4_MESSAGES_KEPT {
            self.px4_messages.pop_front();
        }
        self.px4_messages.push_back(Px4Message {
            severity,
            text: text.to_string(),
            unix_ms,
        });
    }

    /// A HOME_POSITION: PX4 repeats it (0.5 Hz here), the frame is worked out when it
    /// changes.
    fn apply_home(&mut self, h: &HOME_POSITION_DATA) {
        let geo = GeoPoint::from_mavlink(h.latitude, h.longitude, h.altitude);
        let local = Ned::new(h.x.into(), h.y.into(), h.z.into());
        if self
            .home
            .is_none_or(|old| old.geo != geo || old.local != local)
        {
            self.home = Some(Home {
                geo,
                local,
                origin: NedFrame::from_reference(geo, local),
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skein_mavlink::dialect::*;

    fn hb(armed: bool, mode: Px4Mode) -> MavMessage {
        let mut base = MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED;
        if armed {
            base |= MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
        }
        MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: mode.custom_mode(),
            mavtype: MavType::MAV_TYPE_QUADROTOR,
            autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
            base_mode: base,
            system_status: MavState::MAV_STATE_STANDBY,
            mavlink_version: 3,
        })
    }

    #[test]
    fn heartbeat_and_landed_state_produce_observations_only_on_change() {
        let mut t = Telemetry::default();
        let now = Instant::now();
        assert_eq!(
            t.apply(&hb(false, Px4Mode::Hold), now),
            Change::Observed(Observed {
                armed: false,
                mode: Px4Mode::Hold,
                landed: LandedState::Undefined
            })
        );
        assert_eq!(t.apply(&hb(false, Px4Mode::Hold), now), Change::None);
        let ext = MavMessage::EXTENDED_SYS_STATE(EXTENDED_SYS_STATE_DATA {
            vtol_state: MavVtolState::MAV_VTOL_STATE_UNDEFINED,
            landed_state: MavLandedState::MAV_LANDED_STATE_ON_GROUND,
        });
        assert!(
            matches!(t.apply(&ext, now), Change::Observed(o) if o.landed == LandedState::OnGround)
        );
        assert!(
            matches!(t.apply(&hb(true, Px4Mode::Offboard), now), Change::Observed(o) if o.armed && o.mode == Px4Mode::Offboard)
        );
    }

    #[test]
    fn home_position_gives_the_local_frame() {
        let swarm = NedFrame::new(GeoPoint::new(47.397742, 8.545594, 488.0));
        let origin = swarm.to_geo(Ned::new(0.0, 10.0, 0.0));
        let home_local = Ned::new(1.0, 2.0, -0.1);
        let home_geo = NedFrame::new(origin).to_geo(home_local);
        let (lat, lon, alt) = home_geo.to_mavlink();
        let mut t = Telemetry::default();
        t.apply(
            &MavMessage::HOME_POSITION(HOME_POSITION_DATA {
                latitude: lat,
                longitude: lon,
                altitude: alt,
                x: 1.0,
                y: 2.0,
                z: -0.1,
                ..HOME_POSITION_DATA::DEFAULT
            }),
            Instant::now(),
        );
        let frame = t.local_frame().unwrap();
        // degE7 / mm quantisation: about a centimetre.
        assert!(swarm.to_ned(&frame.origin).east_m - 10.0 < 0.02);
    }

    #[test]
    fn boot_time_going_backwards_is_a_reboot() {
        let mut t = Telemetry::default();
        let g = |ms| {
            MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
                time_boot_ms: ms,
                ..GLOBAL_POSITION_INT_DATA::DEFAULT
            })
        };
        assert_eq!(t.apply(&g(60_000), Instant::now()), Change::None);
        assert_eq!(t.apply(&g(60_020), Instant::now()), Change::None);
        // Slight reordering is not a reboot.
        assert_eq!(t.apply(&g(60_010), Instant::now()), Change::None);
        assert_eq!(t.apply(&g(150), Instant::now()), Change::Rebooted);
        // Even an early reboot (2 s after the first boot) shows.
        let mut t = Telemetry::default();
        assert_eq!(t.apply(&g(2002), Instant::now()), Change::None);
        assert_eq!(t.apply(&g(5), Instant::now()), Change::Rebooted);
    }
}
