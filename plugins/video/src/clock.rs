//! Capture times of a stream's frames from its own timestamps.
//!
//! An RTP timestamp (90 kHz for video, RFC 6184) says when the camera sampled each frame
//! relative to the others, not when in wall-clock time. The first frame's arrival alone
//! would carry that one frame's network and decoder delay into every stamp; instead the
//! clock keeps the smallest `arrival - media_time` seen in the session (the fastest
//! delivery, the least delayed frame) as the offset, so jitter never moves a stamp later,
//! and subtracts the camera's own latency (sensor to encoder output, from the config or
//! the camera's datasheet), which no receiver can measure.

/// Wall-clock µs since the Unix epoch (0 before it): the unit of every capture time here
/// and of the frames' `stamp_us`.
pub fn wall_us() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as u64)
}

/// Maps media times (seconds since the session's first frame) to wall-clock capture times
/// (µs since the Unix epoch). One per session: a new session restarts the media clock.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CaptureClock {
    latency_us: i64,
    offset_us: Option<i64>,
}

impl CaptureClock {
    /// A clock for a camera whose frames leave it `latency_ms` after capture.
    pub fn new(latency_ms: f64) -> Self {
        CaptureClock {
            latency_us: (latency_ms * 1000.0).round() as i64,
            offset_us: None,
        }
    }

    /// The capture time of a frame with media time `media_s` that arrived at `arrival_us`
    /// (wall clock, µs since the epoch). Never later than the arrival less the latency.
    pub fn capture_us(&mut self, media_s: f64, arrival_us: u64) -> u64 {
        let media_us = (media_s * 1e6).round() as i64;
        let offset = arrival_us as i64 - media_us;
        let best = self.offset_us.map_or(offset, |o| o.min(offset));
        self.offset_us = Some(best);
        (best + media_us - self.latency_us).max(0) as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jitter_never_moves_a_stamp_later_and_latency_is_subtracted() {
        let mut c = CaptureClock::new(50.0);
        let t0 = 1_700_000_000_000_000u64;
        // Frames every 40 ms; the first arrives 30 ms late, the second on time.
        assert_eq!(c.capture_us(0.0, t0 + 30_000), t0 - 20_000);
        assert_eq!(c.capture_us(0.04, t0 + 40_000), t0 + 40_000 - 50_000);
        // A frame delayed 100 ms by the network keeps its media time's stamp.
        assert_eq!(c.capture_us(0.08, t0 + 180_000), t0 + 80_000 - 50_000);
    }
}
