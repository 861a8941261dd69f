//! The vehicle snapshot: what the API (`GET /api/v1/vehicles/{id}`), the WebSocket stream
//! and the dashboard show of one vehicle. Serialises to the JSON of the design brief.

use crate::fsm::VehicleState;
use crate::geo::Ned;
use serde::{Deserialize, Serialize};

// Position and velocity are shared with the plugin SDK (plugins read them from the same
// JSON), so they live with the geodesy.
pub use crate::geo::{Position, Velocity};

/// Battery (`BATTERY_STATUS` / `SYS_STATUS`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct Battery {
    /// Remaining charge, percent (0–100).
    pub percent: f64,
    /// Pack voltage, volts.
    pub voltage_v: f64,
}

/// Link health.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct LinkStatus {
    /// False after the link timeout (3 s) without a valid message.
    pub connected: bool,
    /// Milliseconds since the last valid message.
    pub last_seen_ms: u64,
}

/// GNSS as the autopilot reports it (`GPS_RAW_INT`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct GpsStatus {
    /// MAVLink's `GPS_FIX_TYPE` number: 0-1 no fix, 2 2D, 3 3D, 4 DGPS, 5 RTK float,
    /// 6 RTK fixed.
    pub fix_type: u8,
    /// Satellites visible (`satellites_visible`).
    pub satellites: u8,
    /// Horizontal position accuracy, metres (`h_acc`, the receiver's estimate, which PX4
    /// fills; `eph` as centimetres where an autopilot leaves `h_acc` out); `null` when
    /// unknown.
    pub eph_m: Option<f64>,
    /// Vertical position accuracy, metres (`v_acc`, else `epv`); `null` when unknown.
    pub epv_m: Option<f64>,
    /// Seconds since skein last sent the vehicle RTK corrections (`GPS_RTCM_DATA`);
    /// `null` when it never did.
    #[serde(default)]
    pub correction_age_s: Option<f64>,
}

impl GpsStatus {
    /// The fix in words (`"3D fix"`, `"RTK float"`, `"RTK fixed"`, ...).
    pub fn fix_name(&self) -> &'static str {
        match self.fix_type {
            0 | 1 => "no fix",
            2 => "2D fix",
            3 => "3D fix",
            4 => "DGPS",
            5 => "RTK float",
            6 => "RTK fixed",
            7 => "static",
            8 => "PPP",
            _ => "other fix",
        }
    }
}

/// A text the autopilot sent (`STATUSTEXT`, chunks joined).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct Px4Message {
    /// `MAV_SEVERITY` (0 emergency … 4 warning … 7 debug).
    pub severity: u8,
    /// The text (`"Preflight Fail: Open Drone ID system missing"`).
    pub text: String,
    /// When it arrived, milliseconds since the Unix epoch (UTC).
    pub unix_ms: u64,
}

/// One of PX4's health and arming checks that reports a problem (PX4's events
/// interface: the check's event in its health and arming check report).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct Px4ArmingCheck {
    /// PX4's message (`"Open Drone ID system missing"`).
    pub message: String,
    /// PX4's longer description (may be empty).
    pub description: String,
    /// The event's log level: `emergency`, `alert`, `critical`, `error`, `warning`,
    /// `notice`, `info`, `debug`.
    pub severity: String,
    /// The check stops arming in the vehicle's current mode.
    pub prevents_arming: bool,
}

/// How many of the autopilot's warnings a snapshot carries
/// ([`VehicleSnapshot::px4_messages`]).
pub const PX4_MESSAGES_KEPT: usize = 5;

/// Remote ID on this vehicle (ASTM F3411 through MAVLink's Open Drone ID messages).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct RemoteIdStatus {
    /// skein sends the operator's part (`OPEN_DRONE_ID_SYSTEM` and
    /// `OPEN_DRONE_ID_OPERATOR_ID`, 1 Hz) to this vehicle (`[remote_id]` configured).
    pub operator_sent: bool,
    /// The vehicle's transmitter's last `OPEN_DRONE_ID_ARM_STATUS`; `null` until one
    /// arrives (no transmitter, or one that does not say).
    pub transmitter: Option<RemoteIdArmStatus>,
    /// Where the operator location of the last `OPEN_DRONE_ID_SYSTEM` sent came from;
    /// `null` before the first.
    #[serde(default)]
    pub operator_location_source: Option<OperatorLocationSource>,
    /// The age of that location now, seconds: for `live_gnss` the time since its fix
    /// arrived from the ground station's receiver; `null` for `fixed` and `takeoff`.
    #[serde(default)]
    pub operator_location_age_s: Option<f64>,
    /// Why the ground station's live GNSS location was not the one sent, while
    /// `[remote_id] operator_gnss` is configured (`"no fix from gpsd://127.0.0.1:2947 for
    /// 3.2 s (the limit is 3 s); the source closed the connection"`); `null` when it was, or
    /// without `operator_gnss`.
    #[serde(default)]
    pub operator_location_fallback: Option<String>,
    /// The ground station's GNSS receiver (`[remote_id] operator_gnss`), one per
    /// process; `null` without one.
    #[serde(default)]
    pub operator_gnss: Option<OperatorGnssStatus>,
}

