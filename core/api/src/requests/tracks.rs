//! `POST /api/v1/tracks/{id}/observe`, `POST /api/v1/swarms/{id}/observe`.

use serde::Deserialize;
use utoipa::ToSchema;

/// Which observation UAVs keep the track or swarm in view (an empty body: every vehicle
/// with a gimbal), and whether they fly to stations.
#[derive(Debug, Clone, PartialEq, Default, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ObserveRequest {
    /// Vehicle ids; absent or null: every vehicle with a gimbal.
    pub vehicles: Option<Vec<String>>,
    /// Also fly them to the stations that fix the target best (two at least, airborne),
    /// re-planned as it moves; absent: `false` for a track (the gimbals only), `true` for
    /// a swarm.
    pub stations: Option<bool>,
    /// The stations' least horizontal distance from the target, metres (10–60; absent:
    /// 25).
    #[schema(minimum = 10.0, maximum = 60.0)]
    pub standoff_m: Option<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::requests::parse_or_empty;

    #[test]
    fn observe_bodies_parse_and_errors_name_the_field() {
        let all: ObserveRequest = parse_or_empty(b"").unwrap();
        assert_eq!(all.vehicles, None);
        let some: ObserveRequest = parse_or_empty(br#"{"vehicles":["uav-2"]}"#).unwrap();
        assert_eq!(some.vehicles, Some(vec!["uav-2".to_string()]));
        let e = parse_or_empty::<ObserveRequest>(br#"{"vehicles":"uav-2"}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("vehicles"));
        let e = parse_or_empty::<ObserveRequest>(br#"{"vehicle":["uav-2"]}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("vehicle"));
        let st: ObserveRequest = parse_or_empty(br#"{"stations":true,"standoff_m":30}"#).unwrap();
        assert_eq!((st.stations, st.standoff_m), (Some(true), Some(30.0)));
        let e = parse_or_empty::<ObserveRequest>(br#"{"stations":"yes"}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("stations"));
    }
}
