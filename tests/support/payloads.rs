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

/// The first `n` JPEG parts of the camera's MJPEG stream (`GET
/// /api/v1/vehicles/{vehicle}/payloads/{slot}/stream`, `multipart/x-mixed-replace`, what
/// the dashboard's `<img>` shows as video), each checked by [`jpeg_size`]; panics when
/// the stream breaks or gives fewer within 20 s.
pub fn mjpeg_parts(skein: &Skein, vehicle: &str, slot: &str, n: usize) -> Vec<Vec<u8>> {
    use std::io::{BufRead, BufReader, Read};
    let path = format!("/api/v1/vehicles/{vehicle}/payloads/{slot}/stream");
    let (status, ctype, body) = skein.get_stream(&path);
    assert_eq!(status, 200, "{path}");
    assert!(ctype.starts_with("multipart/x-mixed-replace"), "{ctype}");
    let mut reader = BufReader::new(body);
    let mut parts = Vec::new();
    let mut length = None;
    let mut line = String::new();
    while parts.len() < n {
        line.clear();
        let read = reader.read_line(&mut line).expect("the stream goes on");
        assert!(read > 0, "the stream ended after {} parts", parts.len());
        let l = line.trim_end();
        if let Some(v) = l.strip_prefix("Content-Length: ") {
            length = Some(v.parse::<usize>().expect("a length"));
        } else if l.is_empty()
            && let Some(len) = length.take()
        {
            let mut jpeg = vec![0; len];
            reader.read_exact(&mut jpeg).expect("a whole part");
            jpeg_size(&jpeg);
            parts.push(jpeg);
        }
    }
    parts
}
