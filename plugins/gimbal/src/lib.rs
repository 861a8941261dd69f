//! The gimbal payload plugin: MAVLink Gimbal Protocol v2 semantics for skein.
//!
//! One instance drives the gimbal of one vehicle. Operator commands follow the gimbal
//! manager's vocabulary: set pitch/yaw angles (yaw in the vehicle or the earth frame) or
//! rates, point at a location (ROI), point at another vehicle of the swarm (tracked while
//! both move), release the ROI, go neutral.
//!
//! Two backends, chosen by `mode` (`"auto"`: simulated when the vehicle is):
//! - **simulated**: a two-axis gimbal whose pitch and yaw slew toward their targets at
//!   most `max_rate_deg_s`, within their limits; its attitude is published as the state
//!   (the equivalent of `GIMBAL_DEVICE_ATTITUDE_STATUS`).
//! - **mavlink**: commands become `GIMBAL_MANAGER_SET_PITCHYAW`,
//!   `MAV_CMD_DO_SET_ROI_LOCATION`, `MAV_CMD_DO_SET_ROI_NONE` and
//!   `MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE` to PX4's gimbal manager; pointing at another
//!   vehicle is done by this plugin, which sends earth-frame pitch/yaw toward it at
//!   `track_send_hz`; the attitude is read from `GIMBAL_DEVICE_ATTITUDE_STATUS`.
//!
//! # Configuration (all optional)
//! `{"mode": "auto" | "simulated" | "mavlink", "max_rate_deg_s": 60, "pitch_min_deg": -90,
//! "pitch_max_deg": 30, "yaw_min_deg": -180, "yaw_max_deg": 180, "rate_hz": 20,
//! "track_send_hz": 10, "gimbal_device_id": 0, "manager_compid": 1}`.
//! A yaw range of 360° or more is continuous (the gimbal takes the short way round).
//!
//! # Commands
//! - `{"command": "set_angles", "pitch_deg": -45, "yaw_deg": 30, "yaw_frame": "vehicle" | "earth"}`
//!   (either angle may be omitted to keep its current target)
//! - `{"command": "set_rates", "pitch_rate_deg_s": 10, "yaw_rate_deg_s": -5}`
//! - `{"command": "roi_location", "north_m": 40, "east_m": 5, "down_m": 0}` (swarm frame) or
//!   `{"command": "roi_location", "lat_deg": 47.39, "lon_deg": 8.54, "alt_amsl_m": 490}`
//! - `{"command": "roi_vehicle", "vehicle": "uav-2"}` or `{"command": "roi_vehicle", "sysid": 2}`
//! - `{"command": "roi_none"}` (hold the current angles), `{"command": "neutral"}`,
//!   `{"command": "status"}`
//!
//! Every command replies with the state below.
//!
//! # Published state
//! ```json
//! {"backend": "simulated", "mode": "roi_vehicle", "attitude_source": "simulated",
//!  "pitch_deg": -12.0, "yaw_deg": 35.0, "roll_deg": 0.0, "yaw_absolute_deg": 125.0,
//!  "pitch_rate_deg_s": 0.0, "yaw_rate_deg_s": 4.2, "q": [w, x, y, z],
//!  "target": {"pitch_deg": -12.0, "yaw_deg": 35.0}, "roi": {"vehicle": "uav-2", "range_m": 41.0},
//!  "roi_error": null, "max_rate_deg_s": 60.0, "time_s": 12.5}
//! ```
//! `yaw_deg` is relative to the vehicle's heading (the gimbal's own frame, what a camera on
//! it needs); `yaw_absolute_deg` is clockwise from north; `q` is the attitude quaternion
//! (w, x, y, z) with yaw in the vehicle frame, as in `GIMBAL_DEVICE_ATTITUDE_STATUS` with
//! `GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME`. Angles are `null` while a real gimbal has not
//! reported its attitude.

mod attitude;
mod commands;
mod config;
mod mavlink_backend;

