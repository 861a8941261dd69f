//! PX4 facts as data: flight modes in `HEARTBEAT.custom_mode`, landed states, and the
//! `SET_POSITION_TARGET_LOCAL_NED.type_mask` combinations skein and its simulator use.
//!
//! Source: PX4 `px4_custom_mode.h` (v1.16) and the MAVLink common dialect; the observed
//! values are listed in the project's `px4.md`.

use serde::{Deserialize, Serialize};

/// PX4 main modes (`PX4_CUSTOM_MAIN_MODE_*`), bits 16..24 of `custom_mode`.
pub mod main_mode {
    /// `PX4_CUSTOM_MAIN_MODE_MANUAL`.
    pub const MANUAL: u8 = 1;
    /// `PX4_CUSTOM_MAIN_MODE_ALTCTL`.
    pub const ALTCTL: u8 = 2;
    /// `PX4_CUSTOM_MAIN_MODE_POSCTL`.
    pub const POSCTL: u8 = 3;
    /// `PX4_CUSTOM_MAIN_MODE_AUTO` (sub mode selects takeoff, hold, mission, RTL, land …).
    pub const AUTO: u8 = 4;
    /// `PX4_CUSTOM_MAIN_MODE_ACRO`.
    pub const ACRO: u8 = 5;
    /// `PX4_CUSTOM_MAIN_MODE_OFFBOARD`.
    pub const OFFBOARD: u8 = 6;
    /// `PX4_CUSTOM_MAIN_MODE_STABILIZED`.
    pub const STABILIZED: u8 = 7;
}

/// PX4 AUTO sub modes (`PX4_CUSTOM_SUB_MODE_AUTO_*`), bits 24..32 of `custom_mode`.
pub mod auto_sub_mode {
    /// `AUTO_READY`.
    pub const READY: u8 = 1;
    /// `AUTO_TAKEOFF`.
    pub const TAKEOFF: u8 = 2;
    /// `AUTO_LOITER`, shown as "Hold".
    pub const LOITER: u8 = 3;
    /// `AUTO_MISSION`.
    pub const MISSION: u8 = 4;
    /// `AUTO_RTL`.
    pub const RTL: u8 = 5;
    /// `AUTO_LAND`.
    pub const LAND: u8 = 6;
    /// `AUTO_FOLLOW_TARGET`.
    pub const FOLLOW_TARGET: u8 = 8;
    /// `AUTO_PRECLAND`.
    pub const PRECLAND: u8 = 9;
}

/// A PX4 flight mode, decoded from / encoded to `HEARTBEAT.custom_mode`
/// (`main_mode << 16 | sub_mode << 24`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Px4Mode {
    /// MANUAL (main 1).
    Manual,
    /// ALTCTL, altitude control (main 2).
    Altctl,
    /// POSCTL, position control (main 3).
    Posctl,
    /// AUTO.READY (4, 1).
    Ready,
    /// AUTO.TAKEOFF (4, 2): climbs to `MIS_TAKEOFF_ALT`.
    Takeoff,
    /// AUTO.LOITER (4, 3), "Hold": PX4's boot mode.
    Hold,
    /// AUTO.MISSION (4, 4).
    Mission,
    /// AUTO.RTL (4, 5): return to launch.
    Rtl,
    /// AUTO.LAND (4, 6).
    Land,
    /// AUTO.FOLLOW_TARGET (4, 8).
    FollowTarget,
    /// AUTO.PRECLAND (4, 9).
    Precland,
    /// ACRO (main 5).
    Acro,
    /// OFFBOARD (main 6): follows the setpoint stream.
    Offboard,
    /// STABILIZED (main 7).
    Stabilized,
    /// Any other `custom_mode` value, kept verbatim.
    Unknown(u32),
}

impl Px4Mode {
    /// Every named mode (without [`Px4Mode::Unknown`]), for tests and UIs.
    pub const ALL: [Px4Mode; 14] = [
        Px4Mode::Manual,
        Px4Mode::Altctl,
        Px4Mode::Posctl,
        Px4Mode::Ready,
        Px4Mode::Takeoff,
        Px4Mode::Hold,
        Px4Mode::Mission,
        Px4Mode::Rtl,
        Px4Mode::Land,
        Px4Mode::FollowTarget,
        Px4Mode::Precland,
        Px4Mode::Acro,
        Px4Mode::Offboard,
        Px4Mode::Stabilized,
    ];

