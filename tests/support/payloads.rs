//! Helpers of the payload end-to-end tests: a config file in a scratch directory, and
//! the payload and plugin listings of the HTTP API.

use super::{Skein, eventually};
use serde_json::Value;
use std::path::Path;
use std::time::Duration;

/// Writes `text` as `skein.toml` in `dir`; returns its path.
pub fn write_config(dir: &Path, text: &str) -> String {
    let path = dir.join("skein.toml");
    std::fs::write(&path, text).unwrap();
    path.to_str().unwrap().to_string()
}

/// The payload in `slot` of `vehicle` as `GET …/payloads` lists it now, or why not.
pub fn try_payload(skein: &Skein, vehicle: &str, slot: &str) -> Result<Value, String> {
    let (status, list) = skein.get(&format!("/api/v1/vehicles/{vehicle}/payloads"));
    if status != 200 {
        return Err(format!("{status}: {list}"));
    }
    list.as_array()
        .and_then(|l| l.iter().find(|p| p["slot"] == slot).cloned())
        .ok_or_else(|| format!("{vehicle} has no payload `{slot}` (yet): {list}"))
}

/// The payload in `slot` of `vehicle` as `GET …/payloads` shows it (waits for the first
/// snapshot that lists it).
pub fn payload(skein: &Skein, vehicle: &str, slot: &str) -> Value {
    eventually(
        &format!("{vehicle}/{slot} listed"),
        Duration::from_secs(10),
        || try_payload(skein, vehicle, slot),
    )
}

/// `GET /api/v1/plugins` (asserting a 200).
pub fn plugins(skein: &Skein) -> Value {
    let (status, v) = skein.get("/api/v1/plugins");
    assert_eq!(status, 200, "{v}");
    v
}

/// The current (not superseded) library called `name`.
pub fn library(listing: &Value, name: &str) -> Option<Value> {
    listing["libraries"]
        .as_array()?
        .iter()
        .find(|l| l["name"] == name && l["status"] == "loaded")
        .cloned()
}

/// Checks the SOI and EOI markers, decodes the whole image with `jpeg-decoder` and returns
/// its size (width, height), pixels.
pub fn jpeg_size(jpeg: &[u8]) -> (u16, u16) {
    assert!(jpeg.len() > 4, "{} bytes is no JPEG", jpeg.len());
    assert_eq!(&jpeg[..2], &[0xFF, 0xD8], "no SOI marker");
    assert_eq!(&jpeg[jpeg.len() - 2..], &[0xFF, 0xD9], "no EOI marker");
    let mut decoder = jpeg_decoder::Decoder::new(jpeg);
    decoder.decode().expect("the snapshot decodes as JPEG");
    let info = decoder.info().expect("JPEG info");
    (info.width, info.height)
}
