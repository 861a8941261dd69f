//! Real cameras, from the outside: the camera plugin's RTSP source against an RTSP camera
//! made of Debian's ffmpeg (libx264) and `tests/peers/rtsp_server.py`, loaded by `skein up
//! --sim 1` with real `dlopen`, checked over HTTP only.
//!
//! `rtsp_cameras_stream_stall_come_back_and_count_what_is_broken`: one vehicle carries
//! four cameras, each on its own stream: over TCP and over UDP from
//! the same camera, one whose every 5th RTP packet is noise (a corrupt bitstream), and
//! one whose connection gets bytes that are no RTSP at all after 40 packets. The frames
//! arrive at the stream's size and rate with the vehicle's pose at their capture time; the
//! camera server is stopped (both cameras on it show `stalled`) and started again on the
//! same port (frames again); the dashboard in headless Chromium shows the camera
//! streaming, then greyed and marked stalled; a recording holds the stream's frames; the faults are counted; no payload and no
//! vehicle is ever restarted.
//!
//! `the_detector_finds_the_intruder_on_decoded_h264_where_it_finds_it_on_the_render`: the
//! simulator's own rendered view of an intruder, encoded to H.264 by ffmpeg and served
//! over RTSP, decoded by a second camera with the same optics and mount on the same
//! vehicle; the detector finds the intruder at the same bearing on both (within 0.5°).
//! Then the same render warped through a calibrated lens (principal point off the centre,
//! barrel distortion; `support::lens`) and served by a second RTSP camera: the camera
//! given the lens's `camera_info` YAML rectifies it and its detector finds the intruder at
//! the render's bearing (within 0.5°); a camera taking it for an ideal pinhole is off by
//! more than 0.8°.
//!
//! The camera's other real sources (ROS 2 image topics, V4L2 devices): `e2e_video_sources`.

mod support;

use serde_json::{Value, json};
use std::time::Duration;
use support::payloads::{jpeg_size, payload, write_config};
use support::plugins::{build_into, scratch};
use support::rtsp::RtspCamera;
use support::video::{
    camera, dashboard_shows, detection_near, never_restarted, streaming_past,
    up_rendering_the_intruder,
};
use support::{Skein, eventually, free_tcp_port, run_peer};

/// The payloads of `deploy/config/observation-rtsp.toml` (the seed's observation UAV:
/// gimbal, RTSP camera, detector), its camera pointed at `url`, as a `[models.observation]`
/// table.
fn observation_preset(url: &str) -> String {
    let path = support::workspace().join("deploy/config/observation-rtsp.toml");
    let text = std::fs::read_to_string(path).unwrap();
    let table = &text[text
        .find("[models.observation]")
        .expect("the preset's models")..];
    let shipped = "rtsp://192.168.144.25:8554/main.264";
    assert!(
        table.contains(shipped),
        "the preset's camera URL changed: update this test"
    );
    table.replace(shipped, url)
}

