//! skein's state as ROS messages and ROS commands as skein's, with the frame change of
//! REP 103: skein's swarm frame is NED (x north, y east, z down) about the swarm origin;
//! the topics carry ENU (x east, y north, z up) about the same origin, in frame
//! [`crate::FRAME_ID`]. Headings turn likewise: skein's yaw is clockwise from north, the
//! ENU yaw counter-clockwise from east.

use crate::msgs::{
    BatteryState, Command, Header, NavSatFix, NavSatStatus, Point, Pose, PoseStamped, Quaternion,
    Track, Tracks, Vector3, VehicleState,
};
use ros2_client::builtin_interfaces::Time;
use serde_json::{Map, json};
use skein_model::command::Command as OperatorCommand;
use skein_model::geo::Ned;
use skein_model::vehicle::VehicleSnapshot;
use skein_swarm::tracks::TrackView;
use std::f64::consts::FRAC_PI_2;

/// A header stamped `stamp` in `frame_id`.
pub fn header(stamp: Time, frame_id: &str) -> Header {
    Header {
        stamp,
        frame_id: frame_id.to_string(),
    }
}

/// NED metres to an ENU point.
pub fn enu_point(ned: Ned) -> Point {
    Point {
        x: ned.east_m,
        y: ned.north_m,
        z: -ned.down_m,
    }
}

/// An ENU point back to NED metres.
pub fn ned_of(p: &Point) -> Ned {
    Ned::new(p.y, p.x, -p.z)
}

/// The ENU orientation of a vehicle level at `heading_deg` (clockwise from north): a
/// rotation about z by `π/2 − heading`.
pub fn enu_orientation(heading_deg: f64) -> Quaternion {
    let yaw = FRAC_PI_2 - heading_deg.to_radians();
    Quaternion {
        x: 0.0,
        y: 0.0,
        z: (yaw / 2.0).sin(),
        w: (yaw / 2.0).cos(),
    }
}

/// `/skein/<vehicle>/pose`: `None` before the vehicle's position is known.
pub fn pose(v: &VehicleSnapshot, stamp: Time) -> Option<PoseStamped> {
    let p = v.position?;
    Some(PoseStamped {
        header: header(stamp, crate::FRAME_ID),
        pose: Pose {
            position: enu_point(p.ned()),
            orientation: enu_orientation(v.heading_deg),
        },
    })
}

/// `/skein/<vehicle>/navsat`: `None` before the vehicle's position is known.
pub fn navsat(v: &VehicleSnapshot, stamp: Time) -> Option<NavSatFix> {
    let p = v.position?;
    Some(NavSatFix {
        header: header(stamp, &v.id),
        status: NavSatStatus {
            status: 0,
            service: 1,
        },
        latitude: p.lat_deg,
        longitude: p.lon_deg,
        altitude: p.alt_amsl_m,
        position_covariance: [0.0; 9],
        position_covariance_type: 0,
    })
}

/// `/skein/<vehicle>/battery`: `None` before the vehicle reports one.
pub fn battery(v: &VehicleSnapshot, stamp: Time) -> Option<BatteryState> {
    let b = v.battery?;
    Some(BatteryState {
        header: header(stamp, &v.id),
        voltage: b.voltage_v as f32,
        temperature: f32::NAN,
        current: f32::NAN,
        charge: f32::NAN,
        capacity: f32::NAN,
        design_capacity: f32::NAN,
        percentage: (b.percent / 100.0) as f32,
        power_supply_status: 2,
        power_supply_health: 0,
        power_supply_technology: 0,
        present: true,
        cell_voltage: Vec::new(),
        cell_temperature: Vec::new(),
        location: String::new(),
        serial_number: String::new(),
    })
}

/// `/skein/<vehicle>/state`.
pub fn state(v: &VehicleSnapshot, stamp: Time) -> VehicleState {
    VehicleState {
        header: header(stamp, crate::FRAME_ID),
        id: v.id.clone(),
        sysid: v.sysid,
        model: v.model.clone(),
        state: v.state.name().to_string(),
        px4_mode: v.px4_mode.clone(),
        armed: v.armed,
        link_connected: v.link.connected,
        slot: v.formation.map_or(-1, |f| f.slot as i32),
        leader: v.formation.is_some_and(|f| f.leader),
    }
}

/// `/skein/tracks`.
pub fn tracks(views: &[TrackView], stamp: Time) -> Tracks {
    Tracks {
        header: header(stamp, crate::FRAME_ID),
        tracks: views
            .iter()
            .map(|t| {
                let [[nn, ne], [en, ee]] = t.covariance_ne_m2;
                Track {
                    id: t.id.clone(),
                    status: serde_json::to_value(t.status)
                        .ok()
                        .and_then(|s| s.as_str().map(str::to_string))
                        .unwrap_or_default(),
                    position: enu_point(Ned::new(
                        t.position.north_m,
                        t.position.east_m,
                        t.position.down_m,
                    )),
                    velocity: Vector3 {
                        x: t.velocity.east_m_s,
                        y: t.velocity.north_m_s,
                        z: -t.velocity.down_m_s,
                    },
                    position_sigma_m: t.position_sigma_m,
                    covariance_en_m2: [ee, en, ne, nn],
                    hits: t.hits,
                    age_s: t.age_s,
                    unseen_s: t.unseen_s,
                }
            })
            .collect(),
    }
}

