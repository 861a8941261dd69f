//! `PUT /api/v1/formation`: the formation to fly. The bounds of spacing, altitude and
//! offsets are the schema's ([`Bounds`]): a formation wider than a kilometre is a typo
//! (and distances to slots at 1e300 m overflow).

use super::parse;
use super::schema_bounds::Bounds;
use crate::error::ApiError;
use serde::Deserialize;
use skein_model::formation::Shape;
use skein_model::geo::Ned;
use skein_swarm::FormationSpec;
use skein_swarm::formation::FormationFrame;
use utoipa::ToSchema;

/// A formation request; only `shape` is always required (`spacing_m` too, except for
/// `custom`).
#[derive(Debug, Clone, PartialEq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct FormationRequest {
    /// The shape (`GET /api/v1/formation/shapes` lists them with the fewest vehicles each
    /// needs).
    pub shape: Shape,
    /// Distance between neighbouring slots, metres, above 0 (at least √2 × (minimum
    /// separation + tracking margin), 4.95 m by default); required except for `custom`.
    #[schema(exclusive_minimum = 0.0, maximum = 1000.0)]
    pub spacing_m: Option<f64>,
    /// A vehicle id, `"virtual"` (a point the operator drives), or absent (the first
    /// member by id).
    pub leader: Option<String>,
    /// Formation heading, degrees clockwise from north (`world` frame); default 0.
    pub heading_deg: Option<f64>,
    /// Altitude above the swarm origin, metres, within ±10 000; default: the leader's.
    #[schema(minimum = -10000.0, maximum = 10000.0)]
    pub altitude_m: Option<f64>,
    /// `world` (fixed at `heading_deg`, the default) or `leader` (turns with the
    /// leader's heading).
    pub frame: Option<FormationFrame>,
    /// Follower offsets of a `custom` formation, in the leader's frame.
    pub offsets: Option<Vec<OffsetRequest>>,
    /// With a track as leader (`"leader": "track-7"`): the distance the formation keeps
    /// from the track, metres (required then; its range is checked by the coordinator,
    /// which names this field, within 5–500 m).
    #[schema(minimum = 5.0, maximum = 500.0)]
    pub standoff_m: Option<f64>,
}

/// One follower's place in a `custom` formation, relative to the leader: forward, right,
/// down, metres.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct OffsetRequest {
    /// Ahead of the leader, metres (negative: behind), within ±1000.
    #[schema(minimum = -1000.0, maximum = 1000.0)]
    pub forward_m: f64,
    /// Right of the leader, metres (negative: left), within ±1000.
    #[schema(minimum = -1000.0, maximum = 1000.0)]
    pub right_m: f64,
    /// Below the leader, metres (negative: above), within ±1000; default 0.
    #[schema(minimum = -1000.0, maximum = 1000.0)]
    pub down_m: Option<f64>,
}

impl FormationRequest {
    /// The spec the coordinator flies (it checks what depends on the swarm: spacing
    /// against the separation, the leader's id, enough vehicles).
    ///
    /// # Errors
    /// 400 naming `spacing_m` when it is missing or not above 0 for a shape other than
    /// `custom`, or above its maximum; `altitude_m` or `offsets[i].forward_m` (…) outside
    /// their bounds (all as the schema declares them).
    pub fn into_spec(self) -> Result<FormationSpec, ApiError> {
        let custom = self.shape == Shape::Custom;
        let spacing = Bounds::of::<FormationRequest>("spacing_m");
        if let Some(s) = self.spacing_m {
            // A custom formation has no spacing: only its upper bound applies.
            spacing.upper().check("spacing_m", s, "m")?;
        }
        if let Some(a) = self.altitude_m {
            Bounds::of::<FormationRequest>("altitude_m").check("altitude_m", a, "m")?;
        }
        for (i, o) in self.offsets.iter().flatten().enumerate() {
            let parts = [
                ("forward_m", o.forward_m),
                ("right_m", o.right_m),
                ("down_m", o.down_m.unwrap_or(0.0)),
            ];
            for (name, v) in parts {
                Bounds::of::<OffsetRequest>(name).check(&format!("offsets[{i}].{name}"), v, "m")?;
            }
        }
        let spacing_m = match (self.spacing_m, custom) {
            (Some(s), false) => {
                spacing.lower().check("spacing_m", s, "m")?;
                s
            }
            (Some(s), true) => s,
            (None, true) => 0.0,
            (None, false) => {
                return Err(ApiError::field(
                    "spacing_m",
                    "missing field `spacing_m` (distance between slots, metres)",
                ));
            }
        };
        Ok(FormationSpec {
            shape: self.shape,
            spacing_m,
            leader: self.leader,
            heading_deg: self.heading_deg.unwrap_or(0.0),
            altitude_m: self.altitude_m,
            frame: self.frame.unwrap_or_default(),
            offsets: self
                .offsets
                .unwrap_or_default()
                .into_iter()
                .map(|o| Ned::new(o.forward_m, o.right_m, o.down_m.unwrap_or(0.0)))
                .collect(),
            standoff_m: self.standoff_m,
        })
    }
}