    /// `(main_mode, sub_mode)` as used by `MAV_CMD_DO_SET_MODE` param2 / param3.
    pub fn main_sub(self) -> (u8, u8) {
        use auto_sub_mode as s;
        use main_mode as m;
        match self {
            Px4Mode::Manual => (m::MANUAL, 0),
            Px4Mode::Altctl => (m::ALTCTL, 0),
            Px4Mode::Posctl => (m::POSCTL, 0),
            Px4Mode::Ready => (m::AUTO, s::READY),
            Px4Mode::Takeoff => (m::AUTO, s::TAKEOFF),
            Px4Mode::Hold => (m::AUTO, s::LOITER),
            Px4Mode::Mission => (m::AUTO, s::MISSION),
            Px4Mode::Rtl => (m::AUTO, s::RTL),
            Px4Mode::Land => (m::AUTO, s::LAND),
            Px4Mode::FollowTarget => (m::AUTO, s::FOLLOW_TARGET),
            Px4Mode::Precland => (m::AUTO, s::PRECLAND),
            Px4Mode::Acro => (m::ACRO, 0),
            Px4Mode::Offboard => (m::OFFBOARD, 0),
            Px4Mode::Stabilized => (m::STABILIZED, 0),
            Px4Mode::Unknown(v) => (((v >> 16) & 0xff) as u8, ((v >> 24) & 0xff) as u8),
        }
    }

    /// The `HEARTBEAT.custom_mode` value (e.g. HOLD = 50593792, OFFBOARD = 393216).
    pub fn custom_mode(self) -> u32 {
        if let Px4Mode::Unknown(v) = self {
            return v;
        }
        let (main, sub) = self.main_sub();
        (u32::from(main) << 16) | (u32::from(sub) << 24)
    }

    /// Decodes `HEARTBEAT.custom_mode`. Sub modes of non-AUTO main modes are ignored, as
    /// PX4 does; anything unrecognised is [`Px4Mode::Unknown`].
    pub fn from_custom_mode(custom_mode: u32) -> Px4Mode {
        Self::from_main_sub(
            ((custom_mode >> 16) & 0xff) as u8,
            ((custom_mode >> 24) & 0xff) as u8,
        )
        .unwrap_or(Px4Mode::Unknown(custom_mode))
    }

    /// Decodes a `(main_mode, sub_mode)` pair as in `MAV_CMD_DO_SET_MODE`, `None` when
    /// PX4 has no such mode.
    pub fn from_main_sub(main: u8, sub: u8) -> Option<Px4Mode> {
        use auto_sub_mode as s;
        use main_mode as m;
        Some(match (main, sub) {
            (m::MANUAL, _) => Px4Mode::Manual,
            (m::ALTCTL, _) => Px4Mode::Altctl,
            (m::POSCTL, _) => Px4Mode::Posctl,
            (m::AUTO, s::READY) => Px4Mode::Ready,
            (m::AUTO, s::TAKEOFF) => Px4Mode::Takeoff,
            (m::AUTO, s::LOITER) => Px4Mode::Hold,
            (m::AUTO, s::MISSION) => Px4Mode::Mission,
            (m::AUTO, s::RTL) => Px4Mode::Rtl,
            (m::AUTO, s::LAND) => Px4Mode::Land,
            (m::AUTO, s::FOLLOW_TARGET) => Px4Mode::FollowTarget,
            (m::AUTO, s::PRECLAND) => Px4Mode::Precland,
            (m::ACRO, _) => Px4Mode::Acro,
            (m::OFFBOARD, _) => Px4Mode::Offboard,
            (m::STABILIZED, _) => Px4Mode::Stabilized,
            _ => return None,
        })
    }