#[test]
fn rtsp_cameras_stream_stall_come_back_and_count_what_is_broken() {
    let good = RtspCamera::start(0, &["--size", "320x240", "--rate", "10"]);
    let corrupt = RtspCamera::start(
        0,
        &["--size", "320x240", "--rate", "10", "--corrupt-every", "5"],
    );
    let garbage = RtspCamera::start(
        0,
        &["--size", "320x240", "--rate", "10", "--garbage-after", "40"],
    );
    let dir = scratch("video");
    build_into(&["skein-plugin-camera"], &[], &dir);
    let cam = |slot: &str, url: &str, extra: &str| {
        format!(
            "{{ slot = \"{slot}\", kind = \"camera\", config = {{ source = \"{url}\", \
             gimbal_slot = \"\", frame_rate_hz = 30.0, stall_timeout_s = 1.0, \
             horizontal_fov_deg = 70.0{extra} }} }},"
        )
    };
    let config = format!(
        "[recording]\ndir = \"{}\"\n\n[models.generic]\npayloads = [\n{}\n{}\n{}\n{}\n]\n\n{}",
        dir.join("recordings").display(),
        cam("camera", &good.url(), ""),
        cam("camera_udp", &good.url(), ", rtsp_transport = \"udp\""),
        cam("camera_corrupt", &corrupt.url(), ""),
        cam("camera_garbage", &garbage.url(), ""),
        observation_preset(&good.url()),
    );
    let config = write_config(&dir, &config);
    build_into(&["skein-plugin-gimbal", "skein-plugin-detector"], &[], &dir);
    // uav-1 generic (the four cameras above), uav-2 observation (the shipped preset's).
    let skein = Skein::up_sim(
        2,
        &["--config", &config, "--plugin-dir", dir.to_str().unwrap()],
    );

    // Frames at the stream's size and rate, with the vehicle's pose at capture time.
    let s = streaming_past(&skein, "camera", 20);
    assert_eq!(
        (s["width_px"].as_u64(), s["height_px"].as_u64()),
        (Some(320), Some(240)),
        "{s}"
    );
    let status = &s["source_status"];
    assert_eq!(status["transport"], "tcp", "{s}");
    let rate = status["stream_rate_hz"].as_f64().unwrap();
    assert!((5.0..=15.0).contains(&rate), "stream at 10 Hz: {s}");
    // Every decoded frame is published or, when the camera's 25 Hz poll came late (a
    // busy machine), counted as superseded by a newer one; none goes missing.
    let published = s["published_rate_hz"].as_f64().unwrap();
    assert!(published > 2.0, "{s}");
    let decoded = status["frames_decoded"].as_u64().unwrap();
    let superseded = status["dropped"]["superseded"].as_u64().unwrap();
    let frames = s["frames"].as_u64().unwrap();
    assert!(
        frames + superseded + 1 >= decoded && frames <= decoded,
        "published {frames} + superseded {superseded} of {decoded} decoded: {s}"
    );
    assert!(s["viewer_kbit_s"].as_f64().unwrap() > 0.0, "{s}");
    assert_eq!(s["pointing"]["from"], "telemetry at capture time", "{s}");
    let latency = s["capture_latency_ms"].as_f64().unwrap();
    assert!((0.0..1000.0).contains(&latency), "{s}");
    let (code, ctype, jpeg) = skein.get_bytes("/api/v1/vehicles/uav-1/payloads/camera/snapshot");
    assert_eq!((code, ctype.as_str()), (200, "image/jpeg"));
    assert_eq!(jpeg_size(&jpeg), (320, 240));
    let xmp = String::from_utf8_lossy(&jpeg);
    assert!(xmp.contains("skein:North="), "the frame carries its pose");
    // Its zoom is the camera's own: skein refuses to pretend otherwise, and says why.
    let (code, body) = skein.post(
        "/api/v1/vehicles/uav-1/payloads/camera",
        json!({"command": "set_zoom", "zoom": 2.0}),
    );
    assert!(
        (400..500).contains(&code) && body.to_string().contains("zooms on the camera itself"),
        "{code}: {body}"
    );
    let udp = streaming_past(&skein, "camera_udp", 10);
    assert_eq!(udp["source_status"]["transport"], "udp", "{udp}");
    dashboard_shows(&skein, "camera", "streaming");

    // A recording holds the real camera's frames as it holds the simulated ones.
    let body = skein.record_for("rtsp", 1.5, Duration::from_secs(20));
    let (code, out, err) = run_peer(
        "read_mcap.py",
        &[body["path"].as_str().unwrap()],
        Duration::from_secs(120),
    );
    assert_eq!(code, Some(0), "read_mcap.py failed:\n{out}\n{err}");
    let mcap: Value = serde_json::from_str(out.trim()).unwrap();
    let image = &mcap["channels"]["/skein/uav-1/camera/image"];
    assert_eq!(image["schema"], "foxglove.CompressedImage", "{image}");
    assert_eq!(image["facts"]["jpeg"], true, "{image}");
    assert!(
        image["count"].as_u64() >= Some(8),
        "10 Hz for 1.5 s: {image}"
    );

    // The shipped observation preset: the stream scaled to its 640x360, aimed by the
    // gimbal, read by the detector.
    let preset = eventually(
        "the preset's camera and detector",
        Duration::from_secs(40),
        || {
            let cam = payload(&skein, "uav-2", "camera")["state"].clone();
            let det = payload(&skein, "uav-2", "detector")["state"].clone();
            let ok = cam["source_status"]["state"] == "streaming"
                && cam["width_px"] == 640
                && cam["height_px"] == 360
                && cam["pointing"]["from"] == "telemetry at capture time"
                && det["frames"].as_u64() > Some(5)
                && det["last_error"].is_null();
            if ok {
                Ok((cam, det))
            } else {
                Err(format!("{cam}\n{det}"))
            }
        },
    );
    eprintln!(
        "preset: camera {} / detector frames {}",
        preset.0["source_status"], preset.1["frames"]
    );

    // The camera goes away: both cameras on it stall, and nothing is restarted.
    let before = camera(&skein, "camera")["source_status"]["frames_decoded"]
        .as_u64()
        .unwrap();
    let port = good.stop();
    for slot in ["camera", "camera_udp"] {
        eventually(&format!("{slot} stalled"), Duration::from_secs(20), || {
            let s = camera(&skein, slot);
            let stalled = s["source_status"]["state"] == "stalled"
                && s["last_error"]
                    .as_str()
                    .is_some_and(|e| e.contains("stalled"));
            if stalled { Ok(()) } else { Err(s.to_string()) }
        });
    }
    never_restarted(&skein, &["camera", "camera_udp"]);
    dashboard_shows(&skein, "camera", "stalled");

    // It comes back on the same port: frames again, in a new session.
    let good = RtspCamera::start(port, &["--size", "320x240", "--rate", "10"]);
    let s = eventually("camera streaming again", Duration::from_secs(40), || {
        let s = camera(&skein, "camera");
        let st = &s["source_status"];
        let ok = st["state"] == "streaming"
            && st["frames_decoded"].as_u64().unwrap_or(0) > before + 10
            && st["sessions"].as_u64().unwrap_or(0) >= 2
            && s["last_error"].is_null();
        if ok { Ok(s) } else { Err(s.to_string()) }
    });
    eprintln!("back: {}", s["source_status"]);
    streaming_past(&skein, "camera_udp", udp["frames"].as_u64().unwrap() + 10);

    // Broken streams: counted, decoded where they can be, never a crash.
    let s = eventually("corrupt frames counted", Duration::from_secs(40), || {
        let s = camera(&skein, "camera_corrupt");
        let d = &s["source_status"]["dropped"];
        let dropped = [
            "decode_error",
            "malformed",
            "lost_packets",
            "depacketize_error",
        ]
        .iter()
        .map(|k| d[k].as_u64().unwrap_or(0))
        .sum::<u64>();
        if dropped > 0 && s["source_status"]["frames_decoded"].as_u64() > Some(0) {
            Ok(s)
        } else {
            Err(s.to_string())
        }
    });
    eprintln!("corrupt: {}", s["source_status"]);
    let s = eventually("garbage survived", Duration::from_secs(40), || {
        let s = camera(&skein, "camera_garbage");
        let st = &s["source_status"];
        let ok = st["dropped"]["depacketize_error"].as_u64() > Some(0)
            && st["sessions"].as_u64() >= Some(2)
            && st["state"] == "streaming";
        if ok { Ok(s) } else { Err(s.to_string()) }
    });
    eprintln!("garbage: {}", s["source_status"]);
    never_restarted(
        &skein,
        &["camera", "camera_udp", "camera_corrupt", "camera_garbage"],
    );
    drop((good, corrupt, garbage));
}

