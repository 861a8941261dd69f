//! What the link configures on a vehicle when it connects (again after a reboot or a
//! restored link): telemetry rates (`MAV_CMD_SET_MESSAGE_INTERVAL`) and parameters.

use serde::{Deserialize, Serialize};
use skein_mavlink::MessageData;
use skein_mavlink::dialect as d;

/// Telemetry rates to ask of each vehicle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TelemetryProfile {
    /// Leave PX4's onboard-mode rates alone (about 400 messages/s per vehicle).
    #[default]
    Px4Default,
    /// A reduced set for large swarms and thin radios (about 40 messages/s): what skein
    /// uses at the rates it uses it, everything else off.
    Swarm,
}

/// Interval that disables a message in `MAV_CMD_SET_MESSAGE_INTERVAL`.
pub const DISABLED: f64 = -1.0;

impl TelemetryProfile {
    /// `(message id, rate Hz)` pairs to request (rate [`DISABLED`] turns a message off).
    pub fn rates(self) -> Vec<(u32, f64)> {
        match self {
            TelemetryProfile::Px4Default => vec![],
            TelemetryProfile::Swarm => vec![
                (d::GLOBAL_POSITION_INT_DATA::ID, 10.0),
                (d::LOCAL_POSITION_NED_DATA::ID, 10.0),
                (d::ATTITUDE_DATA::ID, 5.0),
                (d::EXTENDED_SYS_STATE_DATA::ID, 2.0),
                (d::SYS_STATUS_DATA::ID, 1.0),
                (d::GPS_RAW_INT_DATA::ID, 1.0),
                (d::BATTERY_STATUS_DATA::ID, 0.5),
                (d::HOME_POSITION_DATA::ID, 0.5),
                (d::HIGHRES_IMU_DATA::ID, DISABLED),
                (d::ATTITUDE_QUATERNION_DATA::ID, DISABLED),
                (d::ODOMETRY_DATA::ID, DISABLED),
                (d::ALTITUDE_DATA::ID, DISABLED),
                (d::DISTANCE_SENSOR_DATA::ID, DISABLED),
                (d::ATTITUDE_TARGET_DATA::ID, DISABLED),
                (d::POSITION_TARGET_LOCAL_NED_DATA::ID, DISABLED),
                (d::SERVO_OUTPUT_RAW_DATA::ID, DISABLED),
                (d::VFR_HUD_DATA::ID, DISABLED),
                (d::TIMESYNC_DATA::ID, DISABLED),
                (d::ESTIMATOR_STATUS_DATA::ID, DISABLED),
                (d::SCALED_PRESSURE_DATA::ID, DISABLED),
                (d::VIBRATION_DATA::ID, DISABLED),
                // PING (id 4): deprecated in the dialect, still streamed by PX4 at 1 Hz.
                (4, DISABLED),
                (d::MISSION_CURRENT_DATA::ID, DISABLED),
                (d::LINK_NODE_STATUS_DATA::ID, DISABLED),
                (d::CURRENT_MODE_DATA::ID, DISABLED),
                (d::SYSTEM_TIME_DATA::ID, 0.2),
            ],
        }
    }
}

/// Per-vehicle connect-time configuration.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct LinkSetup {
    /// Telemetry profile.
    pub telemetry: TelemetryProfile,
    /// Parameters to set, by PX4 name, as numbers (written in the parameter's own type),
    /// e.g. `("COM_OF_LOSS_T", 1.0)`, `("COM_OBL_RC_ACT", 5.0)`, `("NAV_DLL_ACT", 0.0)`.
    pub params: Vec<(String, f64)>,
    /// Remote ID: the operator's identity and location sent to the vehicle at 1 Hz
    /// (`[remote_id]`); none: nothing sent.
    #[serde(default)]
    pub remote_id: Option<crate::remote_id::RemoteIdConfig>,
    /// The process's reader of `remote_id`'s `operator_gnss` (one per process, shared by
    /// every vehicle's link, which reads its latest fix without waiting); none: no live
    /// operator location.
    #[serde(skip)]
    pub operator_gnss: Option<skein_gnss::GnssReader>,
    /// Where PX4's component metadata (the events metadata) is cached, by CRC: a vehicle
    /// whose firmware's metadata is there is not asked for it again; none: read from
    /// every vehicle at every connection.
    #[serde(default)]
    pub metadata_cache_dir: Option<std::path::PathBuf>,
    /// The byte-rate cap shared by every flight-log download of the process (`[logs]
    /// max_bytes_s`; see [`crate::log_bandwidth`]); default none.
    #[serde(default)]
    pub log_bandwidth: crate::log_bandwidth::LogBandwidth,
}

/// `MAV_CMD_SET_MESSAGE_INTERVAL` param2 for a rate: microseconds, or -1 to disable.
pub fn interval_us(rate_hz: f64) -> i32 {
    if rate_hz <= 0.0 {
        -1
    } else {
        (1e6 / rate_hz).round() as i32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn swarm_profile_keeps_what_skein_needs() {
        let rates = TelemetryProfile::Swarm.rates();
        let rate = |id| rates.iter().find(|(m, _)| *m == id).map(|(_, r)| *r);
        assert_eq!(rate(d::GLOBAL_POSITION_INT_DATA::ID), Some(10.0));
        assert_eq!(rate(d::ATTITUDE_DATA::ID), Some(5.0));
        assert_eq!(rate(d::HIGHRES_IMU_DATA::ID), Some(DISABLED));
        let total: f64 = rates.iter().map(|(_, r)| r.max(0.0)).sum::<f64>() + 1.0; // + HEARTBEAT
        assert!(total < 45.0, "{total} msg/s");
        assert!(TelemetryProfile::Px4Default.rates().is_empty());
    }

    #[test]
    fn intervals() {
        assert_eq!(interval_us(50.0), 20_000);
        assert_eq!(interval_us(0.5), 2_000_000);
        assert_eq!(interval_us(DISABLED), -1);
    }
}
