//! The detector plugin's detections as the tracker reads them.
//!
//! The detector publishes each processed frame's detections in its payload state (see
//! `plugins/detector`): `last` (the newest frame) and `recent` (the frames of the last
//! half second, oldest first), so the tracker, which reads the states at
//! each of its steps, gets every frame however the rates fall. One frame:
//! `{"frame": 12, "stamp_us": 1700000000000000, "camera_slot": "camera",
//!   "observer": {"north_m": 0.0, "east_m": 5.0, "down_m": -10.0},
//!   "detections": [{"box_px": {"x": 311, "y": 200, "width": 7, "height": 6},
//!                   "azimuth_deg": 12.5, "elevation_deg": 4.1,
//!                   "angular_size_deg": 0.9, "confidence": 0.8}]}`
//! Bearings are in the swarm frame (azimuth clockwise from north, elevation above the
//! horizontal); `observer` is the camera's position when the frame was taken.

use super::geometry::{Ray, bearing_dir};
use nalgebra::Vector3;
use serde::Deserialize;

/// Payload kind of the detector plugin, whose states the tracker reads.
pub const DETECTOR_KIND: &str = "detector";

/// The frames of a detector's `state` newer than frame `after` (every frame when `None`),
/// oldest first: its `recent` frames, or its `last` one when it keeps no `recent` list. A
/// newest frame numbered below `after` means the camera started counting again: all of
/// them are new.
pub fn new_frames(state: &serde_json::Value, after: Option<u64>) -> Vec<&serde_json::Value> {
    let frames: Vec<&serde_json::Value> = match state["recent"].as_array() {
        Some(list) => list.iter().collect(),
        None if state["last"].is_object() => vec![&state["last"]],
        None => Vec::new(),
    };
    let newest = frames.iter().filter_map(|f| f["frame"].as_u64()).max();
    let after = match (after, newest) {
        (Some(a), Some(n)) if n >= a => Some(a),
        _ => None,
    };
    frames
        .into_iter()
        .filter(|f| {
            f["frame"]
                .as_u64()
                .is_some_and(|n| after.is_none_or(|a| n > a))
        })
        .collect()
}

/// Span the tracker assumes for a range from apparent size, metres (small multicopters).
pub const NOMINAL_SPAN_M: f64 = 0.8;

#[derive(Debug, Deserialize)]
struct Observer {
    north_m: f64,
    east_m: f64,
    down_m: f64,
}

#[derive(Debug, Deserialize)]
struct Detection {
    azimuth_deg: f64,
    elevation_deg: f64,
    #[serde(default)]
    angular_size_deg: Option<f64>,
    #[serde(default)]
    confidence: f64,
}

#[derive(Debug, Deserialize)]
struct DetectionsEvent {
    stamp_us: u64,
    observer: Observer,
    detections: Vec<Detection>,
}

/// The bearings of one frame's detections of vehicle `observer_id`.
///
/// # Errors
/// A frame of another shape (named by serde), or a non-finite value.
pub fn parse_detections(observer_id: &str, data: &serde_json::Value) -> Result<Vec<Ray>, String> {
    let ev: DetectionsEvent =
        serde_json::from_value(data.clone()).map_err(|e| format!("detector frame: {e}"))?;
    let origin = Vector3::new(ev.observer.north_m, ev.observer.east_m, ev.observer.down_m);
    if !origin.iter().all(|v| v.is_finite()) {
        return Err("detector frame: observer position is not finite".into());
    }
    ev.detections
        .into_iter()
        .map(|d| {
            if !(d.azimuth_deg.is_finite() && d.elevation_deg.is_finite()) {
                return Err("detector frame: bearing is not finite".to_string());
            }
            let range_from_size_m = d
                .angular_size_deg
                .filter(|a| a.is_finite() && *a > 0.0)
                .map(|a| NOMINAL_SPAN_M / (2.0 * (a.to_radians() / 2.0).tan()));
            Ok(Ray {
                origin,
                dir: bearing_dir(d.azimuth_deg, d.elevation_deg),
                range_from_size_m,
                stamp_us: ev.stamp_us,
                observer: observer_id.to_string(),
                confidence: d.confidence.clamp(0.0, 1.0),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_detector_event() {
        let data = serde_json::json!({
            "frame": 3, "stamp_us": 42, "camera_slot": "camera",
            "observer": {"north_m": 1.0, "east_m": 2.0, "down_m": -10.0},
            "detections": [{"box_px": {"x": 1, "y": 2, "width": 3, "height": 3},
                "azimuth_deg": 90.0, "elevation_deg": 0.0, "angular_size_deg": 0.8, "confidence": 0.7}]
        });
        let rays = parse_detections("uav-2", &data).unwrap();
        assert_eq!(rays.len(), 1);
        assert!((rays[0].dir - Vector3::new(0.0, 1.0, 0.0)).norm() < 1e-12);
        let r = rays[0].range_from_size_m.unwrap();
        assert!((r - 57.3).abs() < 0.1, "{r}");
        assert_eq!(rays[0].stamp_us, 42);
        let err = parse_detections("uav-2", &serde_json::json!({"stamp_us": 1})).unwrap_err();
        assert!(err.contains("observer"), "{err}");
    }

    #[test]
    fn new_frames_are_the_recent_ones_after_the_last_seen() {
        let f = |n: u64| serde_json::json!({"frame": n, "stamp_us": n, "detections": []});
        let state = serde_json::json!({"last": f(7), "recent": [f(5), f(6), f(7)]});
        let numbers = |after| -> Vec<u64> {
            new_frames(&state, after)
                .iter()
                .map(|v| v["frame"].as_u64().unwrap())
                .collect()
        };
        assert_eq!(numbers(None), [5, 6, 7]);
        assert_eq!(numbers(Some(5)), [6, 7]);
        assert!(numbers(Some(7)).is_empty());
        // The camera counts from 0 again (restarted): all are new.
        assert_eq!(numbers(Some(900)), [5, 6, 7]);
        // Without `recent`, `last`.
        let only_last = serde_json::json!({"last": f(3)});
        assert_eq!(new_frames(&only_last, Some(2)).len(), 1);
        assert!(new_frames(&serde_json::json!({"last": null}), None).is_empty());
    }
}
