//! The camera's configuration (see the crate docs): its keys, where frames come from
//! (`source`), a calibrated lens, and the real sources opened from them.

use crate::source::Mount;
use crate::stream::StreamSource;
use skein_plugin_sdk::args::in_range;
use skein_plugin_sdk::serde::Deserialize;
use skein_video::input::VideoInput;
use skein_video::rectify::{Calibration, Rectifier};
use skein_video::ros2::Ros2Config;
use skein_video::rtsp::{RtpTransport, RtspConfig};
use skein_video::v4l2::V4l2Config;
use std::net::IpAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Where frames come from (`source`).
#[derive(Debug, Clone, PartialEq)]
pub enum SourceKind {
    /// `"simulated"`: the rendered world.
    Simulated,
    /// `"rtsp://…"`: a real camera's H.264 stream.
    Rtsp(skein_video::rtsp::Url),
    /// `"ros2:/camera/image_raw/compressed"`: a ROS 2 camera node's image topic (its full
    /// name).
    Ros2(String),
    /// `"v4l2:/dev/video0"`: a V4L2 capture device (USB or CSI camera) by its path.
    V4l2(PathBuf),
}

impl SourceKind {
    /// Parses the `source` key.
    ///
    /// # Errors
    /// An unknown kind of source, or a malformed URL or topic, naming the key.
    pub fn parse(source: &str) -> Result<SourceKind, String> {
        if source == "simulated" {
            return Ok(SourceKind::Simulated);
        }
        if source.starts_with("rtsp://") {
            return RtspConfig::parse_url(source)
                .map(SourceKind::Rtsp)
                .map_err(|e| format!("source: {e}"));
        }
        if let Some(topic) = source.strip_prefix("ros2:") {
            return Ros2Config::check_topic(topic)
                .map(|()| SourceKind::Ros2(topic.to_string()))
                .map_err(|e| format!("source: {e}"));
        }
        if let Some(device) = source.strip_prefix("v4l2:") {
            if !device.starts_with('/') {
                return Err(format!(
                    "source: a V4L2 device is an absolute path (\"v4l2:/dev/video0\"), got \"{source}\""
                ));
            }
            return Ok(SourceKind::V4l2(PathBuf::from(device)));
        }
        Err(format!(
            "source: expected \"simulated\", an RTSP URL (\"rtsp://host:8554/main\"), a \
             ROS 2 image topic (\"ros2:/camera/image_raw/compressed\") or a V4L2 device \
             (\"v4l2:/dev/video0\"), got \"{source}\""
        ))
    }

    /// True for a real camera.
    pub fn real(&self) -> bool {
        *self != SourceKind::Simulated
    }
}

/// The configuration (see the crate docs): every field optional, ranges checked where
/// used. Pixel counts and the JPEG quality are read as numbers, as they always were
/// (`640.0` is 640).
#[derive(Deserialize)]
#[serde(crate = "skein_plugin_sdk::serde", deny_unknown_fields)]
pub(crate) struct Config {
    pub(crate) source: Option<String>,
    pub(crate) rtsp_transport: Option<String>,
    pub(crate) ros_domain_id: Option<f64>,
    pub(crate) dds_network: Option<Vec<String>>,
    pub(crate) stall_timeout_s: Option<f64>,
    pub(crate) latency_ms: Option<f64>,
    pub(crate) camera_info_file: Option<String>,
    pub(crate) horizontal_fov_deg: Option<f64>,
    pub(crate) width_px: Option<f64>,
    pub(crate) height_px: Option<f64>,
    pub(crate) frame_rate_hz: Option<f64>,
    pub(crate) focal_length_mm: Option<f64>,
    pub(crate) focal_min_mm: Option<f64>,
    pub(crate) focal_max_mm: Option<f64>,
    pub(crate) sensor_width_mm: Option<f64>,
    pub(crate) jpeg_quality: Option<f64>,
    pub(crate) gimbal_slot: Option<String>,
    pub(crate) mount_pitch_deg: Option<f64>,
    pub(crate) mount_yaw_deg: Option<f64>,
    pub(crate) ground_down_m: Option<f64>,
    pub(crate) aircraft_span_m: Option<f64>,
}

