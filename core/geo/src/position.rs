//! [`Position`] and [`Velocity`]: where a vehicle is and how it moves, as the vehicle
//! snapshot carries them (`GET /api/v1/vehicles/{id}`, and the JSON plugins receive).

use crate::{GeoPoint, Ned, NedFrame};
use serde::{Deserialize, Serialize};

/// Position of a vehicle: swarm-frame NED plus its geodetic position.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct Position {
    /// North of the swarm origin, metres.
    pub north_m: f64,
    /// East of the swarm origin, metres.
    pub east_m: f64,
    /// Down from the swarm origin, metres (negative is above it).
    pub down_m: f64,
    /// Latitude, degrees (`GLOBAL_POSITION_INT.lat`).
    pub lat_deg: f64,
    /// Longitude, degrees (`GLOBAL_POSITION_INT.lon`).
    pub lon_deg: f64,
    /// Altitude above mean sea level, metres (`GLOBAL_POSITION_INT.alt`).
    pub alt_amsl_m: f64,
    /// Height above the vehicle's home, metres (`GLOBAL_POSITION_INT.relative_alt`).
    pub relative_alt_m: f64,
}

impl Position {
    /// Builds the position from a geodetic point, its height above home, and the swarm
    /// frame.
    pub fn from_geo(geo: GeoPoint, relative_alt_m: f64, swarm: &NedFrame) -> Position {
        let ned = swarm.to_ned(&geo);
        Position {
            north_m: ned.north_m,
            east_m: ned.east_m,
            down_m: ned.down_m,
            lat_deg: geo.lat_deg,
            lon_deg: geo.lon_deg,
            alt_amsl_m: geo.alt_amsl_m,
            relative_alt_m,
        }
    }

    /// The swarm-frame NED part.
    pub fn ned(&self) -> Ned {
        Ned::new(self.north_m, self.east_m, self.down_m)
    }

    /// The geodetic part.
    pub fn geo(&self) -> GeoPoint {
        GeoPoint::new(self.lat_deg, self.lon_deg, self.alt_amsl_m)
    }
}

/// Velocity, NED, metres per second (`GLOBAL_POSITION_INT.vx/vy/vz`).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct Velocity {
    /// North, m/s.
    pub north_m_s: f64,
    /// East, m/s.
    pub east_m_s: f64,
    /// Down, m/s.
    pub down_m_s: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_position_carries_both_frames_of_one_point() {
        let swarm = NedFrame::new(GeoPoint::new(47.3977, 8.5456, 488.0));
        let geo = swarm.to_geo(Ned::new(12.0, -7.0, -10.0));
        let p = Position::from_geo(geo, 10.0, &swarm);
        assert!((p.ned() - Ned::new(12.0, -7.0, -10.0)).norm() < 1e-6);
        assert_eq!(p.geo(), geo);
        let json = serde_json::to_value(p).unwrap();
        assert_eq!(json["relative_alt_m"], 10.0);
        assert_eq!(serde_json::from_value::<Position>(json).unwrap(), p);
    }
}
