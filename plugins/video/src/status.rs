//! What a real video source reports about itself: its state (connecting, streaming,
//! stalled, failed), the frames it decoded and the frames it dropped, by reason.

use serde::Serialize;

/// The state of a real video source, as the camera's `source_status.state` shows it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SourceState {
    /// Opening the source (RTSP `DESCRIBE`/`SETUP`/`PLAY`, a DDS subscription, a V4L2
    /// device), first time or after a retry.
    Connecting,
    /// Frames arrive and decode.
    Streaming,
    /// The source was streaming but no frame decoded within the stall timeout; an RTSP or
    /// V4L2 source closes the session and reopens it with backoff, a ROS 2 subscription
    /// stays and waits. The dashboard shows the camera as
    /// stalled rather than its last image.
    Stalled,
    /// The stream could not be opened (refused, unreachable, a codec this build does not
    /// decode); retried with backoff.
    Failed,
}

/// Frames (or parts of them) dropped, by reason. Every count only grows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct Dropped {
    /// Frames the decoder refused: H.264 access units (a corrupt or truncated bitstream)
    /// after the session's first picture, JPEG or PNG images that do not decode.
    pub decode_error: u64,
    /// Access units refused before the session's first picture: a session joins a stream
    /// between key frames, and the frames up to the next one refer to pictures it never
    /// received.
    pub before_key_frame: u64,
    /// Frames that are no image of their kind: access units with no Annex B start code or
    /// an empty payload, ROS 2 samples that are not the topic's message (not its CDR) or
    /// name an unsupported `format`/`encoding` or a size their data does not hold.
    pub malformed: u64,
    /// RTP packets lost before a frame (sequence number gaps, RFC 3550).
    pub lost_packets: u64,
    /// Items the RTSP library could not depacketize (garbage on the socket, a broken
    /// fragmentation unit); the session goes on where the library allows.
    pub depacketize_error: u64,
    /// Decoded frames the camera never took because a newer one replaced them.
    pub superseded: u64,
}

/// A snapshot of a real source's health, serialised into the camera's state as
/// `source_status`:
/// `{"state": "streaming", "url": "rtsp://cam:8554/main", "transport": "tcp",
///   "detail": null, "frames_decoded": 120, "dropped": {...}, "sessions": 1,
///   "stream_width_px": 1280, "stream_height_px": 720, "stream_rate_hz": 25.0,
///   "last_frame_age_ms": 38}`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StreamStatus {
    /// The state.
    pub state: SourceState,
    /// The source's address, without credentials (`rtsp://…`, `ros2:/topic`,
    /// `v4l2:/dev/video0`).
    pub url: String,
    /// How frames arrive: RTP over `"tcp"` (interleaved on the RTSP connection) or
    /// `"udp"`, `"dds"` (a ROS 2 topic), `"mmap"` (V4L2 buffers).
    pub transport: &'static str,
    /// Why the source is not streaming (the last error), `null` while it streams.
    pub detail: Option<String>,
    /// Frames decoded since the source started.
    pub frames_decoded: u64,
    /// Frames dropped, by reason.
    pub dropped: Dropped,
    /// Sessions opened (RTSP connections, DDS participants, device openings: the first
    /// plus every reconnection).
    pub sessions: u64,
    /// Size of the decoded stream, pixels (`null` before the first frame).
    pub stream_width_px: Option<u32>,
    /// Height of the decoded stream, pixels.
    pub stream_height_px: Option<u32>,
    /// Decoded frames per second over the last few seconds (`null` before two frames).
    pub stream_rate_hz: Option<f64>,
    /// Milliseconds since the last decoded frame (`null` before the first).
    pub last_frame_age_ms: Option<u64>,
}