/// A calibrated lens (`camera_info_file`: a real camera's, rectified into an ideal
/// pinhole by the stream source; the calibration gives the field of view), or none.
///
/// # Errors
/// A calibration for the simulated camera (an ideal pinhole already), one given beside
/// `horizontal_fov_deg` or `focal_length_mm`, or a file that is no valid calibration
/// ([`Calibration::from_ros_yaml_file`]).
pub(crate) fn lens_calibration(
    kind: &SourceKind,
    c: &Config,
) -> Result<Option<Calibration>, String> {
    match c.camera_info_file.as_deref() {
        None => Ok(None),
        Some(_) if !kind.real() => Err(
            "camera_info_file: the simulated camera is an ideal pinhole; a calibration is \
             for a real camera's frames"
                .to_string(),
        ),
        Some(_) if c.horizontal_fov_deg.is_some() || c.focal_length_mm.is_some() => Err(
            "camera_info_file: the calibration gives the field of view; leave out \
             horizontal_fov_deg and focal_length_mm"
                .to_string(),
        ),
        Some(path) => Calibration::from_ros_yaml_file(Path::new(path)).map(Some),
    }
}

/// Checks that the keys only some sources read are not given to another.
///
/// # Errors
/// The first such key, named.
pub(crate) fn only_for(kind: &SourceKind, c: &Config) -> Result<(), String> {
    let rtsp = matches!(kind, SourceKind::Rtsp(_));
    let ros2 = matches!(kind, SourceKind::Ros2(_));
    for (key, given, fits) in [
        ("rtsp_transport", c.rtsp_transport.is_some(), rtsp),
        ("ros_domain_id", c.ros_domain_id.is_some(), ros2),
        ("dds_network", c.dds_network.is_some(), ros2),
        ("stall_timeout_s", c.stall_timeout_s.is_some(), kind.real()),
        ("latency_ms", c.latency_ms.is_some(), kind.real()),
    ] {
        if given && !fits {
            return Err(format!("{key}: not a key of this camera's source"));
        }
    }
    Ok(())
}

/// The DDS domain of a ROS 2 source: `ros_domain_id`, else `ROS_DOMAIN_ID` as ROS 2 reads
/// it, else 0.
fn domain_id(c: &Config) -> Result<u16, String> {
    let id = match c.ros_domain_id {
        Some(id) => id,
        None => match std::env::var("ROS_DOMAIN_ID") {
            Ok(v) if !v.trim().is_empty() => v
                .trim()
                .parse()
                .map_err(|_| format!("ros_domain_id: ROS_DOMAIN_ID is not a number: \"{v}\""))?,
            _ => 0.0,
        },
    };
    Ok(in_range("ros_domain_id", id, 0.0, 232.0)? as u16)
}

