//! A ROS 2 camera node's image topic as a source of decoded frames (`source =
//! "ros2:/camera/image_raw/compressed"`): a DDS participant of the camera's own (ros2-client
//! on RustDDS, node `/skein/camera`) subscribes to the topic, best-effort and keep-last
//! (ROS 2's sensor-data QoS, which matches reliable and best-effort publishers alike),
//! and decodes each sample ([`crate::image_msg`]).
//!
//! Which message: image_transport's convention. A topic whose name ends in
//! `/compressed` carries `sensor_msgs/CompressedImage` (JPEG or PNG), any other
//! `sensor_msgs/Image` (raw `rgb8`, `bgr8`, `rgba8`, `bgra8`, `mono8`).
//!
//! The capture time is the message header's `stamp` (the driver's capture time on the
//! companion computer's clock); a zero stamp, or one more than [`MAX_STAMP_SKEW`] from
//! the arrival, is replaced by the arrival time less the configured latency.
//!
//! A sample that cannot be read (not CDR of that type) is counted `malformed`, one that
//! does not decode `decode_error`; no frame for the stall timeout is reported (`stalled`
//! once frames came, else `failed`, naming the topic and why the last sample gave no
//! frame) while the subscription goes on waiting. A participant that cannot be made is retried with backoff.

use crate::clock::wall_us;
use crate::image_msg::{ImageError, decode_compressed, decode_raw};
use crate::input::{Shared, VideoInput, runtime};
use crate::scale::RgbFrame;
use ros2_client::builtin_interfaces::Time;
use ros2_client::dds::rustdds::DomainParticipantBuilder;
use ros2_client::qos::{Durability, History};
use ros2_client::{
    Context, MessageTypeName, Name, NodeName, NodeOptions, QosProfile, Subscription,
};
use serde::Deserialize;
use std::net::IpAddr;
use std::time::{Duration, Instant};

/// A header stamp further than this from the sample's arrival is not taken for the
/// capture time (a camera node on another host whose clock is not synchronised).
pub const MAX_STAMP_SKEW: Duration = Duration::from_secs(5);

/// `std_msgs/Header`.
#[derive(Debug, Clone, Deserialize)]
pub struct Header {
    /// Capture time (`builtin_interfaces/Time`).
    pub stamp: Time,
    /// The camera's optical frame.
    pub frame_id: String,
}

/// `sensor_msgs/CompressedImage` (Jazzy): `format` is `"jpeg"`, `"png"` or
/// image_transport's `"bgr8; jpeg compressed bgr8"`.
#[derive(Debug, Clone, Deserialize)]
pub struct CompressedImage {
    /// Header.
    pub header: Header,
    /// The codec.
    pub format: String,
    /// The compressed image.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}

/// `sensor_msgs/Image` (Jazzy): raw pixels, rows `step` bytes apart.
#[derive(Debug, Clone, Deserialize)]
pub struct Image {
    /// Header.
    pub header: Header,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// `sensor_msgs/image_encodings` name (`rgb8`, `bgr8`, `mono8` …).
    pub encoding: String,
    /// 1 when multi-byte values are big-endian (none of the 8-bit encodings read here
    /// depends on it).
    pub is_bigendian: u8,
    /// Bytes per row.
    pub step: u32,
    /// The pixels.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}

/// What the source subscribes to.
#[derive(Debug, Clone, PartialEq)]
pub struct Ros2Config {
    /// The topic's full ROS 2 name (`/camera/image_raw/compressed`).
    pub topic: String,
    /// DDS domain (`ROS_DOMAIN_ID`, 0–232).
    pub domain_id: u16,
    /// Local addresses DDS may use (RustDDS `with_only_networks`); empty: every
    /// interface.
    pub networks: Vec<IpAddr>,
    /// No frame for this long: reported stalled (the subscription goes on).
    pub stall_timeout: Duration,
    /// Time from capture to arrival, ms, for samples whose stamp is not used.
    pub latency_ms: f64,
}

impl Ros2Config {
    /// Checks a ROS 2 topic name (`/camera/image_raw`: absolute, ROS 2 name rules).
    ///
    /// # Errors
    /// Not an absolute name, or not a valid ROS 2 name, with the reason.
    pub fn check_topic(topic: &str) -> Result<(), String> {
        if !topic.starts_with('/') {
            return Err(format!(
                "a ROS 2 image topic is an absolute name (\"/camera/image_raw\"), got \"{topic}\""
            ));
        }
        Name::parse(topic)
            .map(|_| ())
            .map_err(|e| format!("not a ROS 2 topic name ({e:?}): \"{topic}\""))
    }

