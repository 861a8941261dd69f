//! Real cameras, from the outside, other than RTSP (`e2e_video`): the camera plugin's ROS 2
//! image topic and V4L2 sources, loaded by `skein up --sim 1` with real `dlopen`, checked
//! over HTTP only.
//!
//! `ros2_image_topics_from_a_cyclonedds_camera_node_reach_the_video_and_the_detector`: a
//! ROS 2 camera node made of CycloneDDS (`tests/peers/image_publisher.py`) publishes the
//! same render as `sensor_msgs/CompressedImage` (JPEG) and as a raw `rgb8`
//! `sensor_msgs/Image`, and a topic of images that do not decode; cameras with `source =
//! "ros2:…"` read them, their detectors find the intruder at the render's bearing (within
//! 0.5°), the dashboard's MJPEG stream serves the frames, images that do not decode and
//! samples that are no Image are counted;
//! the node stops (stalled) and starts again (frames again), nothing restarted.
//!
//! `v4l2_cameras_say_why_a_device_is_missing_and_stream_from_one_that_is_there`: a camera
//! on a V4L2 path that does not exist reports `failed` with the path and the retry, and is
//! retried; with a device present (`/dev/video*`), a camera on it streams; without one the
//! test says it skipped that part.

mod support;

use std::time::Duration;
use support::payloads::{jpeg_size, mjpeg_parts, payload, write_config};
use support::plugins::{build_into, scratch};
use support::video::{
    camera, detection_near, never_restarted, streaming_past, up_rendering_the_intruder,
};
use support::{Process, Skein, eventually, python};

/// A DDS domain of this test process's own: 219–232, apart from the other targets'
/// (`e2e_dds` 100–179, `e2e_ros2` 180–218).
fn ros2_domain() -> String {
    (219 + std::process::id() % 14).to_string()
}

/// `tests/peers/image_publisher.py` on `domain` (loopback) with `args`, once its writers
/// exist; killed on drop.
fn image_publisher(domain: &str, args: &[&str]) -> Process {
    let script = support::workspace().join("tests/peers/image_publisher.py");
    let py = python();
    let mut command = vec![
        py.to_str().unwrap(),
        script.to_str().unwrap(),
        "--domain",
        domain,
        "--loopback",
        "--rate",
        "10",
    ];
    command.extend_from_slice(args);
    let mut p = Process::start_command(&command, &[]);
    p.wait_line("PUBLISHING", Duration::from_secs(60));
    p
}