#[test]
fn the_detector_finds_the_intruder_on_decoded_h264_where_it_finds_it_on_the_render() {
    let dir = scratch("video-detector");
    build_into(&["skein-plugin-camera", "skein-plugin-detector"], &[], &dir);
    // Both cameras: a 12 mm lens on a fixed mount looking 45° right of the nose and 7° up,
    // where the intruder passes (60 m east, 14 m up, starting 90 m north); one renders,
    // one decodes the RTSP stream of that render.
    let (port, lens_port) = (free_tcp_port(), free_tcp_port());
    // A third and fourth camera: the same render as a calibrated lens (off-centre axis,
    // barrel distortion) would have taken it, with its calibration and without.
    let focal_px = 12.0 * 640.0 / 6.17; // the render's: 12 mm on the default 6.17 mm sensor
    let camera_info = support::lens::camera_info_yaml(focal_px);
    let camera_info_file = dir.join("camera_info.yaml");
    std::fs::write(&camera_info_file, &camera_info).unwrap();
    let lens = format!(
        "camera_info_file = \"{}\", width_px = 640, height_px = 480, gimbal_slot = \"\", \
         mount_pitch_deg = 7.0, mount_yaw_deg = 45.0",
        camera_info_file.display()
    );
    let optics = "focal_length_mm = 12.0, width_px = 640, height_px = 480, gimbal_slot = \"\", \
                  mount_pitch_deg = 7.0, mount_yaw_deg = 45.0";
    let config = format!(
        "[models.generic]\npayloads = [\n\
         {{ slot = \"camera\", kind = \"camera\", config = {{ frame_rate_hz = 0.0, {optics} }} }},\n\
         {{ slot = \"detector\", kind = \"detector\", config = {{ camera_slot = \"camera\" }} }},\n\
         {{ slot = \"camera_rtsp\", kind = \"camera\", config = {{ source = \"rtsp://127.0.0.1:{port}/main\", \
            frame_rate_hz = 10.0, {optics} }} }},\n\
         {{ slot = \"detector_rtsp\", kind = \"detector\", config = {{ camera_slot = \"camera_rtsp\" }} }},\n\
         {{ slot = \"camera_lens\", kind = \"camera\", config = {{ source = \"rtsp://127.0.0.1:{lens_port}/main\", \
            frame_rate_hz = 10.0, {lens} }} }},\n\
         {{ slot = \"detector_lens\", kind = \"detector\", config = {{ camera_slot = \"camera_lens\" }} }},\n\
         {{ slot = \"camera_lens_raw\", kind = \"camera\", config = {{ source = \"rtsp://127.0.0.1:{lens_port}/main\", \
            frame_rate_hz = 10.0, {optics} }} }},\n\
         {{ slot = \"detector_lens_raw\", kind = \"detector\", config = {{ camera_slot = \"camera_lens_raw\" }} }},\n]\n"
    );
    // The render: one frame with the intruder in it, and what the detector finds on it.
    let (skein, render) = up_rendering_the_intruder(&dir, &config);
    let (truth_x, on_render, image) = (render.truth_x, render.on_render, &render.image);

    // The same picture through H.264 and RTSP.
    let image_arg = image.to_str().unwrap().to_string();
    let _server = RtspCamera::start(
        port,
        &["--image", &image_arg, "--size", "640x480", "--rate", "10"],
    );
    let on_stream = eventually(
        "the detector on the stream",
        Duration::from_secs(40),
        || {
            let s = payload(&skein, "uav-1", "detector_rtsp")["state"].clone();
            match detection_near(&s, truth_x).filter(|d| (d.0 - truth_x).abs() < 6.0) {
                Some(d) => Ok(d),
                None => Err(s.to_string()),
            }
        },
    );
    let (d_az, d_el) = (
        (on_stream.2 - on_render.2).abs(),
        (on_stream.3 - on_render.3).abs(),
    );
    eprintln!(
        "render: x {:.2} y {:.2} az {:.3} el {:.3}; stream: x {:.2} y {:.2} az {:.3} el {:.3}; \
         difference {d_az:.3}° / {d_el:.3}°",
        on_render.0,
        on_render.1,
        on_render.2,
        on_render.3,
        on_stream.0,
        on_stream.1,
        on_stream.2,
        on_stream.3
    );
    assert!(
        d_az < 0.5 && d_el < 0.5,
        "bearings differ by {d_az:.3}° / {d_el:.3}°"
    );
    let s = camera(&skein, "camera_rtsp");
    assert_eq!(s["source_status"]["state"], "streaming", "{s}");

    // Through the lens: rectified with its calibration, the intruder is where the render
    // has it; taken for an ideal pinhole, it is not.
    let ideal = {
        let mut decoder = jpeg_decoder::Decoder::new(render.jpeg.as_slice());
        decoder.decode().expect("the render decodes")
    };
    let warped = support::lens::warp_through(&camera_info, &ideal, 640, 480, focal_px);
    let warped_file = dir.join("through_the_lens.ppm");
    std::fs::write(&warped_file, support::lens::ppm(&warped, 640, 480)).unwrap();
    let warped_arg = warped_file.to_str().unwrap().to_string();
    let _lens_server = RtspCamera::start(
        lens_port,
        &["--image", &warped_arg, "--size", "640x480", "--rate", "10"],
    );
    let through = |slot: &str, near_x: f64| {
        eventually(
            &format!("{slot} on the lens's stream"),
            Duration::from_secs(40),
            || {
                let s = payload(&skein, "uav-1", slot)["state"].clone();
                match detection_near(&s, near_x).filter(|d| (d.0 - near_x).abs() < 40.0) {
                    Some(d) => Ok(d),
                    None => Err(s.to_string()),
                }
            },
        )
    };
    let rectified = through("detector_lens", truth_x);
    let raw = through("detector_lens_raw", truth_x);
    let off = |d: (f64, f64, f64, f64)| {
        (
            (d.2 - on_render.2 + 180.0).rem_euclid(360.0) - 180.0,
            d.3 - on_render.3,
        )
    };
    let (rect_off, raw_off) = (off(rectified), off(raw));
    eprintln!(
        "through the lens: rectified x {:.2} y {:.2}, {:.3}° / {:.3}° from the render; \
         not rectified x {:.2} y {:.2}, {:.3}° / {:.3}°",
        rectified.0, rectified.1, rect_off.0, rect_off.1, raw.0, raw.1, raw_off.0, raw_off.1
    );
    assert!(
        rect_off.0.abs() < 0.5 && rect_off.1.abs() < 0.5,
        "rectified bearing {rect_off:?}° off the render's"
    );
    assert!(
        raw_off.0.hypot(raw_off.1) > 0.8,
        "the lens should matter here: {raw_off:?}°"
    );
    let s = camera(&skein, "camera_lens");
    assert_eq!(s["camera_info"]["camera_name"], "test_lens", "{s}");
    assert!(
        (s["horizontal_fov_deg"].as_f64().unwrap()
            - camera(&skein, "camera")["horizontal_fov_deg"]
                .as_f64()
                .unwrap())
        .abs()
            < 1e-6,
        "{s}"
    );
    never_restarted(
        &skein,
        &[
            "camera",
            "camera_rtsp",
            "detector",
            "detector_rtsp",
            "camera_lens",
            "detector_lens",
            "camera_lens_raw",
            "detector_lens_raw",
        ],
    );
}