    /// True when the topic carries `sensor_msgs/CompressedImage` (its name ends in
    /// `/compressed`).
    pub fn compressed(&self) -> bool {
        self.topic.ends_with("/compressed")
    }
}

/// Starts subscribing on a thread of its own.
///
/// # Errors
/// The thread could not be started.
pub fn start(config: Ros2Config) -> Result<VideoInput, String> {
    let url = format!("ros2:{}", config.topic);
    VideoInput::spawn("skein-ros2-image", url, "dds", move |shared| {
        if let Some(rt) = runtime(shared, "ROS 2 subscription") {
            rt.block_on(shared.sessions(|| session(shared, &config), |why| why));
        }
    })
}

/// The capture time of a sample stamped `stamp` that arrived at `arrival_us`.
fn capture_us(stamp: Time, arrival_us: u64, latency_ms: f64) -> u64 {
    let stamp_us = (stamp.to_nanos() / 1000).max(0) as u64;
    if stamp_us > 0 && stamp_us.abs_diff(arrival_us) <= MAX_STAMP_SKEW.as_micros() as u64 {
        stamp_us
    } else {
        arrival_us.saturating_sub((latency_ms * 1000.0) as u64)
    }
}

/// The message type the topic carries.
fn sample_type(config: &Ros2Config) -> &'static str {
    if config.compressed() {
        "sensor_msgs/CompressedImage"
    } else {
        "sensor_msgs/Image"
    }
}

/// Counts `e` in the source's drops.
fn dropped(shared: &Shared, e: &ImageError) {
    match e {
        ImageError::Unsupported(_) => shared.count(|d| d.malformed += 1),
        ImageError::Corrupt(_) => shared.count(|d| d.decode_error += 1),
    }
}

/// One participant and subscription, read until the camera drops the source.
async fn session(shared: &Shared, config: &Ros2Config) -> Result<(), String> {
    let mut participant = DomainParticipantBuilder::new(config.domain_id);
    if !config.networks.is_empty() {
        participant = participant.with_only_networks(config.networks.iter().copied());
    }
    let participant = participant
        .build()
        .map_err(|e| format!("DDS participant on domain {}: {e}", config.domain_id))?;
    let context = Context::from_domain_participant(participant)
        .map_err(|e| format!("ROS 2 context: {e:?}"))?;
    let mut node = context
        .new_node(
            NodeName::new("/skein", "camera").map_err(|e| format!("node name: {e:?}"))?,
            NodeOptions::new().enable_rosout(false),
        )
        .map_err(|e| format!("ROS 2 node: {e:?}"))?;
    let name = Name::parse(&config.topic).map_err(|e| format!("{}: {e:?}", config.topic))?;
    let qos = QosProfile::subscription_default()
        .reliability_best_effort()
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 2 });
    let type_name = if config.compressed() {
        MessageTypeName::new("sensor_msgs", "CompressedImage")
    } else {
        MessageTypeName::new("sensor_msgs", "Image")
    };
    let topic = node
        .create_topic(&name, type_name, &qos)
        .map_err(|e| format!("topic {}: {e:?}", config.topic))?;
    if config.compressed() {
        let sub: Subscription<CompressedImage> = node
            .create_subscription(&topic, None)
            .map_err(|e| format!("subscription to {}: {e:?}", config.topic))?;
        read(shared, config, &sub, |m: CompressedImage| {
            (m.header.stamp, decode_compressed(&m.format, &m.data))
        })
        .await
    } else {
        let sub: Subscription<Image> = node
            .create_subscription(&topic, None)
            .map_err(|e| format!("subscription to {}: {e:?}", config.topic))?;
        read(shared, config, &sub, |m: Image| {
            let frame = decode_raw(&m.encoding, m.width, m.height, m.step, &m.data);
            (m.header.stamp, frame)
        })
        .await
    }
}

/// Takes `sub`'s samples, decodes them with `decode` and publishes the frames.
async fn read<M: serde::de::DeserializeOwned + 'static>(
    shared: &Shared,
    config: &Ros2Config,
    sub: &Subscription<M>,
    decode: impl Fn(M) -> (Time, Result<RgbFrame, ImageError>),
) -> Result<(), String> {
    // Why the last sample since the last frame gave none, for the stall's reason.
    let mut last_error: Option<String> = None;
    // The stall clock: reset by every decoded frame (samples that give none do not count)
    // and by every report of a stall.
    let mut since = Instant::now();
    loop {
        let deadline = since + config.stall_timeout;
        let sample = match tokio::time::timeout_at(deadline.into(), sub.async_take()).await {
            Err(_) => {
                since = Instant::now();
                let why = last_error
                    .as_deref()
                    .map_or(String::new(), |e| format!(" (the last sample: {e})"));
                shared.lost(format!(
                    "no image on {} for {:.1} s{why}",
                    config.topic,
                    config.stall_timeout.as_secs_f64()
                ));
                continue;
            }
            Ok(Err(e)) => {
                shared.count(|d| d.malformed += 1);
                last_error = Some(format!("not a {}: {e:?}", sample_type(config)));
                continue;
            }
            Ok(Ok((m, _info))) => m,
        };
        let arrival_us = wall_us();
        match decode(sample) {
            (stamp, Ok(frame)) => {
                last_error = None;
                since = Instant::now();
                shared.publish(frame, capture_us(stamp, arrival_us, config.latency_ms));
            }
            (_, Err(e)) => {
                dropped(shared, &e);
                last_error = Some(e.to_string());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn topics_are_checked_and_tell_their_message() {
        assert!(Ros2Config::check_topic("/camera/image_raw/compressed").is_ok());
        let e = Ros2Config::check_topic("camera/image_raw").unwrap_err();
        assert!(e.contains("absolute"), "{e}");
        assert!(Ros2Config::check_topic("/camera/bad name").is_err());
        let mut c = Ros2Config {
            topic: "/camera/image_raw/compressed".into(),
            domain_id: 0,
            networks: vec![],
            stall_timeout: Duration::from_secs(1),
            latency_ms: 0.0,
        };
        assert!(c.compressed());
        c.topic = "/camera/image_raw".into();
        assert!(!c.compressed());
    }

    #[test]
    fn the_stamp_is_the_capture_time_unless_it_is_zero_or_far_off() {
        let arrival = 1_700_000_000_000_000u64;
        let stamp = Time::from_nanos((arrival as i64 - 40_000) * 1000);
        assert_eq!(capture_us(stamp, arrival, 10.0), arrival - 40_000);
        assert_eq!(capture_us(Time::ZERO, arrival, 10.0), arrival - 10_000);
        let skewed = Time::from_nanos((arrival as i64 - 60_000_000) * 1000);
        assert_eq!(capture_us(skewed, arrival, 0.0), arrival);
    }
}