use attitude::{Attitude, euler_from_quaternion, quaternion_from_euler, slew};
pub use config::{Backend, GimbalConfig};
use skein_plugin_sdk::args;
use skein_plugin_sdk::dialect::{GIMBAL_DEVICE_ATTITUDE_STATUS_DATA, GimbalDeviceFlags};
use skein_plugin_sdk::geometry::{
    GeoPoint, Ned, NedFrame, look_angles, wrap_deg_180, wrap_deg_360,
};
use skein_plugin_sdk::serde::Deserialize;
use skein_plugin_sdk::serde_json::{Value, json};
use skein_plugin_sdk::vehicle::Vehicle;
use skein_plugin_sdk::{Context, MavMessage, MavlinkInterest, MessageData, Plugin, export_plugin};

/// The frame a commanded yaw is given in (`yaw_frame`: `"vehicle"` or `"earth"`).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(crate = "skein_plugin_sdk::serde", rename_all = "snake_case")]
pub enum YawFrame {
    /// Relative to the vehicle's heading (`GIMBAL_MANAGER_FLAGS_YAW_IN_VEHICLE_FRAME`).
    Vehicle,
    /// Clockwise from north (`GIMBAL_MANAGER_FLAGS_YAW_IN_EARTH_FRAME`).
    Earth,
}

/// Where an ROI location was given.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RoiPoint {
    /// Swarm-frame NED, metres.
    Ned(Ned),
    /// Geodetic (WGS84).
    Geo(GeoPoint),
}

/// What the gimbal is asked to do.
#[derive(Debug, Clone, PartialEq)]
pub enum Target {
    /// Hold these angles (a `None` angle keeps the current attitude on that axis).
    Angles {
        /// Pitch, degrees, positive up.
        pitch_deg: Option<f64>,
        /// Yaw, degrees, in `yaw_frame`.
        yaw_deg: Option<f64>,
        /// Frame of `yaw_deg`.
        yaw_frame: YawFrame,
    },
    /// Turn at these rates, degrees per second.
    Rates {
        /// Pitch rate, deg/s, positive up.
        pitch_rate_deg_s: f64,
        /// Yaw rate, deg/s, positive clockwise seen from above.
        yaw_rate_deg_s: f64,
    },
    /// Point at a location.
    RoiLocation(RoiPoint),
    /// Point at another vehicle of the swarm (by id).
    RoiVehicle(String),
    /// Neutral: pitch 0, yaw 0 relative to the vehicle.
    Neutral,
}

impl Target {
    fn mode(&self) -> &'static str {
        match self {
            Target::Angles { .. } => "angles",
            Target::Rates { .. } => "rates",
            Target::RoiLocation(_) => "roi_location",
            Target::RoiVehicle(_) => "roi_vehicle",
            Target::Neutral => "neutral",
        }
    }
}

/// One gimbal instance.
pub struct Gimbal {
    cfg: GimbalConfig,
    backend: Backend,
    target: Target,
    /// Simulated attitude, or the last reported one (mavlink backend).
    attitude: Option<Attitude>,
    /// The pitch/yaw (vehicle frame) the gimbal is steering to, degrees.
    desired: Option<(f64, f64)>,
    /// Why the ROI could not be followed, if it could not.
    roi_error: Option<String>,
    /// Distance to the ROI, metres, when known.
    roi_range_m: Option<f64>,
    /// Simulated time since creation, seconds (sum of tick `dt_s`).
    time_s: f64,
    /// Latest vehicle heading, degrees.
    heading_deg: f64,
    /// Mavlink backend state.
    link: mavlink_backend::LinkState,
}

/// The vehicle with this id, or this sysid when `id` is `sysid:<n>`.
fn find_vehicle<'a>(swarm: &'a [Vehicle], id: &str) -> Option<&'a Vehicle> {
    match id.strip_prefix("sysid:") {
        Some(n) => n
            .parse::<u8>()
            .ok()
            .and_then(|s| swarm.iter().find(|v| v.sysid == s)),
        None => swarm.iter().find(|v| v.id == id),
    }
}

