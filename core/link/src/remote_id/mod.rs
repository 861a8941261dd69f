//! Remote ID (ASTM F3411 / ASD-STAN prEN 4709-002 through MAVLink's Open Drone ID
//! messages): the ground station's part of each aircraft's broadcast. The aircraft's
//! transmitter (a Remote ID module on the autopilot's serial port, `MAV_COMP_ID_ODID_TXRX_1`)
//! broadcasts its own position and identity; the operator's identity and location come
//! from the ground station, as `OPEN_DRONE_ID_OPERATOR_ID` and `OPEN_DRONE_ID_SYSTEM`, at
//! least once a second. The link sends both to its vehicle at 1 Hz with its heartbeat
//! ([`RemoteIdConfig::messages`]), addressed to every component of the vehicle (PX4
//! routes them to the transmitter). The transmitter answers with `OPEN_DRONE_ID_ARM_STATUS`
//! (whether it is ready; PX4 refuses arming without it when `COM_ARM_ODID` = 2), kept in
//! the telemetry (`skein_model::vehicle::RemoteIdArmStatus`).
//!
//! The operator's location is the ground station's own GNSS receiver's while it has a
//! live fix (`operator_gnss`, `LIVE_GNSS`), else the configured one (`FIXED`), else the
//! vehicle's takeoff point (`TAKEOFF`): [`operator_location`].

mod operator_location;

pub use operator_location::{LIVE_FIX_MAX_AGE, OperatorLocation, RemoteIdLink, live_fix};

use serde::{Deserialize, Deserializer, Serialize};
use skein_mavlink::MavMessage;
use skein_mavlink::dialect::{
    MavOdidCategoryEu, MavOdidClassEu, MavOdidClassificationType, MavOdidOperatorIdType,
    MavOdidOperatorLocationType, OPEN_DRONE_ID_OPERATOR_ID_DATA, OPEN_DRONE_ID_SYSTEM_DATA,
};
use skein_model::geo::GeoPoint;
use skein_model::vehicle::OperatorLocationSource;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// Characters of an operator id (`OPEN_DRONE_ID_OPERATOR_ID.operator_id`).
pub const OPERATOR_ID_CHARS: usize = 20;

/// Seconds from the Unix epoch to the Open Drone ID epoch, 2019-01-01 00:00:00 UTC
/// (`OPEN_DRONE_ID_SYSTEM.timestamp` counts from there).
pub const ODID_EPOCH_UNIX_S: u64 = 1_546_300_800;

/// `OPEN_DRONE_ID_SYSTEM`'s "unknown" altitude and area heights, metres.
pub const UNKNOWN_ALTITUDE_M: f32 = -1000.0;

/// `[remote_id]` of the configuration: what skein tells every vehicle's Remote ID
/// transmitter about its operator.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RemoteIdConfig {
    /// The operator's registration number from the civil aviation authority (EU:
    /// 16 characters and a 3-character secret, the secret left out of the broadcast), at
    /// most 20 printable ASCII characters (`OPEN_DRONE_ID_OPERATOR_ID.operator_id`,
    /// type `MAV_ODID_OPERATOR_ID_TYPE_CAA`).
    #[serde(deserialize_with = "operator_id")]
    pub operator_id: String,
    /// Where the operator stands (`operator_location_type` FIXED); absent: at each
    /// vehicle's takeoff point, its home (TAKEOFF; latitude and longitude 0, "unknown",
    /// until the vehicle reports a home). With `operator_gnss`, what is sent while the
    /// receiver has no live fix.
    #[serde(default)]
    pub operator_location: Option<GeoPoint>,
    /// The ground station's own GNSS receiver (`gpsd://HOST[:PORT]`,
    /// `serial:DEVICE:BAUD` or `tcp://HOST:PORT`, see [`skein_gnss::source`]): while its
    /// latest report is a fix no older than [`LIVE_FIX_MAX_AGE`], the operator is there
    /// (`operator_location_type` LIVE_GNSS). Read once per process
    /// ([`crate::LinkSetup::operator_gnss`]).
    #[serde(default)]
    pub operator_gnss: Option<skein_gnss::GnssSource>,
    /// EU category of the operation (`open`, `specific`, `certified`; default
    /// `undeclared`); with a category or class the classification is EU.
    #[serde(default)]
    pub category_eu: CategoryEu,
    /// EU class of the aircraft, 0 to 6 (`C0` … `C6`); absent: undeclared.
    #[serde(default)]
    pub class_eu: Option<ClassEu>,
}

/// EU category of the operation (`OPEN_DRONE_ID_SYSTEM.category_eu`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CategoryEu {
    /// Not declared.
    #[default]
    Undeclared,
    /// The open category.
    Open,
    /// The specific category.
    Specific,
    /// The certified category.
    Certified,
}

/// EU class of the aircraft, 0 to 6 (`OPEN_DRONE_ID_SYSTEM.class_eu`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "u8", into = "u8")]
pub struct ClassEu(u8);

impl TryFrom<u8> for ClassEu {
    type Error = String;

