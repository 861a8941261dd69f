//! The camera plugin: JPEG frames of the configured size, and aircraft drawn where a pinhole
//! camera at the vehicle's pose, aimed by the gimbal's published angles, sees them.

use crate::spec;
use crate::support::*;
use serde_json::{Value, json};
use skein_plugin_host::{Isolation, PayloadDriver, PayloadFactory, PluginManager};
use std::sync::Arc;

/// Decodes a JPEG: `(width, height, rgb pixels)`.
fn decode(jpeg: &[u8]) -> (u32, u32, Vec<u8>) {
    let mut d = jpeg_decoder::Decoder::new(jpeg);
    let pixels = d.decode().expect("a valid JPEG");
    let info = d.info().unwrap();
    assert_eq!(info.pixel_format, jpeg_decoder::PixelFormat::RGB24);
    (u32::from(info.width), u32::from(info.height), pixels)
}

/// Pixels that differ clearly between two frames (JPEG noise stays well below 60).
fn changed_pixels(a: &[u8], b: &[u8], width: u32) -> Vec<(f64, f64)> {
    a.chunks(3)
        .zip(b.chunks(3))
        .enumerate()
        .filter(|(_, (p, q))| {
            p.iter()
                .zip(q.iter())
                .map(|(x, y)| (i32::from(*x) - i32::from(*y)).abs())
                .sum::<i32>()
                > 60
        })
        .map(|(i, _)| {
            (
                (i as u32 % width) as f64 + 0.5,
                (i as u32 / width) as f64 + 0.5,
            )
        })
        .collect()
}

const CONFIG: fn() -> Value = || {
    json!({"width_px": 320, "height_px": 240, "focal_length_mm": 4.0, "focal_min_mm": 2.0,
           "sensor_width_mm": 6.4, "frame_rate_hz": 0, "jpeg_quality": 90})
};

struct Rig {
    world: Arc<World>,
    camera: Box<dyn PayloadDriver>,
}

impl Rig {
    fn new(m: &PluginManager, isolation: Isolation, config: Value) -> Rig {
        let world = World::new(true);
        world.put("uav-1", 1, (0.0, 0.0, -20.0), 0.0);
        let camera = m
            .create(
                &spec("camera", "camera", isolation, config),
                world.host("uav-1", "camera"),
            )
            .unwrap();
        Rig { world, camera }
    }

    fn gimbal(&self, pitch_deg: f64, yaw_deg: f64) {
        self.world.set_state(
            "uav-1",
            "gimbal",
            json!({"pitch_deg": pitch_deg, "yaw_deg": yaw_deg}),
        );
    }

    /// Captures one frame: the reply and the decoded frame. With `SKEIN_DUMP_FRAMES=<dir>`
    /// the JPEGs are also written there, to look at.
    fn capture(&mut self) -> (Value, (u32, u32, Vec<u8>)) {
        let reply = self.camera.handle(json!({"command": "capture"})).unwrap();
        let jpeg = self.world.frames("uav-1").pop().expect("a published frame");
        if let Ok(dir) = std::env::var("SKEIN_DUMP_FRAMES") {
            static N: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
            let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            std::fs::write(format!("{dir}/frame-{n:03}.jpg"), &jpeg).unwrap();
        }
        assert_eq!(reply["bytes"].as_u64().unwrap() as usize, jpeg.len());
        (reply, decode(&jpeg))
    }

    /// The pixels an aircraft changed: frames with and without `uav-2` at `ned`.
    fn aircraft_pixels(&mut self, ned: (f64, f64, f64)) -> (Value, Vec<(f64, f64)>) {
        self.world
            .vehicles
            .lock()
            .unwrap()
            .retain(|v| v.id != "uav-2");
        let (_, (w, _, empty)) = self.capture();
        self.world.put("uav-2", 2, ned, 0.0);
        let (reply, (_, _, with)) = self.capture();
        (reply, changed_pixels(&empty, &with, w))
    }
}

fn centroid(px: &[(f64, f64)]) -> (f64, f64) {
    let n = px.len() as f64;
    (
        px.iter().map(|p| p.0).sum::<f64>() / n,
        px.iter().map(|p| p.1).sum::<f64>() / n,
    )
}

#[test]
fn snapshot_is_a_jpeg_of_the_configured_size() {
    let m = manager_with(&["skein-plugin-camera"]);
    for (isolation, w, h) in [
        (Isolation::InProcess, 320, 240),
        (Isolation::Process, 200, 150),
    ] {
        let mut cfg = CONFIG();
        cfg["width_px"] = json!(w);
        cfg["height_px"] = json!(h);
        cfg["frame_rate_hz"] = json!(5);
        let mut rig = Rig::new(&m, isolation, cfg);
        assert_eq!(rig.camera.tick_rate_hz(), 5.0);
        let (reply, (dw, dh, pixels)) = rig.capture();
        assert_eq!((dw, dh), (w, h), "{isolation:?}");
        assert_eq!(pixels.len(), (w * h * 3) as usize);
        assert_eq!(reply["frame"], 1);
        // The tick streams frames too, and publishes the camera's state.
        rig.camera.tick(0.2).unwrap();
        assert_eq!(rig.world.frames("uav-1").len(), 2);
        let state = rig.world.state("uav-1", "camera").unwrap();
        assert_eq!(state["frames"], 2);
        assert_eq!(state["width_px"], w);
        assert_eq!(state["source"], "simulated");
        // No gimbal state published: the fixed mount (level, forward) aims it.
        assert_eq!(state["pointing"]["from"], "mount");
        // Level camera: sky at the top, ground at the bottom.
        let (_, (_, _, px)) = rig.capture();
        let at = |x: u32, y: u32| {
            let i = ((y * w + x) * 3) as usize;
            (px[i], px[i + 1], px[i + 2])
        };
        let (r, g, b) = at(w / 2, 2);
        assert!(b > r && b > g, "top should be sky: {:?}", (r, g, b));
        let (r, g, b) = at(w / 2, h - 3);
        assert!(g > r && g > b, "bottom should be ground: {:?}", (r, g, b));
    }
}

