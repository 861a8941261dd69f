//! Real video sources for skein's camera plugin.
//!
//! A gimbal camera of the kind observation UAVs carry streams H.264 over RTSP on the
//! companion computer's Ethernet. [`rtsp::RtspSource`] opens such a stream (TCP or UDP
//! transport), decodes it with OpenH264 ([`h264`]), stamps each frame with its capture
//! time from the stream's own timestamps ([`clock`]), and reports its health
//! ([`status`]): connecting, streaming, stalled or failed, frames decoded and frames
//! dropped by reason. The camera plugin takes the newest frame, corrects a calibrated lens
//! ([`rectify`]) or scales it ([`scale`]),
//! adds the pose the vehicle and gimbal had at the capture time and publishes it as a
//! JPEG like the simulated camera's.
//!
//! Everything here runs on the source's own thread or is called by the camera; nothing
//! blocks the vehicle.

pub mod clock;
pub mod h264;
pub mod recent;
pub mod rectify;
pub mod rtsp;
pub mod scale;
pub mod status;