impl Gimbal {
    /// The pitch and vehicle-frame yaw that point from `vehicle` at `target`, plus the
    /// range, or why not.
    fn pointing(
        &self,
        ctx: &Context,
        vehicle: &Vehicle,
    ) -> Result<Option<(f64, f64, f64)>, String> {
        let heading = vehicle.heading_deg;
        let relative = match &self.target {
            Target::RoiLocation(RoiPoint::Ned(p)) => {
                let own = vehicle
                    .ned()
                    .ok_or("the vehicle's position is not known yet")?;
                *p - own
            }
            Target::RoiLocation(RoiPoint::Geo(g)) => {
                let pos = vehicle
                    .position
                    .ok_or("the vehicle's position is not known yet")?;
                NedFrame::new(pos.geo()).to_ned(g)
            }
            Target::RoiVehicle(id) => {
                let own = vehicle
                    .ned()
                    .ok_or("the vehicle's position is not known yet")?;
                let swarm = ctx.swarm()?;
                let other = find_vehicle(&swarm, id)
                    .ok_or_else(|| format!("vehicle `{id}` is not in the swarm"))?;
                let theirs = other
                    .ned()
                    .ok_or_else(|| format!("the position of vehicle `{id}` is not known yet"))?;
                theirs - own
            }
            _ => return Ok(None),
        };
        let look = look_angles(Ned::default(), relative)
            .ok_or("the ROI is at the gimbal's own position")?;
        Ok(Some((
            look.elevation_deg,
            wrap_deg_180(look.azimuth_deg - heading),
            look.range_m,
        )))
    }

    /// Updates `desired` (pitch, vehicle-frame yaw) from the target and the vehicle's pose.
    fn update_desired(&mut self, ctx: &Context, vehicle: &Vehicle) {
        let current = self.attitude.map(|a| (a.pitch_deg, a.yaw_deg));
        self.roi_range_m = None;
        self.desired = match &self.target {
            Target::Angles {
                pitch_deg,
                yaw_deg,
                yaw_frame,
            } => {
                let (cur_p, cur_y) = current.unwrap_or((0.0, 0.0));
                let yaw = yaw_deg.map(|y| match yaw_frame {
                    YawFrame::Vehicle => y,
                    YawFrame::Earth => wrap_deg_180(y - vehicle.heading_deg),
                });
                Some((pitch_deg.unwrap_or(cur_p), yaw.unwrap_or(cur_y)))
            }
            Target::Neutral => Some((0.0, 0.0)),
            Target::Rates { .. } => None,
            Target::RoiLocation(_) | Target::RoiVehicle(_) => match self.pointing(ctx, vehicle) {
                Ok(Some((p, y, range))) => {
                    self.roi_error = None;
                    self.roi_range_m = Some(range);
                    Some((p, y))
                }
                Ok(None) => None,
                Err(e) => {
                    // Hold where it is until the ROI becomes reachable again.
                    self.roi_error = Some(e);
                    current
                }
            },
        };
        if let Some((p, y)) = self.desired {
            let p = p.clamp(self.cfg.pitch_min_deg, self.cfg.pitch_max_deg);
            let y = if self.cfg.yaw_continuous() {
                wrap_deg_180(y)
            } else {
                y.clamp(self.cfg.yaw_min_deg, self.cfg.yaw_max_deg)
            };
            self.desired = Some((p, y));
        }
    }

    /// Moves the simulated gimbal by one tick.
    fn step_simulated(&mut self, dt_s: f64) {
        let cfg = &self.cfg;
        let mut att = self.attitude.unwrap_or_default();
        match (&self.target, self.desired) {
            (
                Target::Rates {
                    pitch_rate_deg_s,
                    yaw_rate_deg_s,
                },
                _,
            ) => {
                let p = (att.pitch_deg + pitch_rate_deg_s * dt_s)
                    .clamp(cfg.pitch_min_deg, cfg.pitch_max_deg);
                let y = att.yaw_deg + yaw_rate_deg_s * dt_s;
                let y = if cfg.yaw_continuous() {
                    wrap_deg_180(y)
                } else {
                    y.clamp(cfg.yaw_min_deg, cfg.yaw_max_deg)
                };
                att.pitch_rate_deg_s = if dt_s > 0.0 {
                    (p - att.pitch_deg) / dt_s
                } else {
                    0.0
                };
                att.yaw_rate_deg_s = if dt_s > 0.0 {
                    wrap_deg_180(y - att.yaw_deg) / dt_s
                } else {
                    0.0
                };
                att.pitch_deg = p;
                att.yaw_deg = y;
            }
            (_, Some((p, y))) => {
                let (np, pr) = slew(att.pitch_deg, p, cfg.max_rate_deg_s, dt_s, false);
                let (ny, yr) = slew(
                    att.yaw_deg,
                    y,
                    cfg.max_rate_deg_s,
                    dt_s,
                    cfg.yaw_continuous(),
                );
                att.pitch_deg = np;
                att.yaw_deg = ny;
                att.pitch_rate_deg_s = pr;
                att.yaw_rate_deg_s = yr;
            }
            (_, None) => {
                att.pitch_rate_deg_s = 0.0;
                att.yaw_rate_deg_s = 0.0;
            }
        }
        self.attitude = Some(att);
    }

