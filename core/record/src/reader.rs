//! Reading a recording back: every message of an MCAP file written by [`crate::Recorder`]
//! (or any MCAP file with JSON messages), in log-time order, for `skein replay`.

use serde_json::Value;
use std::path::Path;

/// One recorded message.
#[derive(Debug, Clone)]
pub struct Recorded {
    /// Log time, ns since the Unix epoch.
    pub time_ns: u64,
    /// Channel topic (`/skein/uav-1/state`).
    pub topic: String,
    /// Schema name (`skein.VehicleState`, `foxglove.CompressedImage`, ...).
    pub schema: String,
    /// The message.
    pub value: Value,
}

/// Why a file cannot be replayed.
#[derive(Debug, Clone, PartialEq)]
pub enum ReplayError {
    /// The file cannot be read.
    Io(String),
    /// The file is not valid MCAP (the reader's message).
    Mcap(String),
    /// The file holds no JSON message.
    Empty,
}

impl std::fmt::Display for ReplayError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ReplayError::Io(e) => write!(f, "{e}"),
            ReplayError::Mcap(e) => write!(f, "not a valid MCAP file: {e}"),
            ReplayError::Empty => write!(f, "the recording holds no JSON message"),
        }
    }
}

impl std::error::Error for ReplayError {}

/// Every JSON message of a recording, sorted by log time.
#[derive(Debug, Clone)]
pub struct Timeline {
    /// The messages.
    pub messages: Vec<Recorded>,
    /// Messages that were not JSON, skipped.
    pub skipped: usize,
}

impl Timeline {
    /// Reads `path`.
    ///
    /// # Errors
    /// [`ReplayError`] when the file cannot be read, is not MCAP, or holds nothing to
    /// replay.
    pub fn load(path: &Path) -> Result<Timeline, ReplayError> {
        let bytes = std::fs::read(path)
            .map_err(|e| ReplayError::Io(format!("cannot read {}: {e}", path.display())))?;
        Timeline::from_bytes(&bytes)
    }

    /// Reads an MCAP file held in memory.
    ///
    /// # Errors
    /// As [`Timeline::load`].
    pub fn from_bytes(bytes: &[u8]) -> Result<Timeline, ReplayError> {
        let stream =
            mcap::MessageStream::new(bytes).map_err(|e| ReplayError::Mcap(e.to_string()))?;
        let mut messages = Vec::new();
        let mut skipped = 0;
        for m in stream {
            let m = m.map_err(|e| ReplayError::Mcap(e.to_string()))?;
            if m.channel.message_encoding != crate::channels::MESSAGE_ENCODING {
                skipped += 1;
                continue;
            }
            let Ok(value) = serde_json::from_slice::<Value>(&m.data) else {
                skipped += 1;
                continue;
            };
            messages.push(Recorded {
                time_ns: m.log_time,
                topic: m.channel.topic.clone(),
                schema: m
                    .channel
                    .schema
                    .as_ref()
                    .map_or(String::new(), |s| s.name.clone()),
                value,
            });
        }
        if messages.is_empty() {
            return Err(ReplayError::Empty);
        }
        messages.sort_by_key(|m| m.time_ns);
        Ok(Timeline { messages, skipped })
    }

    /// Time of the first message, ns since the Unix epoch.
    pub fn start_ns(&self) -> u64 {
        self.messages.first().map_or(0, |m| m.time_ns)
    }

    /// From the first to the last message, s.
    pub fn duration_s(&self) -> f64 {
        let end = self.messages.last().map_or(0, |m| m.time_ns);
        end.saturating_sub(self.start_ns()) as f64 * 1e-9
    }
}