    /// The name ground stations show: `HOLD`, `TAKEOFF`, `OFFBOARD`, `LAND`, `RTL`,
    /// `POSCTL`, `MISSION` …; `UNKNOWN` for unrecognised values.
    pub fn name(self) -> &'static str {
        match self {
            Px4Mode::Manual => "MANUAL",
            Px4Mode::Altctl => "ALTCTL",
            Px4Mode::Posctl => "POSCTL",
            Px4Mode::Ready => "READY",
            Px4Mode::Takeoff => "TAKEOFF",
            Px4Mode::Hold => "HOLD",
            Px4Mode::Mission => "MISSION",
            Px4Mode::Rtl => "RTL",
            Px4Mode::Land => "LAND",
            Px4Mode::FollowTarget => "FOLLOW_TARGET",
            Px4Mode::Precland => "PRECLAND",
            Px4Mode::Acro => "ACRO",
            Px4Mode::Offboard => "OFFBOARD",
            Px4Mode::Stabilized => "STABILIZED",
            Px4Mode::Unknown(_) => "UNKNOWN",
        }
    }

    /// Parses a name as returned by [`Px4Mode::name`] (case-insensitive).
    pub fn from_name(name: &str) -> Option<Px4Mode> {
        Px4Mode::ALL
            .into_iter()
            .find(|m| m.name().eq_ignore_ascii_case(name))
    }
}

impl std::fmt::Display for Px4Mode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// `MAV_LANDED_STATE` as reported in `EXTENDED_SYS_STATE.landed_state`.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default, utoipa::ToSchema,
)]
pub enum LandedState {
    /// `MAV_LANDED_STATE_UNDEFINED` (0), also used before the first report.
    #[default]
    Undefined,
    /// `MAV_LANDED_STATE_ON_GROUND` (1).
    OnGround,
    /// `MAV_LANDED_STATE_IN_AIR` (2).
    InAir,
    /// `MAV_LANDED_STATE_TAKEOFF` (3).
    Takeoff,
    /// `MAV_LANDED_STATE_LANDING` (4).
    Landing,
}

impl LandedState {
    /// Decodes the MAVLink enum value; unknown values are `Undefined`.
    pub fn from_mavlink(v: u8) -> LandedState {
        match v {
            1 => LandedState::OnGround,
            2 => LandedState::InAir,
            3 => LandedState::Takeoff,
            4 => LandedState::Landing,
            _ => LandedState::Undefined,
        }
    }

    /// The MAVLink enum value.
    pub fn to_mavlink(self) -> u8 {
        match self {
            LandedState::Undefined => 0,
            LandedState::OnGround => 1,
            LandedState::InAir => 2,
            LandedState::Takeoff => 3,
            LandedState::Landing => 4,
        }
    }

    /// True for `IN_AIR`, `TAKEOFF` and `LANDING`.
    pub fn is_airborne(self) -> bool {
        matches!(
            self,
            LandedState::InAir | LandedState::Takeoff | LandedState::Landing
        )
    }
}

