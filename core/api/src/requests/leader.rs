//! Leader motion: `POST /api/v1/formation/leader/{goto,waypoints,orbit,hold}`, moving the
//! formation's reference point (the virtual leader, or a leader vehicle). One parser per
//! route; the coordinator then checks the motion against the swarm (the slowest vehicle
//! model's speed limit, the geofence, the minimum separation for an orbit's radius).

use super::parse_or_empty;
use crate::error::ApiError;
use serde::Deserialize;
use skein_model::geo::Ned;
use skein_swarm::formation::LeaderMotion;
use utoipa::ToSchema;

/// Default speed of leader motions, m/s.
pub const DEFAULT_LEADER_SPEED_M_S: f64 = 5.0;

/// A swarm-frame point; without `down_m` the formation keeps its altitude.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PointRequest {
    /// Swarm-frame north, metres.
    pub north_m: f64,
    /// Swarm-frame east, metres.
    pub east_m: f64,
    /// Swarm-frame down, metres (negative is up); default: the formation's altitude.
    pub down_m: Option<f64>,
}

impl PointRequest {
    fn ned(self) -> Ned {
        // Missing altitude: keep the formation's (the coordinator fills NaN in).
        Ned::new(self.north_m, self.east_m, self.down_m.unwrap_or(f64::NAN))
    }
}

/// `POST …/leader/goto`: fly to a point.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct LeaderGoToRequest {
    /// Swarm-frame north, metres.
    pub north_m: f64,
    /// Swarm-frame east, metres.
    pub east_m: f64,
    /// Swarm-frame down, metres (negative is up); default: the formation's altitude.
    pub down_m: Option<f64>,
    /// Cruise speed, m/s, above 0 and at most the slowest vehicle model's limit; default 5.
    #[schema(exclusive_minimum = 0.0)]
    pub speed_m_s: Option<f64>,
}

/// `POST …/leader/waypoints`: fly a list of points in order.
#[derive(Debug, Clone, PartialEq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct LeaderWaypointsRequest {
    /// The points, in order (at least one).
    #[schema(min_items = 1)]
    pub waypoints: Vec<PointRequest>,
    /// Cruise speed, m/s, above 0 and at most the slowest vehicle model's limit; default 5.
    #[schema(exclusive_minimum = 0.0)]
    pub speed_m_s: Option<f64>,
    /// Start again from the first point after the last; default false.
    pub repeat: Option<bool>,
}

/// `POST …/leader/orbit`: circle a centre.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct LeaderOrbitRequest {
    /// Centre, swarm-frame north, metres.
    pub north_m: f64,
    /// Centre, swarm-frame east, metres.
    pub east_m: f64,
    /// Centre, swarm-frame down, metres; default: the formation's altitude.
    pub down_m: Option<f64>,
    /// Orbit radius, metres, at least the minimum separation plus its margin.
    #[schema(exclusive_minimum = 0.0)]
    pub radius_m: f64,
    /// Speed along the circle, m/s, above 0 and at most the slowest vehicle model's
    /// limit; default 5.
    #[schema(exclusive_minimum = 0.0)]
    pub speed_m_s: Option<f64>,
    /// Clockwise seen from above; default true.
    pub clockwise: Option<bool>,
}

/// `POST …/leader/hold`: stay where it is (empty body or `{}`).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct LeaderHoldRequest {}

fn speed(s: Option<f64>) -> f64 {
    s.unwrap_or(DEFAULT_LEADER_SPEED_M_S)
}

/// Parses `POST …/leader/goto`.
///
/// # Errors
/// 400 naming the field path.
pub fn goto(body: &[u8]) -> Result<LeaderMotion, ApiError> {
    let r: LeaderGoToRequest = parse_or_empty(body)?;
    Ok(LeaderMotion::GoTo {
        target: PointRequest {
            north_m: r.north_m,
            east_m: r.east_m,
            down_m: r.down_m,
        }
        .ned(),
        speed_m_s: speed(r.speed_m_s),
    })
}

/// Parses `POST …/leader/waypoints`.
///
/// # Errors
/// 400 naming the field path.
pub fn waypoints(body: &[u8]) -> Result<LeaderMotion, ApiError> {
    let r: LeaderWaypointsRequest = parse_or_empty(body)?;
    Ok(LeaderMotion::Waypoints {
        points: r.waypoints.into_iter().map(PointRequest::ned).collect(),
        speed_m_s: speed(r.speed_m_s),
        next: 0,
        repeat: r.repeat.unwrap_or(false),
    })
}

/// Parses `POST …/leader/orbit`.
///
/// # Errors
/// 400 naming the field path.
pub fn orbit(body: &[u8]) -> Result<LeaderMotion, ApiError> {
    let r: LeaderOrbitRequest = parse_or_empty(body)?;
    Ok(LeaderMotion::Orbit {
        centre: PointRequest {
            north_m: r.north_m,
            east_m: r.east_m,
            down_m: r.down_m,
        }
        .ned(),
        radius_m: r.radius_m,
        speed_m_s: speed(r.speed_m_s),
        clockwise: r.clockwise.unwrap_or(true),
    })
}

/// Parses `POST …/leader/hold` (an empty body or `{}`).
///
/// # Errors
/// 400 naming an unknown field.
pub fn hold(body: &[u8]) -> Result<LeaderMotion, ApiError> {
    let LeaderHoldRequest {} = parse_or_empty(body)?;
    Ok(LeaderMotion::Hold)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn field_of(r: Result<impl std::fmt::Debug, ApiError>) -> String {
        r.unwrap_err().field.unwrap_or_default()
    }

    #[test]
    fn leader_motions_parse_and_errors_name_the_field() {
        let g = goto(br#"{"north_m":10,"east_m":5,"speed_m_s":3}"#).unwrap();
        let LeaderMotion::GoTo { target, speed_m_s } = g else {
            panic!()
        };
        assert_eq!((target.north_m, target.east_m, speed_m_s), (10.0, 5.0, 3.0));
        assert!(target.down_m.is_nan(), "altitude left to the formation");
        assert_eq!(field_of(goto(br#"{"north_m":10}"#)), "east_m");
        let w = waypoints(br#"{"waypoints":[{"north_m":1,"east_m":2},{"north_m":3,"east_m":4,"down_m":-12}],"repeat":true}"#).unwrap();
        assert!(
            matches!(w, LeaderMotion::Waypoints { ref points, repeat: true, .. } if points.len() == 2)
        );
        assert_eq!(
            field_of(waypoints(br#"{"waypoints":[{"north_m":1}]}"#)),
            "waypoints[0].east_m"
        );
        assert_eq!(field_of(waypoints(br#"{}"#)), "waypoints");
        let o = orbit(br#"{"north_m":0,"east_m":0,"radius_m":20,"clockwise":false}"#).unwrap();
        assert!(
            matches!(o, LeaderMotion::Orbit { radius_m, clockwise: false, .. } if radius_m == 20.0)
        );
        assert_eq!(field_of(orbit(br#"{"north_m":0,"east_m":0}"#)), "radius_m");
        assert_eq!(hold(b"").unwrap(), LeaderMotion::Hold);
        assert_eq!(hold(b"{}").unwrap(), LeaderMotion::Hold);
        assert_eq!(field_of(hold(br#"{"speed_m_s":1}"#)), "speed_m_s");
    }
}