    fn try_from(class: u8) -> Result<Self, String> {
        if class <= 6 {
            Ok(ClassEu(class))
        } else {
            Err(format!("class_eu {class}: the EU classes are 0 to 6"))
        }
    }
}

impl From<ClassEu> for u8 {
    fn from(c: ClassEu) -> u8 {
        c.0
    }
}

fn operator_id<'de, D: Deserializer<'de>>(d: D) -> Result<String, D::Error> {
    let id = String::deserialize(d)?;
    if id.is_empty() || id.len() > OPERATOR_ID_CHARS || !id.bytes().all(|b| b.is_ascii_graphic()) {
        return Err(serde::de::Error::custom(format!(
            "operator_id {id:?}: 1 to {OPERATOR_ID_CHARS} printable ASCII characters"
        )));
    }
    Ok(id)
}

impl RemoteIdConfig {
    /// The two messages for vehicle `sysid` at `now`: `OPEN_DRONE_ID_SYSTEM` (the
    /// operator at `location`, from [`RemoteIdConfig::operator_location`]) and
    /// `OPEN_DRONE_ID_OPERATOR_ID`, to every component of the vehicle.
    pub fn messages(
        &self,
        sysid: u8,
        location: &OperatorLocation,
        now: SystemTime,
    ) -> [MavMessage; 2] {
        [
            MavMessage::OPEN_DRONE_ID_SYSTEM(self.system(sysid, location, now)),
            MavMessage::OPEN_DRONE_ID_OPERATOR_ID(self.operator(sysid)),
        ]
    }

    fn system(
        &self,
        sysid: u8,
        location: &OperatorLocation,
        now: SystemTime,
    ) -> OPEN_DRONE_ID_SYSTEM_DATA {
        use MavOdidOperatorLocationType::*;
        let location_type = match location.source {
            OperatorLocationSource::LiveGnss => MAV_ODID_OPERATOR_LOCATION_TYPE_LIVE_GNSS,
            OperatorLocationSource::Fixed => MAV_ODID_OPERATOR_LOCATION_TYPE_FIXED,
            OperatorLocationSource::Takeoff => MAV_ODID_OPERATOR_LOCATION_TYPE_TAKEOFF,
        };
        let at = location.lat_lon_deg;
        let declared = self.category_eu != CategoryEu::Undeclared || self.class_eu.is_some();
        OPEN_DRONE_ID_SYSTEM_DATA {
            target_system: sysid,
            target_component: 0,
            id_or_mac: [0; 20],
            operator_location_type: location_type,
            classification_type: if declared {
                MavOdidClassificationType::MAV_ODID_CLASSIFICATION_TYPE_EU
            } else {
                MavOdidClassificationType::MAV_ODID_CLASSIFICATION_TYPE_UNDECLARED
            },
            operator_latitude: at.map_or(0, |(lat, _)| (lat * 1e7).round() as i32),
            operator_longitude: at.map_or(0, |(_, lon)| (lon * 1e7).round() as i32),
            operator_altitude_geo: location.altitude_m.map_or(UNKNOWN_ALTITUDE_M, |a| a as f32),
            area_count: 1,
            area_radius: 0,
            area_ceiling: UNKNOWN_ALTITUDE_M,
            area_floor: UNKNOWN_ALTITUDE_M,
            category_eu: match self.category_eu {
                CategoryEu::Undeclared => MavOdidCategoryEu::MAV_ODID_CATEGORY_EU_UNDECLARED,
                CategoryEu::Open => MavOdidCategoryEu::MAV_ODID_CATEGORY_EU_OPEN,
                CategoryEu::Specific => MavOdidCategoryEu::MAV_ODID_CATEGORY_EU_SPECIFIC,
                CategoryEu::Certified => MavOdidCategoryEu::MAV_ODID_CATEGORY_EU_CERTIFIED,
            },
            class_eu: self
                .class_eu
                .map_or(MavOdidClassEu::MAV_ODID_CLASS_EU_UNDECLARED, class_eu),
            timestamp: odid_timestamp(now),
        }
    }

    fn operator(&self, sysid: u8) -> OPEN_DRONE_ID_OPERATOR_ID_DATA {
        OPEN_DRONE_ID_OPERATOR_ID_DATA {
            target_system: sysid,
            target_component: 0,
            id_or_mac: [0; 20],
            operator_id_type: MavOdidOperatorIdType::MAV_ODID_OPERATOR_ID_TYPE_CAA,
            operator_id: self.operator_id.as_str().into(),
        }
    }
}

/// `MAV_ODID_CLASS_EU_CLASS_<n>` of class `c`.
fn class_eu(c: ClassEu) -> MavOdidClassEu {
    use MavOdidClassEu::*;
    [
        MAV_ODID_CLASS_EU_CLASS_0,
        MAV_ODID_CLASS_EU_CLASS_1,
        MAV_ODID_CLASS_EU_CLASS_2,
        MAV_ODID_CLASS_EU_CLASS_3,
        MAV_ODID_CLASS_EU_CLASS_4,
        MAV_ODID_CLASS_EU_CLASS_5,
        MAV_ODID_CLASS_EU_CLASS_6,
    ][usize::from(c.0)]
}