#[test]
fn ros2_image_topics_from_a_cyclonedds_camera_node_reach_the_video_and_the_detector() {
    let dir = scratch("video-ros2");
    build_into(&["skein-plugin-camera", "skein-plugin-detector"], &[], &dir);
    let d = ros2_domain();
    // As in the RTSP test: a simulated camera renders the intruder; the cameras reading
    // ROS 2 topics have the same optics and mount on the same vehicle.
    let optics = "focal_length_mm = 12.0, width_px = 640, height_px = 480, gimbal_slot = \"\", \
                  mount_pitch_deg = 7.0, mount_yaw_deg = 45.0";
    let ros2 = |topic: &str| {
        format!(
            "source = \"ros2:{topic}\", ros_domain_id = {d}, dds_network = [\"127.0.0.1\"], \
             stall_timeout_s = 1.0, frame_rate_hz = 10.0, {optics}"
        )
    };
    let config = format!(
        "[models.generic]\npayloads = [\n\
         {{ slot = \"camera\", kind = \"camera\", config = {{ frame_rate_hz = 0.0, {optics} }} }},\n\
         {{ slot = \"detector\", kind = \"detector\", config = {{ camera_slot = \"camera\" }} }},\n\
         {{ slot = \"camera_jpeg\", kind = \"camera\", config = {{ {} }} }},\n\
         {{ slot = \"detector_jpeg\", kind = \"detector\", config = {{ camera_slot = \"camera_jpeg\" }} }},\n\
         {{ slot = \"camera_raw\", kind = \"camera\", config = {{ {} }} }},\n\
         {{ slot = \"detector_raw\", kind = \"detector\", config = {{ camera_slot = \"camera_raw\" }} }},\n\
         {{ slot = \"camera_broken\", kind = \"camera\", config = {{ {} }} }},\n\
         {{ slot = \"camera_wrong\", kind = \"camera\", config = {{ {} }} }},\n]\n",
        ros2("/gimbal/image_raw/compressed"),
        ros2("/gimbal/image_raw"),
        ros2("/broken/image_raw/compressed"),
        ros2("/wrong/image_raw"),
    );
    let (skein, render) = up_rendering_the_intruder(&dir, &config);
    let (truth_x, on_render, image, jpeg) = (
        render.truth_x,
        render.on_render,
        &render.image,
        &render.jpeg,
    );
    let rgb = jpeg_decoder::Decoder::new(jpeg.as_slice())
        .decode()
        .expect("the render decodes");
    let ppm = dir.join("render.ppm");
    std::fs::write(&ppm, support::lens::ppm(&rgb, 640, 480)).unwrap();

    // A ROS 2 camera node: the render as CompressedImage (JPEG) and as a raw rgb8 Image,
    // and a topic of images that do not decode.
    let compressed = format!("/gimbal/image_raw/compressed={}", image.display());
    let raw = format!("/gimbal/image_raw={}", ppm.display());
    let node_args = [
        "--compressed",
        compressed.as_str(),
        "--raw",
        raw.as_str(),
        "--corrupt",
        "/broken/image_raw/compressed",
        "--wrong-type",
        "/wrong/image_raw",
    ];
    let node = image_publisher(&d, &node_args);
    for (slot, detector) in [
        ("camera_jpeg", "detector_jpeg"),
        ("camera_raw", "detector_raw"),
    ] {
        let found = eventually(
            &format!("{detector} on the ROS 2 topic"),
            Duration::from_secs(60),
            || {
                let s = payload(&skein, "uav-1", detector)["state"].clone();
                match detection_near(&s, truth_x).filter(|d| (d.0 - truth_x).abs() < 6.0) {
                    Some(d) => Ok(d),
                    None => Err(format!("{s} / camera: {}", camera(&skein, slot))),
                }
            },
        );
        let (d_az, d_el) = ((found.2 - on_render.2).abs(), (found.3 - on_render.3).abs());
        eprintln!(
            "{slot}: x {:.2} y {:.2}, {d_az:.3}° / {d_el:.3}° from the render's bearing",
            found.0, found.1
        );
        assert!(d_az < 0.5 && d_el < 0.5, "{slot}: {d_az:.3}° / {d_el:.3}°");
        let s = streaming_past(&skein, slot, 3);
        let status = &s["source_status"];
        assert_eq!(s["source"], "ros2", "{s}");
        assert_eq!(status["transport"], "dds", "{s}");
        assert_eq!(
            (
                status["stream_width_px"].as_u64(),
                status["stream_height_px"].as_u64()
            ),
            (Some(640), Some(480)),
            "{s}"
        );
        // The header's stamp is the capture time: the pose is the telemetry's then.
        let latency = s["capture_latency_ms"].as_f64().unwrap();
        assert!((0.0..1000.0).contains(&latency), "{s}");
        eprintln!(
            "{slot}: {:?} frames/s, capture to camera {latency:.1} ms",
            status["stream_rate_hz"].as_f64()
        );
        assert!(s["pointing"].is_object(), "{s}");
    }
    // The dashboard's video: the MJPEG stream serves the topic's frames.
    let parts = mjpeg_parts(&skein, "uav-1", "camera_jpeg", 3);
    assert!(parts.iter().all(|p| jpeg_size(p) == (640, 480)));
    eprintln!(
        "MJPEG from the ROS 2 topic: {} parts of {:?} bytes",
        parts.len(),
        parts.iter().map(Vec::len).collect::<Vec<_>>()
    );
    // Images that do not decode are counted and never shown; the stall they make names
    // why (at the first stall report after them: one may have come before the first).
    let broken = eventually("the broken topic counted", Duration::from_secs(30), || {
        let s = camera(&skein, "camera_broken");
        let d = &s["source_status"]["dropped"];
        let named = s["source_status"]["detail"]
            .as_str()
            .is_some_and(|d| d.contains("image decoding failed"));
        let ok = d["decode_error"].as_u64().unwrap_or(0) >= 4 && s["frames"] == 0 && named;
        if ok { Ok(s) } else { Err(s.to_string()) }
    });
    eprintln!("broken topic: {}", broken["source_status"]);
    assert_ne!(broken["source_status"]["state"], "streaming", "{broken}");
    // Samples that are not the topic's message: counted as malformed, never shown.
    let wrong = eventually(
        "the mistyped topic counted",
        Duration::from_secs(30),
        || {
            let s = camera(&skein, "camera_wrong");
            let malformed = s["source_status"]["dropped"]["malformed"]
                .as_u64()
                .unwrap_or(0);
            if malformed >= 4 && s["frames"] == 0 {
                Ok(s)
            } else {
                Err(s.to_string())
            }
        },
    );
    eprintln!("mistyped topic: {}", wrong["source_status"]);

    // The camera node stops: stalled; it comes back: frames again.
    drop(node);
    let stalled = eventually("camera_jpeg stalled", Duration::from_secs(20), || {
        let s = camera(&skein, "camera_jpeg");
        if s["source_status"]["state"] == "stalled" {
            Ok(s)
        } else {
            Err(s.to_string())
        }
    });
    let detail = stalled["source_status"]["detail"].as_str().unwrap();
    assert!(detail.contains("/gimbal/image_raw/compressed"), "{detail}");
    let before = stalled["frames"].as_u64().unwrap();
    let _node = image_publisher(&d, &node_args);
    streaming_past(&skein, "camera_jpeg", before);
    never_restarted(
        &skein,
        &[
            "camera_jpeg",
            "detector_jpeg",
            "camera_raw",
            "detector_raw",
            "camera_broken",
            "camera_wrong",
        ],
    );
}

