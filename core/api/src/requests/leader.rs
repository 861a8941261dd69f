//! Leader motion: `POST /api/v1/formation/leader/{goto,waypoints,orbit,hold}`, moving the
//! formation's reference point (the virtual leader, or a leader vehicle).

use super::parse_or_empty;
use crate::error::ApiError;
use serde::Deserialize;
use skein_model::geo::Ned;
use skein_swarm::formation::LeaderMotion;
use utoipa::ToSchema;

/// Default speed of leader motions, m/s.
pub const DEFAULT_LEADER_SPEED_M_S: f64 = 5.0;

/// The leader commands, as in the path.
pub const LEADER_COMMANDS: [&str; 4] = ["goto", "waypoints", "orbit", "hold"];

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
    /// Cruise speed, m/s; default 5.
    pub speed_m_s: Option<f64>,
}

/// `POST …/leader/waypoints`: fly a list of points in order.
#[derive(Debug, Clone, PartialEq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct LeaderWaypointsRequest {
    /// The points, in order.
    pub waypoints: Vec<PointRequest>,
    /// Cruise speed, m/s; default 5.
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
    /// Orbit radius, metres.
    pub radius_m: f64,
    /// Speed along the circle, m/s; default 5.
    pub speed_m_s: Option<f64>,
    /// Clockwise seen from above; default true.
    pub clockwise: Option<bool>,
}

/// `POST …/leader/hold`: stay where it is (empty body or `{}`).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct LeaderHoldRequest {}

/// Parses the body of leader command `kind` (an empty body reads as `{}`).
///
/// # Errors
/// 404 for an unknown `kind`; 400 naming the field path.
pub fn leader_motion(kind: &str, body: &[u8]) -> Result<LeaderMotion, ApiError> {
    let speed = |s: Option<f64>| s.unwrap_or(DEFAULT_LEADER_SPEED_M_S);
    Ok(match kind {
        "goto" => {
            let r: LeaderGoToRequest = parse_or_empty(body)?;
            LeaderMotion::GoTo {
                target: PointRequest {
                    north_m: r.north_m,
                    east_m: r.east_m,
                    down_m: r.down_m,
                }
                .ned(),
                speed_m_s: speed(r.speed_m_s),
            }
        }
        "waypoints" => {
            let r: LeaderWaypointsRequest = parse_or_empty(body)?;
            LeaderMotion::Waypoints {
                points: r.waypoints.into_iter().map(PointRequest::ned).collect(),
                speed_m_s: speed(r.speed_m_s),
                next: 0,
                repeat: r.repeat.unwrap_or(false),
            }
        }
        "orbit" => {
            let r: LeaderOrbitRequest = parse_or_empty(body)?;
            LeaderMotion::Orbit {
                centre: PointRequest {
                    north_m: r.north_m,
                    east_m: r.east_m,
                    down_m: r.down_m,
                }
                .ned(),
                radius_m: r.radius_m,
                speed_m_s: speed(r.speed_m_s),
                clockwise: r.clockwise.unwrap_or(true),
            }
        }
        "hold" => {
            let LeaderHoldRequest {} = parse_or_empty(body)?;
            LeaderMotion::Hold
        }
        other => {
            return Err(ApiError::not_found(format!(
                "no leader command `{other}` ({})",
                LEADER_COMMANDS.join(", ")
            )));
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn field_of(r: Result<impl std::fmt::Debug, ApiError>) -> String {
        r.unwrap_err().field.unwrap_or_default()
    }

    #[test]
    fn leader_motions_parse_and_errors_name_the_field() {
        let g = leader_motion("goto", br#"{"north_m":10,"east_m":5,"speed_m_s":3}"#).unwrap();
        let LeaderMotion::GoTo { target, speed_m_s } = g else {
            panic!()
        };
        assert_eq!((target.north_m, target.east_m, speed_m_s), (10.0, 5.0, 3.0));
        assert!(target.down_m.is_nan(), "altitude left to the formation");
        assert_eq!(
            field_of(leader_motion("goto", br#"{"north_m":10}"#)),
            "east_m"
        );
        let w = leader_motion("waypoints", br#"{"waypoints":[{"north_m":1,"east_m":2},{"north_m":3,"east_m":4,"down_m":-12}],"repeat":true}"#).unwrap();
        assert!(
            matches!(w, LeaderMotion::Waypoints { ref points, repeat: true, .. } if points.len() == 2)
        );
        assert_eq!(
            field_of(leader_motion(
                "waypoints",
                br#"{"waypoints":[{"north_m":1}]}"#
            )),
            "waypoints[0].east_m"
        );
        assert_eq!(field_of(leader_motion("waypoints", br#"{}"#)), "waypoints");
        let o = leader_motion(
            "orbit",
            br#"{"north_m":0,"east_m":0,"radius_m":20,"clockwise":false}"#,
        )
        .unwrap();
        assert!(
            matches!(o, LeaderMotion::Orbit { radius_m, clockwise: false, .. } if radius_m == 20.0)
        );
        assert_eq!(
            field_of(leader_motion("orbit", br#"{"north_m":0,"east_m":0}"#)),
            "radius_m"
        );
        assert_eq!(leader_motion("hold", b"").unwrap(), LeaderMotion::Hold);
        assert_eq!(leader_motion("hold", b"{}").unwrap(), LeaderMotion::Hold);
        assert_eq!(
            field_of(leader_motion("hold", br#"{"speed_m_s":1}"#)),
            "speed_m_s"
        );
        assert_eq!(
            leader_motion("spin", b"").unwrap_err().status,
            axum::http::StatusCode::NOT_FOUND
        );
    }
}
