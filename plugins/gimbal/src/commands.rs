//! The gimbal's operator commands (see the crate docs): read by serde, then checked
//! against the gimbal's configuration and turned into a [`Target`].

use crate::attitude::Attitude;
use crate::{GimbalConfig, RoiPoint, Target, YawFrame};
use skein_plugin_sdk::args::{field_error, in_range};
use skein_plugin_sdk::geometry::{GeoPoint, Ned};
use skein_plugin_sdk::serde::Deserialize;

/// A command as written, one variant per `command` name.
#[derive(Deserialize)]
#[serde(crate = "skein_plugin_sdk::serde")]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Command {
    /// Hold angles: pitch (degrees, positive up) and yaw (degrees, in `yaw_frame`,
    /// default the vehicle's), either may be left out to keep its current target.
    SetAngles {
        /// Pitch, degrees, positive up.
        pitch_deg: Option<f64>,
        /// Yaw, degrees.
        yaw_deg: Option<f64>,
        /// Frame of `yaw_deg` (`"vehicle"` or `"earth"`).
        yaw_frame: Option<YawFrame>,
    },
    /// Turn at rates, deg/s (default 0), within `max_rate_deg_s`.
    SetRates {
        /// Pitch rate, deg/s, positive up.
        pitch_rate_deg_s: Option<f64>,
        /// Yaw rate, deg/s, positive clockwise seen from above.
        yaw_rate_deg_s: Option<f64>,
    },
    /// Point at a location: swarm-frame `north_m`/`east_m` (and `down_m`, default 0), or
    /// geodetic `lat_deg`/`lon_deg`/`alt_amsl_m`.
    RoiLocation {
        /// Swarm-frame north, metres.
        north_m: Option<f64>,
        /// Swarm-frame east, metres.
        east_m: Option<f64>,
        /// Swarm-frame down, metres.
        down_m: Option<f64>,
        /// Latitude, degrees.
        lat_deg: Option<f64>,
        /// Longitude, degrees.
        lon_deg: Option<f64>,
        /// Altitude above mean sea level, metres.
        alt_amsl_m: Option<f64>,
    },
    /// Point at another vehicle of the swarm, by `vehicle` id or by `sysid`.
    RoiVehicle {
        /// Vehicle id (`"uav-2"`).
        vehicle: Option<String>,
        /// MAVLink system id, 1–255.
        sysid: Option<u64>,
    },
    /// Hold the current angles.
    RoiNone,
    /// Pitch 0, yaw 0 relative to the vehicle.
    Neutral,
    /// Change nothing; reply with the state.
    Status,
}

impl Command {
    /// What the gimbal is asked to do (`None` for `status`), checked against `cfg`;
    /// `attitude` is where the gimbal points now (what `roi_none` holds).
    ///
    /// # Errors
    /// An angle or rate outside the gimbal's limits, a location given both ways or half
    /// given, no vehicle or two: the field at fault first.
    pub fn into_target(
        self,
        cfg: &GimbalConfig,
        attitude: Option<Attitude>,
    ) -> Result<Option<Target>, String> {
        Ok(Some(match self {
            Command::SetAngles {
                pitch_deg,
                yaw_deg,
                yaw_frame,
            } => {
                let yaw_frame = yaw_frame.unwrap_or(YawFrame::Vehicle);
                if let Some(p) = pitch_deg {
                    within_limits(
                        "pitch_deg",
                        "pitch",
                        p,
                        cfg.pitch_min_deg,
                        cfg.pitch_max_deg,
                    )?;
                }
                if let Some(y) = yaw_deg
                    && yaw_frame == YawFrame::Vehicle
                    && !cfg.yaw_continuous()
                {
                    within_limits("yaw_deg", "yaw", y, cfg.yaw_min_deg, cfg.yaw_max_deg)?;
                }
                if pitch_deg.is_none() && yaw_deg.is_none() {
                    return Err("command `set_angles`: give `pitch_deg`, `yaw_deg` or both".into());
                }
                Target::Angles {
                    pitch_deg,
                    yaw_deg,
                    yaw_frame,
                }
            }
            Command::SetRates {
                pitch_rate_deg_s,
                yaw_rate_deg_s,
            } => {
                let max = cfg.max_rate_deg_s;
                Target::Rates {
                    pitch_rate_deg_s: in_range(
                        "pitch_rate_deg_s",
                        pitch_rate_deg_s.unwrap_or(0.0),
                        -max,
                        max,
                    )?,
                    yaw_rate_deg_s: in_range(
                        "yaw_rate_deg_s",
                        yaw_rate_deg_s.unwrap_or(0.0),
                        -max,
                        max,
                    )?,
                }
            }
            Command::RoiLocation {
                north_m,
                east_m,
                down_m,
                lat_deg,
                lon_deg,
                alt_amsl_m,
            } => {
                let required = |field: &str, v: Option<f64>| {
                    v.ok_or_else(|| field_error(field, format!("missing field `{field}`")))
                };
                if lat_deg.is_some() || lon_deg.is_some() || alt_amsl_m.is_some() {
                    if north_m.is_some() || east_m.is_some() || down_m.is_some() {
                        return Err("command `roi_location`: give either `north_m`/`east_m`/`down_m` (swarm frame) or `lat_deg`/`lon_deg`/`alt_amsl_m`, not both".into());
                    }
                    Target::RoiLocation(RoiPoint::Geo(GeoPoint::new(
                        in_range("lat_deg", required("lat_deg", lat_deg)?, -90.0, 90.0)?,
                        in_range("lon_deg", required("lon_deg", lon_deg)?, -180.0, 180.0)?,
                        in_range(
                            "alt_amsl_m",
                            required("alt_amsl_m", alt_amsl_m)?,
                            -500.0,
                            20_000.0,
                        )?,
                    )))
                } else {
                    Target::RoiLocation(RoiPoint::Ned(Ned::new(
                        required("north_m", north_m)?,
                        required("east_m", east_m)?,
                        down_m.unwrap_or(0.0),
                    )))
                }
            }
            Command::RoiVehicle { vehicle, sysid } => match (vehicle, sysid) {
                (Some(id), None) => Target::RoiVehicle(id),
                (None, Some(s)) if (1..=255).contains(&s) => {
                    Target::RoiVehicle(format!("sysid:{s}"))
                }
                (None, Some(s)) => {
                    return Err(field_error(
                        "sysid",
                        format!("{s} is not a MAVLink system id (1..255)"),
                    ));
                }
                _ => {
                    return Err(
                        "command `roi_vehicle`: give `vehicle` (an id such as \"uav-2\") or `sysid`, one of them".into(),
                    );
                }
            },
            Command::RoiNone => {
                let (p, y) = attitude
                    .map(|a| (a.pitch_deg, a.yaw_deg))
                    .unwrap_or((0.0, 0.0));
                Target::Angles {
                    pitch_deg: Some(p),
                    yaw_deg: Some(y),
                    yaw_frame: YawFrame::Vehicle,
                }
            }
            Command::Neutral => Target::Neutral,
            Command::Status => return Ok(None),
        }))
    }
}

