//! A plugin's typed view of the vehicle snapshot JSON the host sends (the object of
//! `GET /api/v1/vehicles/{id}`, see skein's `VehicleSnapshot`).
//!
//! Every field of [`Vehicle`] has a default and unknown fields are ignored, so a plugin keeps working when
//! skein adds fields to the snapshot; a field whose *meaning* changes bumps
//! [`crate::abi::MESSAGES_VERSION`]. [`Position`] and [`Velocity`] are skein's own types
//! (`skein-geo`), shared rather than mirrored; [`Vehicle`] itself stays a view of its own:
//! skein's `VehicleSnapshot` lives in `skein-model` (which a plugin does not link) and
//! holds typed states (`VehicleState`, `LandedState`) a plugin built against an older SDK
//! must not fail on, so here `state` is a string and every field has a default.

use crate::geometry::Ned;
use serde::{Deserialize, Serialize};

/// Position (swarm-frame NED plus geodetic) and velocity (NED, m/s): skein's own types,
/// the very ones the host serialises into the snapshot.
pub use skein_geo::{Position, Velocity};

/// Link health of the vehicle's MAVLink link.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(default)]
pub struct Link {
    /// False after the link timeout (3 s) without a valid message.
    pub connected: bool,
    /// Milliseconds since the last valid message.
    pub last_seen_ms: u64,
}

/// One vehicle as a plugin sees it.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default)]
pub struct Vehicle {
    /// User-facing id (`"uav-1"`).
    pub id: String,
    /// MAVLink system id.
    pub sysid: u8,
    /// Vehicle model name (`"generic"`, `"observation"`).
    pub model: String,
    /// FSM state name (`"InFormation"`).
    pub state: String,
    /// Armed flag.
    pub armed: bool,
    /// PX4 mode name (`"OFFBOARD"`).
    pub px4_mode: String,
    /// Position, once known.
    pub position: Option<Position>,
    /// Velocity.
    pub velocity: Velocity,
    /// Heading, degrees clockwise from north in `[0, 360)`.
    pub heading_deg: f64,
    /// Link health.
    pub link: Link,
}

impl Vehicle {
    /// The swarm-frame NED position, if known.
    pub fn ned(&self) -> Option<Ned> {
        self.position.map(|p| p.ned())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_api_shape_and_ignores_unknown_fields() {
        let v: Vehicle = serde_json::from_value(serde_json::json!({
            "id": "uav-1", "sysid": 1, "model": "generic", "state": "InFormation", "armed": true,
            "px4_mode": "OFFBOARD", "landed_state": "InAir",
            "position": {"north_m": 0.0, "east_m": 5.0, "down_m": -10.0, "lat_deg": 47.3977,
                         "lon_deg": 8.5456, "alt_amsl_m": 498.0, "relative_alt_m": 10.0},
            "velocity": {"north_m_s": 1.0, "east_m_s": 0.0, "down_m_s": 0.0}, "heading_deg": 90.0,
            "battery": {"percent": 87.0, "voltage_v": 15.9}, "link": {"connected": true, "last_seen_ms": 12},
            "formation": null, "payloads": [], "something_new": 3
        }))
        .unwrap();
        assert_eq!(v.id, "uav-1");
        assert_eq!(v.ned(), Some(Ned::new(0.0, 5.0, -10.0)));
        assert_eq!(v.heading_deg, 90.0);
        assert!(v.link.connected);
    }
}

/// A simulated non-cooperative aircraft (an intruder) as [`crate::Context::sim_aircraft`]
/// gives it: the simulator's truth, for simulated sensors to render.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default)]
pub struct SimAircraft {
    /// Its truth id (`"intruder-1"`), for evaluation; a camera must not draw it.
    pub id: String,
    /// North of the swarm origin, metres.
    pub north_m: f64,
    /// East of the swarm origin, metres.
    pub east_m: f64,
    /// Down from the swarm origin, metres.
    pub down_m: f64,
    /// Velocity, NED.
    pub velocity: Velocity,
    /// Rotor-tip to rotor-tip span, metres.
    pub span_m: f64,
}

impl SimAircraft {
    /// The swarm-frame NED position.
    pub fn ned(&self) -> Ned {
        Ned::new(self.north_m, self.east_m, self.down_m)
    }
}