/// Where Remote ID's operator location comes from
/// (`OPEN_DRONE_ID_SYSTEM.operator_location_type`, `MAV_ODID_OPERATOR_LOCATION_TYPE_*`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum OperatorLocationSource {
    /// The ground station's own GNSS receiver, live (`LIVE_GNSS`).
    LiveGnss,
    /// The configured `[remote_id] operator_location` (`FIXED`).
    Fixed,
    /// The vehicle's takeoff point, its home (`TAKEOFF`).
    Takeoff,
}

/// The ground station's GNSS receiver as the process reads it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct OperatorGnssStatus {
    /// The source (`gpsd://127.0.0.1:2947`, `serial:/dev/ttyACM0:9600`,
    /// `tcp://HOST:PORT`).
    pub source: String,
    /// A connection to it is open.
    pub connected: bool,
    /// Seconds since its last valid fix arrived; `null` before the first.
    pub fix_age_s: Option<f64>,
    /// That fix's estimated horizontal error, metres (gpsd's `eph`); `null` when not
    /// given (NMEA).
    pub eph_m: Option<f64>,
    /// The receiver's latest report says it has no fix.
    pub no_fix: bool,
    /// Why the last connection ended or could not open; `null` once it reports.
    pub error: Option<String>,
    /// Lines dropped as malformed (a bad checksum or field, JSON that does not parse).
    pub malformed: u64,
}

/// What a Remote ID transmitter says of itself (`OPEN_DRONE_ID_ARM_STATUS`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct RemoteIdArmStatus {
    /// `status` is `MAV_ODID_ARM_STATUS_GOOD_TO_ARM`.
    pub good_to_arm: bool,
    /// Why not (`error`; empty when good to arm).
    pub error: String,
}

/// The vehicle's place in the formation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct FormationSlot {
    /// Slot index (0 is the leader's slot).
    pub slot: usize,
    /// True for the formation leader.
    pub leader: bool,
    /// The slot's position, swarm-frame NED.
    pub target: Ned,
    /// Distance from the vehicle to its slot, metres.
    pub error_m: f64,
}

/// One vehicle as the API shows it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct VehicleSnapshot {
    /// User-facing id (`uav-<sysid>` by default).
    pub id: String,
    /// MAVLink system id.
    pub sysid: u8,
    /// Connection string of the MAVLink endpoint it is reached on (`udpin:0.0.0.0:14540`;
    /// empty when unknown): the key of its counters in `GET /api/v1/links`.
    #[serde(default)]
    pub connection: String,
    /// Vehicle model name (`generic`, `observation`).
    pub model: String,
    /// FSM state.
    pub state: VehicleState,
    /// Armed flag from the last `HEARTBEAT`.
    pub armed: bool,
    /// PX4 mode name from the last `HEARTBEAT.custom_mode` (`"OFFBOARD"`).
    pub px4_mode: String,
    /// `EXTENDED_SYS_STATE.landed_state` (`"OnGround"`, `"InAir"` …).
    pub landed_state: crate::px4::LandedState,
    /// Position, once a global position has been received.
    pub position: Option<Position>,
    /// Home position (`HOME_POSITION`, height above home 0), once received: where RTL
    /// returns to and takeoff altitudes are measured from. Until it is known the vehicle
    /// has no local frame, and takeoff, hold and go-to are refused.
    #[serde(default)]
    pub home: Option<Position>,
    /// Velocity.
    pub velocity: Velocity,
    /// Heading, degrees clockwise from north in `[0, 360)` (`ATTITUDE.yaw`).
    pub heading_deg: f64,
    /// Battery, once reported.
    pub battery: Option<Battery>,
    /// GNSS fix, once reported (`GPS_RAW_INT`).
    #[serde(default)]
    pub gps: Option<GpsStatus>,
    /// PX4's own arming checks pass in its current mode (`SYS_STATUS`'s
    /// `MAV_SYS_STATUS_PREARM_CHECK` health bit); `null` until reported.
    #[serde(default)]
    pub prearm_ok: Option<bool>,
    /// The autopilot's latest warnings and errors (`STATUSTEXT` of severity 4 or worse),
    /// oldest first, at most [`PX4_MESSAGES_KEPT`].
    #[serde(default)]
    pub px4_messages: Vec<Px4Message>,
    /// PX4's failing health and arming checks (its events' report, in the current
    /// mode); empty for an autopilot without the events interface, or all passing.
    #[serde(default)]
    pub px4_arming_checks: Vec<Px4ArmingCheck>,
    /// Link health.
    pub link: LinkStatus,
    /// Formation slot, while in formation.
    pub formation: Option<FormationSlot>,
    /// Payload instances (filled by the plugin host).
    pub payloads: Vec<serde_json::Value>,
    /// The geofence on this vehicle: its autopilot's copy (`synced`, `differs`, `failed`
    /// with the reason, `pending`) and skein's own breach check; `null` where no fence is
    /// kept (a vehicle of another process before it reports one).
    #[serde(default)]
    pub fence: Option<crate::geofence::FenceStatus>,
    /// Remote ID; `null` where skein sends none and no transmitter reported.
    #[serde(default)]
    pub remote_id: Option<RemoteIdStatus>,
}