/// `Ok` when `value` (the command's `field`) lies within the gimbal's `axis` range
/// `[min, max]`, degrees.
fn within_limits(field: &str, axis: &str, value: f64, min: f64, max: f64) -> Result<(), String> {
    if (min..=max).contains(&value) {
        Ok(())
    } else {
        Err(field_error(
            field,
            format!("{value} is outside the gimbal's {axis} range [{min}, {max}]"),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skein_plugin_sdk::args;
    use skein_plugin_sdk::serde_json::{Value, json};

    fn target(v: Value) -> Result<Option<Target>, String> {
        let cfg = GimbalConfig::parse(json!({"yaw_min_deg": -90, "yaw_max_deg": 90})).unwrap();
        args::command::<Command>(v)?.into_target(&cfg, None)
    }

    #[test]
    fn commands_become_targets() {
        assert_eq!(
            target(
                json!({"command": "set_angles", "pitch_deg": -30, "yaw_frame": "earth", "yaw_deg": 120})
            ),
            Ok(Some(Target::Angles {
                pitch_deg: Some(-30.0),
                yaw_deg: Some(120.0),
                yaw_frame: YawFrame::Earth
            }))
        );
        assert_eq!(
            target(json!({"command": "roi_location", "north_m": 40, "east_m": 5})),
            Ok(Some(Target::RoiLocation(RoiPoint::Ned(Ned::new(
                40.0, 5.0, 0.0
            )))))
        );
        assert_eq!(
            target(json!({"command": "roi_vehicle", "sysid": 2})),
            Ok(Some(Target::RoiVehicle("sysid:2".into())))
        );
        assert_eq!(target(json!({"command": "status"})), Ok(None));
        assert_eq!(
            target(json!({"command": "neutral"})),
            Ok(Some(Target::Neutral))
        );
    }

    #[test]
    fn refusals_lead_with_the_field() {
        for (command, error) in [
            (
                json!({"command": "set_angles", "yaw_deg": 120}),
                "yaw_deg: 120 is outside the gimbal's yaw range [-90, 90]",
            ),
            (
                json!({"command": "set_angles", "yaw_frame": "moon", "yaw_deg": 1}),
                "yaw_frame: unknown variant `moon`, expected `vehicle` or `earth`",
            ),
            (
                json!({"command": "set_rates", "yaw_rate_deg_s": 100}),
                "yaw_rate_deg_s: 100 is outside [-60, 60]",
            ),
            (
                json!({"command": "roi_location", "lat_deg": 47.4, "lon_deg": 8.5}),
                "alt_amsl_m: missing field `alt_amsl_m`",
            ),
            (
                json!({"command": "roi_location", "east_m": 5}),
                "north_m: missing field `north_m`",
            ),
            (
                json!({"command": "roi_vehicle", "sysid": 300}),
                "sysid: 300 is not a MAVLink system id (1..255)",
            ),
            (
                json!({"command": "neutral", "pitch_deg": 0}),
                "pitch_deg: unknown field `pitch_deg`: command `neutral` takes no fields",
            ),
        ] {
            assert_eq!(target(command.clone()), Err(error.to_string()), "{command}");
        }
        assert!(target(json!({"command": "set_angles"})).is_err());
        assert!(target(json!({"command": "roi_vehicle"})).is_err());
    }
}