/// Opens a real camera's source (`kind` is not simulated): its frames at `size_px` (or
/// its own size), rectified when `calibration` is given, aimed by `mount`.
///
/// # Errors
/// A key out of range or meant for another source (named), or the source's thread could
/// not start.
pub(crate) fn open_real(
    kind: SourceKind,
    c: &Config,
    mount: Mount,
    size_px: Option<(u32, u32)>,
    calibration: Option<Calibration>,
) -> Result<StreamSource, String> {
    let stall_timeout = Duration::from_secs_f64(in_range(
        "stall_timeout_s",
        c.stall_timeout_s.unwrap_or(2.0),
        0.2,
        60.0,
    )?);
    let latency_ms = in_range("latency_ms", c.latency_ms.unwrap_or(0.0), 0.0, 2000.0)?;
    let (name, input): (&'static str, VideoInput) = match kind {
        SourceKind::Simulated => return Err("source: simulated is not a real camera".into()),
        SourceKind::Rtsp(url) => {
            let transport = match c.rtsp_transport.as_deref().unwrap_or("tcp") {
                "tcp" => RtpTransport::Tcp,
                "udp" => RtpTransport::Udp,
                other => {
                    return Err(format!(
                        "rtsp_transport: expected \"tcp\" or \"udp\", got \"{other}\""
                    ));
                }
            };
            let config = RtspConfig {
                url,
                transport,
                stall_timeout,
                latency_ms,
            };
            ("rtsp", skein_video::rtsp::start(config)?)
        }
        SourceKind::Ros2(topic) => {
            let networks = c
                .dds_network
                .iter()
                .flatten()
                .map(|a| {
                    a.parse::<IpAddr>()
                        .map_err(|_| format!("dds_network: not an IP address: \"{a}\""))
                })
                .collect::<Result<Vec<_>, _>>()?;
            let config = Ros2Config {
                topic,
                domain_id: domain_id(c)?,
                networks,
                stall_timeout,
                latency_ms,
            };
            ("ros2", skein_video::ros2::start(config)?)
        }
        SourceKind::V4l2(device) => {
            // The device is asked for the output size and rate; what it offers instead is
            // scaled and capped by the camera.
            let config = V4l2Config {
                device,
                width_px: size_px.map(|s| s.0),
                height_px: size_px.map(|s| s.1),
                frame_rate_hz: c.frame_rate_hz.filter(|hz| *hz > 0.0),
                stall_timeout,
                latency_ms,
            };
            ("v4l2", skein_video::v4l2::start(config)?)
        }
    };
    Ok(StreamSource::new(
        name,
        input,
        mount,
        size_px,
        calibration.map(Rectifier::new),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use skein_plugin_sdk::args;
    use skein_plugin_sdk::serde_json::{Value, json};

    fn config(v: Value) -> Config {
        args::config(v).unwrap()
    }

    #[test]
    fn a_lens_calibration_is_for_a_real_camera_and_alone() {
        let rtsp = SourceKind::parse("rtsp://cam:8554/main").unwrap();
        let none = config(json!({"source": "rtsp://cam:8554/main"}));
        assert!(lens_calibration(&rtsp, &none).unwrap().is_none());
        let simulated = config(json!({"camera_info_file": "/etc/cam.yaml"}));
        let e = lens_calibration(&SourceKind::Simulated, &simulated).unwrap_err();
        assert!(
            e.starts_with("camera_info_file: the simulated camera"),
            "{e}"
        );
        let both = config(json!({"camera_info_file": "/etc/cam.yaml", "horizontal_fov_deg": 80.0}));
        let e = lens_calibration(&rtsp, &both).unwrap_err();
        assert!(e.contains("leave out horizontal_fov_deg"), "{e}");
        let missing = config(json!({"camera_info_file": "/nonexistent/cam.yaml"}));
        let e = lens_calibration(&rtsp, &missing).unwrap_err();
        assert!(
            e.starts_with("camera_info_file /nonexistent/cam.yaml:"),
            "{e}"
        );
    }

    #[test]
    fn sources_are_parsed_and_bad_ones_named() {
        assert_eq!(SourceKind::parse("simulated"), Ok(SourceKind::Simulated));
        assert!(matches!(
            SourceKind::parse("rtsp://cam:8554/main"),
            Ok(SourceKind::Rtsp(u)) if u.port() == Some(8554)
        ));
        assert_eq!(
            SourceKind::parse("ros2:/camera/image_raw/compressed"),
            Ok(SourceKind::Ros2("/camera/image_raw/compressed".into()))
        );
        let e = SourceKind::parse("ros2:camera/image_raw").unwrap_err();
        assert!(e.starts_with("source:") && e.contains("absolute"), "{e}");
        assert_eq!(
            SourceKind::parse("v4l2:/dev/video0"),
            Ok(SourceKind::V4l2("/dev/video0".into()))
        );
        let e = SourceKind::parse("v4l2:video0").unwrap_err();
        assert!(e.contains("absolute path"), "{e}");
        let e = SourceKind::parse("http://cam/main").unwrap_err();
        assert!(
            e.starts_with("source:") && e.contains("http://cam/main"),
            "{e}"
        );
        assert!(
            SourceKind::parse("rtsp://")
                .unwrap_err()
                .starts_with("source:")
        );
    }

    #[test]
    fn keys_of_another_source_and_bad_dds_settings_are_named() {
        let mount = Mount {
            gimbal_slot: None,
            mount_pitch_deg: 0.0,
            mount_yaw_deg: 0.0,
        };
        let open = |v: Value| {
            let c = config(v);
            let kind = SourceKind::parse(c.source.as_deref().unwrap()).unwrap();
            only_for(&kind, &c)?;
            open_real(kind, &c, mount.clone(), None, None).map(|_| ())
        };
        let e = open(json!({"source": "rtsp://cam/main", "ros_domain_id": 3.0})).unwrap_err();
        assert!(e.starts_with("ros_domain_id: not a key"), "{e}");
        let e = open(json!({"source": "ros2:/cam/image", "rtsp_transport": "udp"})).unwrap_err();
        assert!(e.starts_with("rtsp_transport: not a key"), "{e}");
        let e = open(json!({"source": "ros2:/cam/image", "ros_domain_id": 300.0})).unwrap_err();
        assert!(e.starts_with("ros_domain_id"), "{e}");
        let e = open(json!({"source": "ros2:/cam/image", "dds_network": ["lo"]})).unwrap_err();
        assert!(e.contains("not an IP address: \"lo\""), "{e}");
        let simulated = config(json!({"stall_timeout_s": 1.0}));
        let e = only_for(&SourceKind::Simulated, &simulated).unwrap_err();
        assert!(e.starts_with("stall_timeout_s: not a key"), "{e}");
    }
}