impl VehicleSnapshot {
    /// A connected vehicle hovering under offboard control at `position` (NED in the swarm
    /// frame `frame`, home at the frame's origin), model `observation`: what a benchmark's
    /// payload host or a test presents where no vehicle flies. Change the fields a case
    /// needs (`state`, `heading_deg` …) after.
    pub fn hovering_at(id: &str, sysid: u8, frame: &crate::geo::NedFrame, position: Ned) -> Self {
        VehicleSnapshot {
            id: id.into(),
            sysid,
            connection: String::new(),
            model: "observation".into(),
            state: VehicleState::Hovering,
            armed: true,
            px4_mode: "OFFBOARD".into(),
            landed_state: crate::px4::LandedState::InAir,
            position: Some(Position::from_geo(
                frame.to_geo(position),
                -position.down_m,
                frame,
            )),
            home: Some(Position::from_geo(frame.origin, 0.0, frame)),
            velocity: Velocity::default(),
            heading_deg: 0.0,
            battery: None,
            gps: None,
            prearm_ok: None,
            px4_messages: vec![],
            px4_arming_checks: vec![],
            link: LinkStatus {
                connected: true,
                last_seen_ms: 0,
            },
            formation: None,
            payloads: vec![],
            fence: None,
            remote_id: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::{GeoPoint, NedFrame};

    #[test]
    fn snapshot_serialises_to_the_contract_shape() {
        let swarm = NedFrame::new(GeoPoint::new(47.3977, 8.5456, 488.0));
        let geo = swarm.to_geo(Ned::new(0.0, 5.0, -10.0));
        let snap = VehicleSnapshot {
            id: "uav-1".into(),
            sysid: 1,
            connection: "udpin:0.0.0.0:14540".into(),
            model: "generic".into(),
            state: VehicleState::InFormation,
            armed: true,
            px4_mode: "OFFBOARD".into(),
            landed_state: crate::px4::LandedState::InAir,
            position: Some(Position::from_geo(geo, 10.0, &swarm)),
            home: Some(Position::from_geo(swarm.origin, 0.0, &swarm)),
            velocity: Velocity::default(),
            heading_deg: 90.0,
            battery: Some(Battery {
                percent: 87.0,
                voltage_v: 15.9,
            }),
            gps: Some(GpsStatus {
                fix_type: 3,
                satellites: 12,
                eph_m: Some(0.8),
                epv_m: None,
                correction_age_s: None,
            }),
            prearm_ok: Some(true),
            px4_messages: vec![],
            px4_arming_checks: vec![],
            link: LinkStatus {
                connected: true,
                last_seen_ms: 12,
            },
            formation: None,
            payloads: vec![],
            fence: None,
            remote_id: None,
        };
        let v = serde_json::to_value(&snap).unwrap();
        assert_eq!(v["state"], "InFormation");
        assert_eq!(v["px4_mode"], "OFFBOARD");
        assert!((v["position"]["east_m"].as_f64().unwrap() - 5.0).abs() < 1e-6);
        assert!((v["position"]["down_m"].as_f64().unwrap() + 10.0).abs() < 1e-6);
        assert_eq!(v["home"]["north_m"], 0.0);
        assert_eq!(v["battery"]["voltage_v"], 15.9);
        assert_eq!(v["link"]["connected"], true);
        // The field day's contract: `gps` with `fix_type`, `satellites`, `eph_m`, `epv_m`.
        assert_eq!(
            v["gps"],
            serde_json::json!({"fix_type": 3, "satellites": 12, "eph_m": 0.8, "epv_m": null,
                "correction_age_s": null})
        );
        assert!(v["payloads"].as_array().unwrap().is_empty());
    }
}
