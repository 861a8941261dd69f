//! The simulated PX4's component metadata (MAVLink's Component Metadata Protocol), as
//! PX4 v1.16 ships it in its ROMFS and serves it through MAVLink FTP:
//!
//! - `COMPONENT_METADATA` (397), sent on `MAV_CMD_REQUEST_MESSAGE`, names the general
//!   metadata: `uri` [`GENERAL_URI`] and `file_crc`, the CRC of the uncompressed JSON
//!   (`streams/COMPONENT_METADATA.hpp`).
//! - The general metadata (`component_general.json`, `generate_component_general.py`):
//!   `{"version": 1, "metadataTypes": [{"type", "uri", "fileCrc", "uriFallback"}]}`,
//!   here one entry, type 4 (`COMP_METADATA_TYPE_EVENTS`) at [`EVENTS_URI`], its
//!   `fileCrc` that of the uncompressed events JSON.
//! - The events metadata ([`crate::px4_events::events_metadata_json`]).
//!
//! Both files are xz-compressed (`.json.xz`, lzma-rs); CRCs are MAVLink's CRC32
//! ([`skein_mavlink::ftp::crc32`]). Built once per process ([`MetadataFiles::get`]).

use skein_mavlink::ftp::crc32;
use std::collections::HashMap;
use std::sync::OnceLock;

/// Where PX4 keeps the general metadata (`mftp://` = the vehicle's MAVLink FTP).
pub const GENERAL_URI: &str = "mftp://etc/extras/component_general.json.xz";
/// Where PX4 keeps the events metadata.
pub const EVENTS_URI: &str = "mftp://etc/extras/all_events.json.xz";
/// `COMP_METADATA_TYPE_EVENTS`.
pub const COMP_METADATA_TYPE_EVENTS: u32 = 4;

/// The metadata files of the simulated PX4, by FTP path.
#[derive(Debug)]
pub struct MetadataFiles {
    files: HashMap<String, Vec<u8>>,
    /// CRC of the uncompressed general metadata (`COMPONENT_METADATA.file_crc`).
    pub general_crc: u32,
    /// CRC of the uncompressed events metadata.
    pub events_crc: u32,
}

/// The FTP path of an `mftp://` URI (`etc/extras/x.json.xz`), without a leading `/`.
pub fn ftp_path(uri: &str) -> &str {
    uri.trim_start_matches("mftp://").trim_start_matches('/')
}

fn xz(bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    lzma_rs::xz_compress(&mut std::io::Cursor::new(bytes), &mut out)
        .expect("xz into memory does not fail");
    out
}

impl MetadataFiles {
    fn build() -> Self {
        let events =
            serde_json::to_vec(&crate::px4_events::events_metadata_json()).expect("serialisable");
        let events_crc = crc32(&events);
        let general = serde_json::to_vec(&serde_json::json!({
            "version": 1,
            "metadataTypes": [{
                "type": COMP_METADATA_TYPE_EVENTS,
                "uri": EVENTS_URI,
                "fileCrc": events_crc,
                "uriFallback": "",
            }],
        }))
        .expect("serialisable");
        let general_crc = crc32(&general);
        let files = HashMap::from([
            (ftp_path(GENERAL_URI).to_string(), xz(&general)),
            (ftp_path(EVENTS_URI).to_string(), xz(&events)),
        ]);
        MetadataFiles {
            files,
            general_crc,
            events_crc,
        }
    }

    /// The files, built on first use.
    pub fn get() -> &'static MetadataFiles {
        static FILES: OnceLock<MetadataFiles> = OnceLock::new();
        FILES.get_or_init(MetadataFiles::build)
    }

    /// The file at FTP `path` (a leading `/` or none).
    pub fn file(&self, path: &str) -> Option<&[u8]> {
        self.files
            .get(path.trim_start_matches('/'))
            .map(Vec::as_slice)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_general_metadata_lists_the_events_file_with_its_crc() {
        let m = MetadataFiles::get();
        let xz = m.file("/etc/extras/component_general.json.xz").unwrap();
        let mut json = Vec::new();
        lzma_rs::xz_decompress(&mut std::io::Cursor::new(xz), &mut json).unwrap();
        assert_eq!(crc32(&json), m.general_crc);
        let v: serde_json::Value = serde_json::from_slice(&json).unwrap();
        assert_eq!(v["metadataTypes"][0]["type"], 4);
        assert_eq!(v["metadataTypes"][0]["uri"], EVENTS_URI);
        assert_eq!(v["metadataTypes"][0]["fileCrc"], m.events_crc);
        let events = m.file(ftp_path(EVENTS_URI)).unwrap();
        assert_eq!(&events[..6], b"\xFD7zXZ\x00", "an xz stream");
    }
}