/// Seconds since 2019-01-01 00:00:00 UTC at `now` (0 before it).
fn odid_timestamp(now: SystemTime) -> u32 {
    let unix = now
        .duration_since(UNIX_EPOCH)
        .unwrap_or(Duration::ZERO)
        .as_secs();
    unix.saturating_sub(ODID_EPOCH_UNIX_S) as u32
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Instant;

    fn config(toml_text: &str) -> Result<RemoteIdConfig, String> {
        toml::from_str(toml_text).map_err(|e| e.to_string())
    }

    #[test]
    fn a_fixed_operator_with_an_eu_class_goes_out_as_configured() {
        let c = config(
            r#"operator_id = "FIN87astrdge12k8"
               operator_location = { lat_deg = 60.1699, lon_deg = 24.9384, alt_amsl_m = 25.0 }
               category_eu = "open"
               class_eu = 1"#,
        )
        .unwrap();
        let at = UNIX_EPOCH + Duration::from_secs(ODID_EPOCH_UNIX_S + 100);
        let location = c.operator_location(None, None, Instant::now());
        let [
            MavMessage::OPEN_DRONE_ID_SYSTEM(s),
            MavMessage::OPEN_DRONE_ID_OPERATOR_ID(o),
        ] = c.messages(3, &location, at)
        else {
            panic!()
        };
        assert_eq!((s.target_system, s.target_component), (3, 0));
        assert_eq!(
            (s.operator_latitude, s.operator_longitude),
            (601_699_000, 249_384_000)
        );
        assert_eq!(s.operator_altitude_geo, 25.0);
        assert_eq!(
            s.operator_location_type,
            MavOdidOperatorLocationType::MAV_ODID_OPERATOR_LOCATION_TYPE_FIXED
        );
        assert_eq!(
            s.classification_type,
            MavOdidClassificationType::MAV_ODID_CLASSIFICATION_TYPE_EU
        );
        assert_eq!(s.category_eu, MavOdidCategoryEu::MAV_ODID_CATEGORY_EU_OPEN);
        assert_eq!(s.class_eu, MavOdidClassEu::MAV_ODID_CLASS_EU_CLASS_1);
        assert_eq!(s.timestamp, 100);
        assert_eq!(o.target_system, 3);
        assert_eq!(o.operator_id.to_str().unwrap(), "FIN87astrdge12k8");
    }

    #[test]
    fn without_a_location_the_operator_is_at_the_takeoff_point() {
        let c = config(r#"operator_id = "OP1""#).unwrap();
        let home = GeoPoint::new(47.397742, 8.545594, 488.0);
        let location = c.operator_location(None, Some(home), Instant::now());
        let [MavMessage::OPEN_DRONE_ID_SYSTEM(s), _] = c.messages(1, &location, SystemTime::now())
        else {
            panic!()
        };
        assert_eq!(
            s.operator_location_type,
            MavOdidOperatorLocationType::MAV_ODID_OPERATOR_LOCATION_TYPE_TAKEOFF
        );
        assert_eq!(s.operator_latitude, 473_977_420);
        assert_eq!(
            s.classification_type,
            MavOdidClassificationType::MAV_ODID_CLASSIFICATION_TYPE_UNDECLARED
        );
        let location = c.operator_location(None, None, Instant::now());
        let [MavMessage::OPEN_DRONE_ID_SYSTEM(s), _] = c.messages(1, &location, SystemTime::now())
        else {
            panic!()
        };
        assert_eq!(
            (s.operator_latitude, s.operator_altitude_geo),
            (0, UNKNOWN_ALTITUDE_M)
        );
    }

    #[test]
    fn bad_values_are_refused_naming_them() {
        let e = config(r#"operator_id = "THIS-ID-IS-LONGER-THAN-20""#).unwrap_err();
        assert!(e.contains("operator_id"), "{e}");
        let e = config(r#"operator_id = "two words""#).unwrap_err();
        assert!(e.contains("printable"), "{e}");
        let e = config("operator_id = \"OP1\"\nclass_eu = 7").unwrap_err();
        assert!(e.contains("0 to 6"), "{e}");
        let e = config("operator_id = \"OP1\"\ncategory_eu = \"fun\"").unwrap_err();
        assert!(e.contains("category_eu") || e.contains("fun"), "{e}");
        let e = config("operator_id = \"OP1\"\noperator = 1").unwrap_err();
        assert!(e.contains("operator"), "{e}");
        let e = config("operator_id = \"OP1\"\noperator_gnss = \"gps://x\"").unwrap_err();
        assert!(e.contains("expected gpsd://"), "{e}");
        let c = config("operator_id = \"OP1\"\noperator_gnss = \"gpsd://localhost\"").unwrap();
        assert_eq!(
            c.operator_gnss.unwrap().to_string(),
            "gpsd://localhost:2947"
        );
    }
}