    /// The published state (also every command's reply).
    pub fn state(&self) -> Value {
        let att = self.attitude;
        let roi = match &self.target {
            Target::RoiLocation(RoiPoint::Ned(p)) => json!({
                "north_m": p.north_m, "east_m": p.east_m, "down_m": p.down_m,
                "range_m": self.roi_range_m,
            }),
            Target::RoiLocation(RoiPoint::Geo(g)) => json!({
                "lat_deg": g.lat_deg, "lon_deg": g.lon_deg, "alt_amsl_m": g.alt_amsl_m,
                "range_m": self.roi_range_m,
            }),
            Target::RoiVehicle(id) => json!({ "vehicle": id, "range_m": self.roi_range_m }),
            _ => Value::Null,
        };
        json!({
            "backend": match self.backend { Backend::Simulated => "simulated", Backend::Mavlink => "mavlink" },
            "mode": self.target.mode(),
            "attitude_source": match (self.backend, att.is_some()) {
                (Backend::Simulated, _) => "simulated",
                (Backend::Mavlink, true) => GIMBAL_DEVICE_ATTITUDE_STATUS_DATA::NAME,
                (Backend::Mavlink, false) => "none",
            },
            "pitch_deg": att.map(|a| a.pitch_deg),
            "yaw_deg": att.map(|a| a.yaw_deg),
            "roll_deg": att.map(|a| a.roll_deg),
            "yaw_absolute_deg": att.map(|a| wrap_deg_360(a.yaw_deg + self.heading_deg)),
            "pitch_rate_deg_s": att.map(|a| a.pitch_rate_deg_s),
            "yaw_rate_deg_s": att.map(|a| a.yaw_rate_deg_s),
            "q": att.map(|a| quaternion_from_euler(a.roll_deg, a.pitch_deg, a.yaw_deg).to_vec()),
            "target": self.desired.map(|(p, y)| json!({"pitch_deg": p, "yaw_deg": y})),
            "roi": roi,
            "roi_error": self.roi_error,
            "max_rate_deg_s": self.cfg.max_rate_deg_s,
            "time_s": self.time_s,
        })
    }

    fn on_attitude_status(&mut self, s: &GIMBAL_DEVICE_ATTITUDE_STATUS_DATA) {
        if self.cfg.gimbal_device_id != 0
            && s.gimbal_device_id != 0
            && s.gimbal_device_id != self.cfg.gimbal_device_id
        {
            return;
        }
        let (roll, pitch, yaw) = euler_from_quaternion(s.q);
        let yaw_vehicle = if s
            .flags
            .contains(GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_YAW_IN_EARTH_FRAME)
        {
            if s.delta_yaw.is_finite() {
                s.delta_yaw.to_degrees() as f64
            } else {
                wrap_deg_180(yaw - self.heading_deg)
            }
        } else {
            yaw
        };
        let finite_or_zero = |v: f32| {
            if v.is_finite() {
                (v as f64).to_degrees()
            } else {
                0.0
            }
        };
        self.attitude = Some(Attitude {
            roll_deg: roll,
            pitch_deg: pitch,
            yaw_deg: wrap_deg_180(yaw_vehicle),
            pitch_rate_deg_s: finite_or_zero(s.angular_velocity_y),
            yaw_rate_deg_s: finite_or_zero(s.angular_velocity_z),
        });
    }
}