/// `SET_POSITION_TARGET_LOCAL_NED.type_mask` bits (`POSITION_TARGET_TYPEMASK`): a set bit
/// means "ignore this field".
pub mod type_mask {
    /// Ignore x (north) position.
    pub const IGNORE_PX: u16 = 1;
    /// Ignore y (east) position.
    pub const IGNORE_PY: u16 = 2;
    /// Ignore z (down) position.
    pub const IGNORE_PZ: u16 = 4;
    /// Ignore x velocity.
    pub const IGNORE_VX: u16 = 8;
    /// Ignore y velocity.
    pub const IGNORE_VY: u16 = 16;
    /// Ignore z velocity.
    pub const IGNORE_VZ: u16 = 32;
    /// Ignore x acceleration.
    pub const IGNORE_AX: u16 = 64;
    /// Ignore y acceleration.
    pub const IGNORE_AY: u16 = 128;
    /// Ignore z acceleration.
    pub const IGNORE_AZ: u16 = 256;
    /// Acceleration fields are forces.
    pub const FORCE: u16 = 512;
    /// Ignore yaw.
    pub const IGNORE_YAW: u16 = 1024;
    /// Ignore yaw rate.
    pub const IGNORE_YAW_RATE: u16 = 2048;
    /// All three position bits.
    pub const IGNORE_POSITION: u16 = IGNORE_PX | IGNORE_PY | IGNORE_PZ;
    /// All three velocity bits.
    pub const IGNORE_VELOCITY: u16 = IGNORE_VX | IGNORE_VY | IGNORE_VZ;
    /// All three acceleration bits.
    pub const IGNORE_ACCELERATION: u16 = IGNORE_AX | IGNORE_AY | IGNORE_AZ;
    /// Position + yaw: 2552 (0x09F8).
    pub const POSITION_YAW: u16 = IGNORE_VELOCITY | IGNORE_ACCELERATION | IGNORE_YAW_RATE;
    /// Velocity + yaw rate: 1479 (0x05C7).
    pub const VELOCITY_YAW_RATE: u16 = IGNORE_POSITION | IGNORE_ACCELERATION | IGNORE_YAW;
    /// Position + velocity feed-forward + yaw: 2496 (0x09C0).
    pub const POSITION_VELOCITY_YAW: u16 = IGNORE_ACCELERATION | IGNORE_YAW_RATE;
    /// Position + velocity and acceleration feed-forward + yaw: 2048 (0x0800). PX4 adds
    /// the acceleration to its velocity controller's output.
    pub const POSITION_VELOCITY_ACCELERATION_YAW: u16 = IGNORE_YAW_RATE;
}

/// `MAV_FRAME_LOCAL_NED` (1): the PX4 local frame of `SET_POSITION_TARGET_LOCAL_NED`.
pub const MAV_FRAME_LOCAL_NED: u8 = 1;
/// `MAV_FRAME_BODY_NED` (8).
pub const MAV_FRAME_BODY_NED: u8 = 8;
/// Magic `param2` of `MAV_CMD_COMPONENT_ARM_DISARM` that forces arming/disarming (21196).
pub const FORCE_ARM_DISARM_MAGIC: f32 = 21196.0;
/// `MAV_MODE_FLAG_CUSTOM_MODE_ENABLED` (1): `param1` of `MAV_CMD_DO_SET_MODE` for PX4 modes.
pub const MAV_MODE_FLAG_CUSTOM_MODE_ENABLED: f32 = 1.0;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn observed_custom_mode_values() {
        // Values observed on PX4 v1.16 SITL (px4.md).
        assert_eq!(Px4Mode::Hold.custom_mode(), 50_593_792);
        assert_eq!(Px4Mode::Takeoff.custom_mode(), 33_816_576);
        assert_eq!(Px4Mode::Offboard.custom_mode(), 393_216);
        assert_eq!(Px4Mode::Land.custom_mode(), 100_925_440);
        assert_eq!(Px4Mode::Rtl.custom_mode(), 84_148_224);
        assert_eq!(Px4Mode::Posctl.custom_mode(), 196_608);
    }

    #[test]
    fn every_mode_round_trips_through_custom_mode_and_name() {
        for m in Px4Mode::ALL {
            assert_eq!(Px4Mode::from_custom_mode(m.custom_mode()), m);
            assert_eq!(Px4Mode::from_name(m.name()), Some(m));
            let (main, sub) = m.main_sub();
            assert_eq!(Px4Mode::from_main_sub(main, sub), Some(m));
        }
        assert_eq!(
            Px4Mode::from_custom_mode(0x0909_0000),
            Px4Mode::Unknown(0x0909_0000)
        );
        assert_eq!(Px4Mode::Unknown(0x0909_0000).custom_mode(), 0x0909_0000);
    }

    #[test]
    fn type_masks_match_px4_docs() {
        assert_eq!(type_mask::POSITION_YAW, 2552);
        assert_eq!(type_mask::VELOCITY_YAW_RATE, 1479);
        assert_eq!(type_mask::POSITION_VELOCITY_YAW, 2496);
    }

    #[test]
    fn landed_state_round_trips() {
        for v in 0..=4 {
            assert_eq!(LandedState::from_mavlink(v).to_mavlink(), v);
        }
        assert!(LandedState::InAir.is_airborne());
        assert!(!LandedState::OnGround.is_airborne());
    }
}