/// The V4L2 device nodes of this machine (`/dev/video*`).
fn v4l2_devices() -> Vec<String> {
    let mut found: Vec<String> = std::fs::read_dir("/dev")
        .map(|d| {
            d.filter_map(Result::ok)
                .map(|e| e.path().display().to_string())
                .filter(|p| p.starts_with("/dev/video"))
                .collect()
        })
        .unwrap_or_default();
    found.sort();
    found
}

#[test]
fn v4l2_cameras_say_why_a_device_is_missing_and_stream_from_one_that_is_there() {
    let dir = scratch("video-v4l2");
    build_into(&["skein-plugin-camera"], &[], &dir);
    let devices = v4l2_devices();
    let v4l2 = |device: &str| {
        format!(
            "source = \"v4l2:{device}\", horizontal_fov_deg = 70.0, width_px = 320, \
             height_px = 240, frame_rate_hz = 10.0, stall_timeout_s = 2.0"
        )
    };
    let mut payloads = format!(
        "{{ slot = \"camera_missing\", kind = \"camera\", config = {{ {} }} }},\n",
        v4l2("/dev/skein-no-such-camera")
    );
    if let Some(d) = devices.first() {
        payloads += &format!(
            "{{ slot = \"camera_device\", kind = \"camera\", config = {{ {} }} }},\n",
            v4l2(d)
        );
    }
    let config = write_config(
        &dir,
        &format!("[models.generic]\npayloads = [\n{payloads}]\n"),
    );
    let skein = Skein::up_sim(
        1,
        &["--config", &config, "--plugin-dir", dir.to_str().unwrap()],
    );
    // A device that is not there: failed, the path and the retry named, tried again.
    let missing = eventually(
        "the missing device retried",
        Duration::from_secs(30),
        || {
            let s = camera(&skein, "camera_missing");
            let status = &s["source_status"];
            let ok = status["state"] == "failed" && status["sessions"].as_u64() >= Some(2);
            if ok { Ok(s) } else { Err(s.to_string()) }
        },
    );
    let status = &missing["source_status"];
    let detail = status["detail"].as_str().unwrap();
    assert!(
        detail.contains("cannot open /dev/skein-no-such-camera") && detail.contains("again in"),
        "{detail}"
    );
    assert_eq!(status["url"], "v4l2:/dev/skein-no-such-camera", "{status}");
    assert_eq!(status["transport"], "mmap", "{status}");
    eprintln!("missing V4L2 device: {detail}");
    match devices.first() {
        Some(d) => {
            let s = streaming_past(&skein, "camera_device", 3);
            eprintln!("V4L2 {d}: {}", s["source_status"]);
            never_restarted(&skein, &["camera_missing", "camera_device"]);
        }
        None => {
            eprintln!(
                "skipped: no V4L2 capture device (/dev/video*) on this machine; only the \
                 missing device was driven"
            );
            never_restarted(&skein, &["camera_missing"]);
        }
    }
}