impl Plugin for Gimbal {
    const NAME: &'static str = "gimbal";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");
    const KINDS: &'static [&'static str] = &["gimbal"];

    fn create(_kind: &str, config: Value, ctx: &Context) -> Result<Self, String> {
        let cfg = GimbalConfig::parse(config)?;
        let backend = if cfg.mode.simulated(ctx.simulated()) {
            Backend::Simulated
        } else {
            Backend::Mavlink
        };
        let mut g = Gimbal {
            backend,
            target: Target::Neutral,
            attitude: (backend == Backend::Simulated).then(Attitude::default),
            desired: Some((0.0, 0.0)),
            roi_error: None,
            roi_range_m: None,
            time_s: 0.0,
            heading_deg: 0.0,
            link: mavlink_backend::LinkState::default(),
            cfg,
        };
        if backend == Backend::Mavlink {
            // Not fatal: the link may have no address yet; retried before each command.
            if let Err(e) = g.link.take_control(ctx, &g.cfg) {
                ctx.log_warn(&format!(
                    "gimbal: cannot take gimbal manager control yet: {e}"
                ));
            }
        }
        Ok(g)
    }

    fn tick_rate_hz(&self) -> f64 {
        self.cfg.rate_hz
    }

    fn tick(&mut self, ctx: &Context, dt_s: f64) -> Result<(), String> {
        let dt_s = dt_s.clamp(0.0, 1.0);
        self.time_s += dt_s;
        let vehicle = ctx.vehicle()?;
        self.heading_deg = vehicle.heading_deg;
        self.update_desired(ctx, &vehicle);
        match self.backend {
            Backend::Simulated => self.step_simulated(dt_s),
            Backend::Mavlink => {
                if let (Target::RoiVehicle(_), Some((pitch, yaw))) = (&self.target, self.desired)
                    && self
                        .link
                        .due_for_tracking(self.time_s, self.cfg.track_send_hz)
                {
                    let yaw_earth = wrap_deg_180(yaw + vehicle.heading_deg);
                    self.link.set_pitch_yaw(
                        ctx,
                        &self.cfg,
                        &vehicle,
                        pitch,
                        yaw_earth,
                        YawFrame::Earth,
                    )?;
                }
            }
        }
        ctx.publish_state(&self.state())
    }

    fn handle(&mut self, ctx: &Context, command: Value) -> Result<Value, String> {
        let command: commands::Command = args::command(command)?;
        let Some(target) = command.into_target(&self.cfg, self.attitude)? else {
            return Ok(self.state());
        };
        let vehicle = ctx.vehicle()?;
        self.heading_deg = vehicle.heading_deg;
        if self.backend == Backend::Mavlink {
            self.link.send_target(ctx, &self.cfg, &vehicle, &target)?;
        }
        self.target = target;
        self.update_desired(ctx, &vehicle);
        if let Some(e) = &self.roi_error {
            // The ROI was accepted (it may become reachable) but say why it is not followed.
            ctx.log_warn(&format!("gimbal: ROI not followed yet: {e}"));
        }
        let state = self.state();
        ctx.publish_state(&state)?;
        Ok(state)
    }

    fn mavlink_interest(&self) -> MavlinkInterest {
        match self.backend {
            Backend::Simulated => MavlinkInterest::None,
            Backend::Mavlink => MavlinkInterest::Ids(vec![GIMBAL_DEVICE_ATTITUDE_STATUS_DATA::ID]),
        }
    }

    fn on_mavlink(&mut self, _ctx: &Context, _compid: u8, msg: &MavMessage) -> Result<(), String> {
        if let MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(s) = msg {
            self.on_attitude_status(s);
        }
        Ok(())
    }

    fn shutdown(&mut self, ctx: &Context) {
        if self.backend == Backend::Mavlink {
            // Hand the gimbal manager back (MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE, -3).
            let _ = self.link.release_control(ctx, &self.cfg);
        }
    }
}

export_plugin!(Gimbal);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vehicles_are_found_by_id_or_sysid() {
        let swarm = vec![
            Vehicle {
                id: "uav-1".into(),
                sysid: 1,
                ..Default::default()
            },
            Vehicle {
                id: "scout".into(),
                sysid: 7,
                ..Default::default()
            },
        ];
        assert_eq!(find_vehicle(&swarm, "scout").unwrap().sysid, 7);
        assert_eq!(find_vehicle(&swarm, "sysid:7").unwrap().id, "scout");
        assert!(find_vehicle(&swarm, "uav-9").is_none());
    }
}