#[test]
fn another_vehicle_appears_at_its_projected_position_and_not_when_looking_away() {
    let m = manager_with(&["skein-plugin-camera"]);
    for isolation in [Isolation::InProcess, Isolation::Process] {
        let mut rig = Rig::new(&m, isolation, CONFIG());
        rig.gimbal(0.0, 0.0);
        // uav-2: 40 m north (ahead), 5 m east (right), 2 m higher. Pinhole with f = 4 mm on
        // a 6.4 mm wide sensor over 320 px: f = 200 px; principal point (160, 120).
        let target = (40.0, 5.0, -22.0);
        let (u, v) = (160.0 + 200.0 * 5.0 / 40.0, 120.0 - 200.0 * 2.0 / 40.0);
        let (reply, changed) = rig.aircraft_pixels(target);
        assert!(
            changed.len() >= 10,
            "{isolation:?}: only {} changed pixels",
            changed.len()
        );
        let (cx, cy) = centroid(&changed);
        assert!(
            (cx - u).abs() < 2.0 && (cy - v).abs() < 2.0,
            "{isolation:?}: centroid ({cx:.1}, {cy:.1}) vs ({u}, {v})"
        );
        assert!(
            changed.iter().all(|(x, y)| (x - u).hypot(y - v) < 16.0),
            "stray pixels"
        );
        let visible = reply["visible"].as_array().unwrap();
        assert_eq!(visible.len(), 1);
        assert_eq!(visible[0]["id"], "uav-2");
        assert!((visible[0]["x_px"].as_f64().unwrap() - u).abs() < 1e-6);
        assert!((visible[0]["y_px"].as_f64().unwrap() - v).abs() < 1e-6);
        assert_eq!(reply["pointing"]["from"], "gimbal");

        // The gimbal turned the other way: nothing of it in the frame.
        rig.gimbal(0.0, 180.0);
        let (reply, changed) = rig.aircraft_pixels(target);
        assert!(
            changed.is_empty(),
            "{isolation:?}: {} pixels changed looking away",
            changed.len()
        );
        assert!(reply["visible"].as_array().unwrap().is_empty());

        // Turning the vehicle instead (heading 90°, gimbal yaw -90°) looks north again.
        rig.gimbal(0.0, -90.0);
        rig.world.put("uav-1", 1, (0.0, 0.0, -20.0), 90.0);
        let (_, changed) = rig.aircraft_pixels(target);
        let (cx, cy) = centroid(&changed);
        assert!((cx - u).abs() < 2.0 && (cy - v).abs() < 2.0, "({cx}, {cy})");
        rig.world.put("uav-1", 1, (0.0, 0.0, -20.0), 0.0);
    }
}

#[test]
fn zoom_scales_the_image_about_its_centre() {
    let m = manager_with(&["skein-plugin-camera"]);
    let mut rig = Rig::new(&m, Isolation::InProcess, CONFIG());
    rig.gimbal(-10.0, 0.0);
    rig.world.put("uav-2", 2, (60.0, -6.0, -12.0), 0.0);
    let x_offset = |rig: &mut Rig| {
        let (reply, _) = rig.capture();
        let v = &reply["visible"][0];
        (
            v["x_px"].as_f64().unwrap() - 160.0,
            v["y_px"].as_f64().unwrap() - 120.0,
        )
    };
    let (x1, y1) = x_offset(&mut rig);
    let s = rig
        .camera
        .handle(json!({"command": "set_focal_length", "focal_length_mm": 8.0}))
        .unwrap();
    assert_eq!(s["zoom"], 4.0);
    let (x2, y2) = x_offset(&mut rig);
    assert!(
        (x2 - 2.0 * x1).abs() < 1e-6 && (y2 - 2.0 * y1).abs() < 1e-6,
        "({x1}, {y1}) → ({x2}, {y2})"
    );
    let e = rig
        .camera
        .handle(json!({"command": "set_focal_length", "focal_length_mm": 1.0}))
        .unwrap_err();
    assert_eq!(e, "focal_length_mm: 1 is outside [2, 48]");
    let s = rig
        .camera
        .handle(json!({"command": "set_zoom", "zoom": 3.0}))
        .unwrap();
    assert_eq!(s["focal_length_mm"], 6.0);
}