/// Parses and checks a `PUT /api/v1/formation` body.
///
/// # Errors
/// 400 naming the field path (see [`super::parse`], [`FormationRequest::into_spec`]).
pub fn formation(body: &[u8]) -> Result<FormationSpec, ApiError> {
    parse::<FormationRequest>(body)?.into_spec()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_contract_states_the_coordinators_standoff_range() {
        let (lo, hi) = skein_swarm::coordinator::track_leader::STANDOFF_RANGE_M;
        let b = Bounds::of::<FormationRequest>("standoff_m");
        assert_eq!((b.minimum, b.maximum), (Some(lo), Some(hi)));
    }

    fn field_of(r: Result<impl std::fmt::Debug, ApiError>) -> String {
        r.unwrap_err().field.unwrap_or_default()
    }

    #[test]
    fn formation_parses_and_errors_name_the_field() {
        let f = formation(br#"{"shape":"line","spacing_m":5,"leader":"uav-1"}"#).unwrap();
        assert_eq!(f.shape, Shape::Line);
        assert_eq!(f.spacing_m, 5.0);
        assert_eq!(f.leader.as_deref(), Some("uav-1"));
        assert_eq!(field_of(formation(br#"{"spacing_m":5}"#)), "shape");
        let f =
            formation(br#"{"shape":"wedge","spacing_m":4,"leader":"virtual","frame":"leader"}"#)
                .unwrap();
        assert_eq!(
            (f.shape, f.frame, f.leader.as_deref()),
            (Shape::Wedge, FormationFrame::Leader, Some("virtual"))
        );
        let f =
            formation(br#"{"shape":"custom","offsets":[{"forward_m":-4,"right_m":3}]}"#).unwrap();
        assert_eq!(f.offsets, vec![Ned::new(-4.0, 3.0, 0.0)]);
        assert_eq!(
            field_of(formation(
                br#"{"shape":"custom","offsets":[{"forward_m":-4}]}"#
            )),
            "offsets[0].right_m"
        );
        assert_eq!(
            field_of(formation(
                br#"{"shape":"custom","offsets":[{"forward_m":-4,"right_m":3},{"forward_m":-4,"right_m":"x"}]}"#
            )),
            "offsets[1].right_m"
        );
        assert_eq!(
            field_of(formation(
                br#"{"shape":"custom","offsets":[{"north_m":-4,"right_m":3}]}"#
            )),
            "offsets[0].north_m"
        );
        assert_eq!(
            field_of(formation(
                br#"{"shape":"line","spacing_m":5,"frame":"body"}"#
            )),
            "frame"
        );
        let e = formation(br#"{"shape":"hexagon","spacing_m":5}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("shape"));
        assert!(e.error.contains("hexagon"));
        assert_eq!(field_of(formation(br#"{"shape":"line"}"#)), "spacing_m");
        assert_eq!(
            field_of(formation(br#"{"shape":"line","spacing_m":-1}"#)),
            "spacing_m"
        );
        assert_eq!(
            field_of(formation(br#"{"shape":"line","spacing_m":5,"spacing":3}"#)),
            "spacing"
        );
        // Found by schemathesis: slots at 1e303 m made the status's distances overflow.
        assert_eq!(
            field_of(formation(br#"{"shape":"line","spacing_m":5.7e303}"#)),
            "spacing_m"
        );
        assert_eq!(
            field_of(formation(
                br#"{"shape":"line","spacing_m":5,"altitude_m":-1e20}"#
            )),
            "altitude_m"
        );
        assert_eq!(
            field_of(formation(
                br#"{"shape":"custom","offsets":[{"forward_m":1,"right_m":3},{"forward_m":1,"right_m":3,"down_m":2e9}]}"#
            )),
            "offsets[1].down_m"
        );
    }
}