/// Why a `skein_msgs/Command` is not a skein command: the message field at fault and the
/// reason.
#[derive(Debug, Clone, PartialEq)]
pub struct CommandError {
    /// The message field (`"command"`, `"altitude_m"`, `"force"`, `"target"`).
    pub field: &'static str,
    /// Why.
    pub reason: String,
}

impl std::fmt::Display for CommandError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.field, self.reason)
    }
}

/// The skein command a `skein_msgs/Command` asks for: its fields laid out as the
/// command's JSON object (`disarm` with `force` is `force_disarm`; a NaN `altitude_m` is
/// the default; `target` is ENU, the command's point NED) and read by
/// [`OperatorCommand::from_object`], so a ROS node and the API get the same commands
/// with the same checks.
///
/// # Errors
/// An unknown `command`, a takeoff `altitude_m` that is neither NaN nor a finite height
/// above home, a goto `target` with a non-finite coordinate; named by the message's own
/// field.
pub fn command(c: &Command) -> Result<OperatorCommand, CommandError> {
    let name = match (c.command.as_str(), c.force) {
        ("disarm", true) => "force_disarm",
        (name, _) => name,
    };
    let mut m = Map::new();
    m.insert("command".into(), json!(name));
    match name {
        "force_disarm" => {
            m.insert("confirm".into(), json!(true));
        }
        "takeoff" if !c.altitude_m.is_nan() => {
            if !c.altitude_m.is_finite() {
                return Err(CommandError {
                    field: "altitude_m",
                    reason: format!("{} is not a height (NaN for the default)", c.altitude_m),
                });
            }
            m.insert("altitude_m".into(), json!(c.altitude_m));
        }
        "goto" => {
            let t = c.target;
            if !(t.x.is_finite() && t.y.is_finite() && t.z.is_finite()) {
                return Err(CommandError {
                    field: "target",
                    reason: "every coordinate must be a finite number of metres".into(),
                });
            }
            let p = ned_of(&t);
            m.insert("north_m".into(), json!(p.north_m));
            m.insert("east_m".into(), json!(p.east_m));
            m.insert("down_m".into(), json!(p.down_m));
        }
        _ => {}
    }
    OperatorCommand::from_object(m).map_err(|e| CommandError {
        field: match e.field.as_str() {
            "altitude_m" => "altitude_m",
            "confirm" => "force",
            "north_m" | "east_m" | "down_m" => "target",
            _ => "command",
        },
        reason: e.error,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use skein_model::command::{ForceDisarm, Takeoff};

    fn cmd(name: &str) -> Command {
        Command {
            source: "test".into(),
            request_id: 1,
            command: name.into(),
            altitude_m: f64::NAN,
            force: false,
            target: Point::default(),
        }
    }

    #[test]
    fn ned_becomes_enu_and_back() {
        let ned = Ned::new(10.0, 3.0, -7.0);
        let p = enu_point(ned);
        assert_eq!((p.x, p.y, p.z), (3.0, 10.0, 7.0));
        assert_eq!(ned_of(&p), ned);
    }

    #[test]
    fn a_north_heading_is_an_enu_yaw_of_a_quarter_turn() {
        let q = enu_orientation(0.0);
        let yaw = 2.0 * q.z.atan2(q.w);
        assert!((yaw - FRAC_PI_2).abs() < 1e-12, "{yaw}");
        let q = enu_orientation(90.0); // east: ENU yaw 0
        assert!((2.0 * q.z.atan2(q.w)).abs() < 1e-12);
    }

    #[test]
    fn commands_parse_and_bad_fields_are_named() {
        assert_eq!(
            command(&cmd("takeoff")).unwrap(),
            OperatorCommand::Takeoff(Takeoff { altitude_m: None })
        );
        let mut c = cmd("takeoff");
        c.altitude_m = -3.0;
        assert_eq!(command(&c).unwrap_err().field, "altitude_m");
        let mut c = cmd("goto");
        c.target = Point {
            x: 5.0,
            y: 20.0,
            z: 10.0,
        };
        assert_eq!(
            command(&c).unwrap(),
            OperatorCommand::GoTo(Ned::new(20.0, 5.0, -10.0).into())
        );
        c.target.z = f64::INFINITY;
        assert_eq!(command(&c).unwrap_err().field, "target");
        let e = command(&cmd("explode")).unwrap_err();
        assert_eq!(e.field, "command");
        assert!(e.reason.contains("explode"), "{e}");
        let mut c = cmd("disarm");
        assert_eq!(command(&c).unwrap(), OperatorCommand::Disarm);
        c.force = true;
        assert_eq!(
            command(&c).unwrap(),
            OperatorCommand::ForceDisarm(ForceDisarm { confirm: true })
        );
        let mut c = cmd("takeoff");
        c.altitude_m = f64::INFINITY;
        assert_eq!(command(&c).unwrap_err().field, "altitude_m");
    }
}
