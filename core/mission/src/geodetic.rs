//! Plan positions written as latitude/longitude: where a plan gives a point as
//! `{"lat_deg": 47.397, "lon_deg": 8.546}` (WGS-84 degrees, as a map or a survey file
//! gives it) instead of a swarm-frame `[north_m, east_m]` pair, it is put into the swarm
//! frame (the tangent plane at the swarm origin) before the plan is read, so a stored
//! plan, its validation and its flight all work in the one frame the geofence and the
//! formations use.
//!
//! Points are looked for where a plan has them: `steps[i].waypoints`, `.polygon`,
//! `.route`, `.points`, and `reactions.intruder.zone`.

use crate::validate::PlanError;
use serde_json::{Map, Value};
use skein_model::geo::{GeoPoint, NedFrame};

/// The step fields that hold lists of points.
const STEP_POINT_LISTS: [&str; 4] = ["waypoints", "polygon", "route", "points"];

/// Replaces each latitude/longitude point of `plan` (a plan as a JSON object, before it
/// is parsed) with its `[north_m, east_m]` in `frame` (the swarm frame). Returns how many
/// points were converted; a plan with none is left as it is.
///
/// # Errors
/// The point's field (`steps[1].polygon[2]`): a latitude outside ±90° or a longitude
/// outside ±180°, a point object with other keys, or (with `frame` `None`) a
/// latitude/longitude point while the swarm frame is not anchored yet (no vehicle has
/// reported a home).
pub fn points_to_swarm_frame(
    plan: &mut Map<String, Value>,
    frame: Option<&NedFrame>,
) -> Result<usize, PlanError> {
    let mut converted = 0;
    if let Some(steps) = plan.get_mut("steps").and_then(Value::as_array_mut) {
        for (i, step) in steps.iter_mut().enumerate() {
            for key in STEP_POINT_LISTS {
                if let Some(list) = step.get_mut(key) {
                    converted += convert_list(list, &format!("steps[{i}].{key}"), frame)?;
                }
            }
        }
    }
    if let Some(zone) = plan
        .get_mut("reactions")
        .and_then(|r| r.pointer_mut("/intruder/zone"))
    {
        converted += convert_list(zone, "reactions.intruder.zone", frame)?;
    }
    Ok(converted)
}

/// Each latitude/longitude object of `list` converted in place (anything else is left
/// for the plan's own parser to accept or refuse).
fn convert_list(
    list: &mut Value,
    field: &str,
    frame: Option<&NedFrame>,
) -> Result<usize, PlanError> {
    let Some(items) = list.as_array_mut() else {
        return Ok(0);
    };
    let mut converted = 0;
    for (j, item) in items.iter_mut().enumerate() {
        if let Value::Object(point) = item {
            let field = format!("{field}[{j}]");
            let geo = geodetic(point, &field)?;
            let frame = frame.ok_or_else(|| {
                PlanError::new(
                    &field,
                    "a latitude/longitude point needs the swarm frame, which is anchored \
                     when the first vehicle reports its home: none has yet",
                )
            })?;
            let ned = frame.to_ned(&GeoPoint::new(geo.0, geo.1, frame.origin.alt_amsl_m));
            *item = serde_json::json!([round_mm(ned.north_m), round_mm(ned.east_m)]);
            converted += 1;
        }
    }
    Ok(converted)
}

/// `{"lat_deg", "lon_deg"}` as degrees, checked.
fn geodetic(point: &Map<String, Value>, field: &str) -> Result<(f64, f64), PlanError> {
    if let Some(k) = point.keys().find(|k| *k != "lat_deg" && *k != "lon_deg") {
        return Err(PlanError::new(
            field,
            format!("unknown key `{k}`: a point is [north_m, east_m] or {{lat_deg, lon_deg}}"),
        ));
    }
    let degrees = |key: &str, limit: f64| {
        point
            .get(key)
            .and_then(Value::as_f64)
            .filter(|d| d.abs() <= limit)
            .ok_or_else(|| {
                PlanError::new(
                    format!("{field}.{key}"),
                    format!("missing or not a number from -{limit} to {limit} degrees"),
                )
            })
    };
    Ok((degrees("lat_deg", 90.0)?, degrees("lon_deg", 180.0)?))
}

/// Metres to the millimetre: a converted plan reads as written by hand.
fn round_mm(m: f64) -> f64 {
    (m * 1000.0).round() / 1000.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn obj(v: &mut Value) -> &mut Map<String, Value> {
        v.as_object_mut().unwrap()
    }

    fn zurich() -> NedFrame {
        NedFrame::new(GeoPoint::new(47.397742, 8.545594, 488.0))
    }

    #[test]
    fn latitude_and_longitude_become_north_and_east_of_the_origin() {
        // 0.001° of latitude is 111.2 m north; 0.001° of longitude at 47.4° is 75.3 m.
        let mut plan = json!({"name": "geo", "steps": [
            {"kind": "transit", "waypoints": [[5, 5],
                {"lat_deg": 47.398742, "lon_deg": 8.546594}], "altitude_m": 10, "speed_m_s": 3},
            {"kind": "land"}],
            "reactions": {"intruder": {"zone": [{"lat_deg": 47.397742, "lon_deg": 8.545594},
                [0, 50], [50, 0]]}}});
        assert_eq!(
            points_to_swarm_frame(obj(&mut plan), Some(&zurich())),
            Ok(2)
        );
        let p = &plan["steps"][0]["waypoints"];
        assert_eq!(p[0], json!([5, 5]));
        let (n, e) = (p[1][0].as_f64().unwrap(), p[1][1].as_f64().unwrap());
        assert!((n - 111.2).abs() < 0.3 && (e - 75.3).abs() < 0.3, "{p}");
        assert_eq!(plan["reactions"]["intruder"]["zone"][0], json!([0.0, 0.0]));
        let parsed: crate::MissionPlan = serde_json::from_value(plan).unwrap();
        assert_eq!(parsed.steps.len(), 2);
    }

    #[test]
    fn bad_points_are_refused_naming_the_field() {
        for (point, field, says) in [
            (
                json!({"lat_deg": 91, "lon_deg": 8}),
                "steps[0].polygon[1].lat_deg",
                "-90 to 90",
            ),
            (
                json!({"lat_deg": 47}),
                "steps[0].polygon[1].lon_deg",
                "missing",
            ),
            (
                json!({"lat": 47, "lon_deg": 8}),
                "steps[0].polygon[1]",
                "unknown key `lat`",
            ),
        ] {
            let mut plan = json!({"steps": [{"kind": "survey", "polygon": [[0, 0], point]}]});
            let e = points_to_swarm_frame(obj(&mut plan), Some(&zurich())).unwrap_err();
            assert_eq!(
                (e.field.as_str(), e.error.contains(says)),
                (field, true),
                "{e:?}"
            );
        }
        let mut plan = json!({"steps": [{"kind": "station",
            "points": [{"lat_deg": 47.4, "lon_deg": 8.5}]}]});
        let e = points_to_swarm_frame(obj(&mut plan), None).unwrap_err();
        assert_eq!(e.field, "steps[0].points[0]");
        assert!(e.error.contains("anchored"), "{e:?}");
        let mut plain = json!({"steps": [{"kind": "station", "points": [[1, 2]]}]});
        assert_eq!(points_to_swarm_frame(obj(&mut plain), None), Ok(0));
    }
}
