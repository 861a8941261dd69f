//! Real video sources for skein's camera plugin.
//!
//! Every real source runs on a thread of its own behind the same handle
//! ([`input::VideoInput`]): the newest decoded frame, its capture time, and the source's
//! health ([`status`]: connecting, streaming, stalled or failed, frames decoded and frames
//! dropped by reason), reopened with backoff when it fails.
//!
//! - A gimbal camera of the kind observation UAVs carry streams H.264 over RTSP on the
//!   companion computer's Ethernet: [`rtsp::start`] opens such a stream (TCP or UDP
//!   transport), decodes it with OpenH264 ([`h264`]) and stamps each frame with its
//!   capture time from the stream's own timestamps ([`clock`]).
//! - A team with a ROS 2 camera driver publishes `sensor_msgs/CompressedImage` or
//!   `sensor_msgs/Image`: [`ros2::start`] subscribes (feature `ros2`), [`image_msg`]
//!   decodes the JPEG, PNG or raw pixels, the header's stamp gives the capture time.
//! - A USB (UVC) or CSI camera on the companion computer is a V4L2 device (`/dev/video0`):
//!   [`v4l2::start`] negotiates MJPEG or YUYV (or raw RGB, BGR, grey), streams it through
//!   mmap buffers and converts each frame to RGB.
//!
//! The camera plugin takes the newest frame, corrects a calibrated lens ([`rectify`]) or
//! scales it ([`scale`]), adds the pose the vehicle and gimbal had at the capture time and
//! publishes it as a JPEG like the simulated camera's.
//!
//! Everything here runs on the source's own thread or is called by the camera; nothing
//! blocks the vehicle.

pub mod clock;
pub mod h264;
pub mod image_msg;
pub mod input;
pub mod recent;
pub mod rectify;
#[cfg(feature = "ros2")]
pub mod ros2;
pub mod rtsp;
pub mod scale;
pub mod status;
pub mod v4l2;
