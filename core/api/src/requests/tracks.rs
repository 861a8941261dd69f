//! `POST /api/v1/tracks/{id}/observe`.

use serde::Deserialize;
use utoipa::ToSchema;

/// Which observation UAVs keep the track in view (an empty body: every vehicle with a
/// gimbal).
#[derive(Debug, Clone, PartialEq, Default, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ObserveRequest {
    /// Vehicle ids; absent or null: every vehicle with a gimbal.
    pub vehicles: Option<Vec<String>>,
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
    }
}
