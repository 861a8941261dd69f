//! Helpers of the video tests (`e2e_video`, `e2e_video_sources`): uav-1's cameras and
//! detectors as the HTTP API shows them, the intruder on the simulated render, and the
//! dashboard's camera card.

use super::payloads::{payload, write_config};
use super::{Skein, eventually, run_peer};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The simulator's render of its intruder and what the detector found on it.
pub struct Render {
    /// The intruder's x in the render, pixels.
    pub truth_x: f64,
    /// The frame (JPEG).
    pub jpeg: Vec<u8>,
    /// The frame, written as `render.jpg` in the test's directory.
    pub image: PathBuf,
    /// The detection: center x, center y (pixels), azimuth, elevation (degrees).
    pub on_render: (f64, f64, f64, f64),
}

/// `skein up --sim 1` with `config` (written in `dir`, the plugins' directory) and one
/// intruder passing straight at 0.5 m/s; once uav-1's simulated `camera` and its
/// `detector` have the intruder ([`render_with_intruder`]), that render.
pub fn up_rendering_the_intruder(dir: &Path, config: &str) -> (Skein, Render) {
    let config = write_config(dir, config);
    let mut args = vec!["--config", &config, "--plugin-dir", dir.to_str().unwrap()];
    let pass = super::counter_uas::pass_args("straight", 1, 0.5);
    args.extend(pass.iter().map(String::as_str));
    let skein = Skein::up_sim(1, &args);
    let (truth_x, jpeg, on_render) = render_with_intruder(&skein, "camera", "detector");
    let image = dir.join("render.jpg");
    std::fs::write(&image, &jpeg).unwrap();
    let render = Render {
        truth_x,
        jpeg,
        image,
        on_render,
    };
    (skein, render)
}

/// The camera's state in `slot` of uav-1.
pub fn camera(skein: &Skein, slot: &str) -> Value {
    payload(skein, "uav-1", slot)["state"].clone()
}

/// Waits until `slot` streams and has published more than `frames` frames; its state.
pub fn streaming_past(skein: &Skein, slot: &str, frames: u64) -> Value {
    eventually(
        &format!("{slot} streaming past frame {frames}"),
        Duration::from_secs(40),
        || {
            let s = camera(skein, slot);
            let ok = s["source_status"]["state"] == "streaming"
                && s["frames"].as_u64().is_some_and(|f| f > frames);
            if ok { Ok(s) } else { Err(s.to_string()) }
        },
    )
}

/// The payload at `coordinator/uav-1/payload/SLOT` was never restarted, nor the vehicle.
pub fn never_restarted(skein: &Skein, slots: &[&str]) {
    for slot in slots {
        assert_eq!(
            skein.restarts(&format!("coordinator/uav-1/payload/{slot}")),
            0,
            "{slot}"
        );
    }
    assert_eq!(skein.restarts("coordinator/uav-1"), 0, "the vehicle");
}

/// The dashboard in headless Chromium shows uav-1's camera card in `slot` as `expect`
/// (`tests/peers/camera_selenium.py`).
pub fn dashboard_shows(skein: &Skein, slot: &str, expect: &str) {
    let url = format!("{}/", skein.base);
    let (code, out, err) = run_peer(
        "camera_selenium.py",
        &[
            "--url",
            &url,
            "--vehicle",
            "uav-1",
            "--slot",
            slot,
            "--expect",
            expect,
        ],
        Duration::from_secs(120),
    );
    assert_eq!(
        code,
        Some(0),
        "camera_selenium.py --expect {expect} (exit {code:?})\n--- stdout\n{out}\n--- stderr\n{err}"
    );
    eprintln!("dashboard: {}", out.trim());
}

/// The detection nearest `x_px` in the detector's last frame, as (center x, center y,
/// azimuth, elevation).
pub fn detection_near(state: &Value, x_px: f64) -> Option<(f64, f64, f64, f64)> {
    state["last"]["detections"]
        .as_array()?
        .iter()
        .map(|d| {
            (
                d["center_px"]["x"].as_f64().unwrap(),
                d["center_px"]["y"].as_f64().unwrap(),
                d["azimuth_deg"].as_f64().unwrap(),
                d["elevation_deg"].as_f64().unwrap(),
            )
        })
        .min_by(|a, b| (a.0 - x_px).abs().total_cmp(&(b.0 - x_px).abs()))
}

/// Captures frames of uav-1's simulated `camera` until one shows the simulator's intruder
/// and `detector` finds it there (within 6 px); returns the intruder's x in the render,
/// pixels, the frame (JPEG) and the detection (center x, center y, azimuth, elevation).
pub fn render_with_intruder(
    skein: &Skein,
    camera: &str,
    detector: &str,
) -> (f64, Vec<u8>, (f64, f64, f64, f64)) {
    let (truth_x, render) = eventually("the intruder rendered", Duration::from_secs(30), || {
        let (code, frame) = skein.post(
            &format!("/api/v1/vehicles/uav-1/payloads/{camera}"),
            json!({"command": "capture"}),
        );
        let intruder = frame["visible"]
            .as_array()
            .and_then(|v| v.iter().find(|a| a["intruder"] == true).cloned());
        let Some(intruder) = intruder.filter(|_| code == 200) else {
            return Err(format!("{code}: {frame}"));
        };
        let (code, _, jpeg) = skein.get_bytes(&format!(
            "/api/v1/vehicles/uav-1/payloads/{camera}/snapshot"
        ));
        let (dcode, det) = skein.post(
            &format!("/api/v1/vehicles/uav-1/payloads/{detector}"),
            json!({"command": "detect"}),
        );
        let x = intruder["x_px"].as_f64().unwrap();
        let found = detection_near(&json!({"last": det}), x)
            .filter(|d| (d.0 - x).abs() < 6.0 && code == 200 && dcode == 200);
        match found {
            Some(d) => Ok((x, (jpeg, d))),
            None => Err(format!("no detection near x = {x}: {det}")),
        }
    });
    let (jpeg, on_render) = render;
    (truth_x, jpeg, on_render)
}
