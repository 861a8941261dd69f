//! What the link knows of a vehicle's events: where its metadata came from, and how the
//! events arrived (the telemetry's `px4_events`).

use serde::Serialize;

/// The events metadata in use.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct MetadataInfo {
    /// CRC of the general metadata (`COMPONENT_METADATA.file_crc`).
    pub general_crc: u32,
    /// CRC of the events metadata (its `fileCrc`).
    pub events_crc: u32,
    /// `"vehicle"` (read over MAVLink FTP) or `"cache"` (read from the cache directory).
    pub source: &'static str,
    /// Bytes read over MAVLink FTP for it (both files, as sent: xz-compressed); 0 from
    /// the cache.
    pub ftp_bytes: usize,
    /// FTP requests sent for it (first transmissions and retries); 0 from the cache.
    pub ftp_requests: u32,
    /// From `COMPONENT_METADATA` to the metadata parsed, milliseconds.
    pub fetch_ms: u64,
    /// Events the metadata describes.
    pub events: usize,
}

/// The events of one vehicle.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct EventsStatus {
    /// The metadata in use, once loaded.
    pub metadata: Option<MetadataInfo>,
    /// Why there is none (the vehicle has none, a failed read).
    pub metadata_error: Option<String>,
    /// `EVENT`s received (repeats included).
    pub received: u64,
    /// Events asked for again (`REQUEST_EVENT`).
    pub requested: u64,
    /// Events given up as lost.
    pub lost: u64,
    /// Events the metadata does not describe (dropped).
    pub unknown: u64,
}
