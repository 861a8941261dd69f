//! The detector plugin's `detections` payload events as the tracker reads them.
//!
//! Shape (one event per processed frame, see `plugins/detector`):
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

/// Payload event kind the detector raises per frame.
pub const DETECTIONS_EVENT: &str = "detections";

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

/// The bearings of one `detections` event of vehicle `observer_id`.
///
/// # Errors
/// An event of another shape (named by serde), or a non-finite value.
pub fn parse_detections(observer_id: &str, data: &serde_json::Value) -> Result<Vec<Ray>, String> {
    let ev: DetectionsEvent =
        serde_json::from_value(data.clone()).map_err(|e| format!("detections event: {e}"))?;
    let origin = Vector3::new(ev.observer.north_m, ev.observer.east_m, ev.observer.down_m);
    if !origin.iter().all(|v| v.is_finite()) {
        return Err("detections event: observer position is not finite".into());
    }
    ev.detections
        .into_iter()
        .map(|d| {
            if !(d.azimuth_deg.is_finite() && d.elevation_deg.is_finite()) {
                return Err("detections event: bearing is not finite".to_string());
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
}
