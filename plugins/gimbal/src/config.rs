//! The gimbal's configuration: the JSON a payload slot gives (see the crate docs), read
//! with serde and range-checked into a [`GimbalConfig`].

use skein_plugin_sdk::args::{self, DeviceMode, field_error, in_range};
use skein_plugin_sdk::serde::Deserialize;
use skein_plugin_sdk::serde_json::Value;

/// Which device the instance drives (its `mode`, resolved).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Backend {
    /// A simulated gimbal moved by this plugin.
    Simulated,
    /// PX4's gimbal manager, over the vehicle's MAVLink link.
    Mavlink,
}

/// The configuration as written: every field optional. Ids are read as numbers, as they
/// always were (`1.0` is 1).
#[derive(Debug, Default, Deserialize)]
#[serde(crate = "skein_plugin_sdk::serde", deny_unknown_fields)]
struct Settings {
    #[serde(default)]
    mode: DeviceMode,
    max_rate_deg_s: Option<f64>,
    pitch_min_deg: Option<f64>,
    pitch_max_deg: Option<f64>,
    yaw_min_deg: Option<f64>,
    yaw_max_deg: Option<f64>,
    rate_hz: Option<f64>,
    track_send_hz: Option<f64>,
    gimbal_device_id: Option<f64>,
    manager_compid: Option<f64>,
}

/// Configuration of an instance (see the crate docs for the JSON).
#[derive(Debug, Clone, PartialEq)]
pub struct GimbalConfig {
    /// `mode`: auto (simulated when the vehicle is), simulated or mavlink.
    pub mode: DeviceMode,
    /// Slew-rate limit of each axis, deg/s.
    pub max_rate_deg_s: f64,
    /// Lowest pitch, degrees (negative looks down).
    pub pitch_min_deg: f64,
    /// Highest pitch, degrees.
    pub pitch_max_deg: f64,
    /// Lowest yaw relative to the vehicle, degrees.
    pub yaw_min_deg: f64,
    /// Highest yaw relative to the vehicle, degrees.
    pub yaw_max_deg: f64,
    /// Tick (and state publication) rate, Hz.
    pub rate_hz: f64,
    /// Rate of pitch/yaw setpoints sent while tracking a vehicle (mavlink backend), Hz.
    pub track_send_hz: f64,
    /// `gimbal_device_id` of the Gimbal Protocol v2 messages (0 = all gimbals).
    pub gimbal_device_id: u8,
    /// Component id of the gimbal manager (PX4: the autopilot, 1).
    pub manager_compid: u8,
}

impl GimbalConfig {
    /// Parses the configuration JSON (`null`: every default).
    ///
    /// # Errors
    /// An unknown field, a wrong type, or a value out of range, as `field: message`.
    pub fn parse(config: Value) -> Result<GimbalConfig, String> {
        let s: Settings = args::config(config)?;
        let cfg = GimbalConfig {
            mode: s.mode,
            max_rate_deg_s: in_range(
                "max_rate_deg_s",
                s.max_rate_deg_s.unwrap_or(60.0),
                0.1,
                720.0,
            )?,
            pitch_min_deg: in_range(
                "pitch_min_deg",
                s.pitch_min_deg.unwrap_or(-90.0),
                -180.0,
                180.0,
            )?,
            pitch_max_deg: in_range(
                "pitch_max_deg",
                s.pitch_max_deg.unwrap_or(30.0),
                -180.0,
                180.0,
            )?,
            yaw_min_deg: in_range(
                "yaw_min_deg",
                s.yaw_min_deg.unwrap_or(-180.0),
                -360.0,
                360.0,
            )?,
            yaw_max_deg: in_range("yaw_max_deg", s.yaw_max_deg.unwrap_or(180.0), -360.0, 360.0)?,
            rate_hz: in_range("rate_hz", s.rate_hz.unwrap_or(20.0), 1.0, 200.0)?,
            track_send_hz: in_range("track_send_hz", s.track_send_hz.unwrap_or(10.0), 0.5, 50.0)?,
            gimbal_device_id: in_range(
                "gimbal_device_id",
                s.gimbal_device_id.unwrap_or(0.0),
                0.0,
                255.0,
            )? as u8,
            manager_compid: in_range(
                "manager_compid",
                s.manager_compid.unwrap_or(1.0),
                0.0,
                255.0,
            )? as u8,
        };
        below(
            "pitch_min_deg",
            cfg.pitch_min_deg,
            "pitch_max_deg",
            cfg.pitch_max_deg,
        )?;
        below(
            "yaw_min_deg",
            cfg.yaw_min_deg,
            "yaw_max_deg",
            cfg.yaw_max_deg,
        )?;
        Ok(cfg)
    }

    /// True when yaw turns all the way round.
    pub fn yaw_continuous(&self) -> bool {
        self.yaw_max_deg - self.yaw_min_deg >= 360.0
    }
}

/// `Ok` when the lower limit `min_field` lies below the upper one, `max_field`.
fn below(min_field: &str, min: f64, max_field: &str, max: f64) -> Result<(), String> {
    if min < max {
        Ok(())
    } else {
        Err(field_error(
            min_field,
            format!("{min} must be below `{max_field}` ({max})"),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skein_plugin_sdk::serde_json::json;

    #[test]
    fn config_defaults_and_errors() {
        let c = GimbalConfig::parse(Value::Null).unwrap();
        assert_eq!(c.max_rate_deg_s, 60.0);
        assert!(c.yaw_continuous());
        let e = GimbalConfig::parse(json!({"max_rate_deg": 3})).unwrap_err();
        assert!(
            e.starts_with("max_rate_deg: unknown field `max_rate_deg`"),
            "{e}"
        );
        let e = GimbalConfig::parse(json!({"pitch_min_deg": 10, "pitch_max_deg": 0})).unwrap_err();
        assert_eq!(e, "pitch_min_deg: 10 must be below `pitch_max_deg` (0)");
        let e = GimbalConfig::parse(json!({"mode": "magic"})).unwrap_err();
        assert!(e.starts_with("mode: unknown variant `magic`"), "{e}");
        let e = GimbalConfig::parse(json!({"rate_hz": 0})).unwrap_err();
        assert_eq!(e, "rate_hz: 0 is outside [1, 200]");
    }
}
