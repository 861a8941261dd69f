//! A folder of tiles, `z/x/y.png` (or `.jpg`, `.jpeg`, `.webp`), as `gdal2tiles.py --xyz`
//! and most tile downloaders write them. An optional `metadata.json` beside the zoom
//! folders says what MBTiles' metadata would (`name`, `bounds` as `[w, s, e, n]` or
//! `"w,s,e,n"`, `minzoom`, `maxzoom`, `attribution`) and, as TileJSON's `scheme`,
//! whether rows count from the south (`"tms"`, gdal2tiles' default without `--xyz`).

use super::MapInfo;
use super::mbtiles::tms_row;
use serde_json::Value;
use std::path::{Path, PathBuf};

/// Tile file extensions tried, in order.
const EXTENSIONS: [&str; 4] = ["png", "jpg", "jpeg", "webp"];

/// A `z/x/y` tile folder.
pub struct TileFolder {
    root: PathBuf,
    tms: bool,
    /// What it holds (the tile URL is set by the caller).
    pub info: MapInfo,
}

fn bounds_of(v: &Value) -> Option<[f64; 4]> {
    let nums: Vec<f64> = match v {
        Value::Array(a) => a.iter().filter_map(Value::as_f64).collect(),
        Value::String(s) => s.split(',').filter_map(|p| p.trim().parse().ok()).collect(),
        _ => return None,
    };
    let b: [f64; 4] = nums.try_into().ok()?;
    (b[0] < b[2] && b[1] < b[3]).then_some(b)
}

impl TileFolder {
    /// Opens `root`: its numeric sub-folders are the zoom levels.
    ///
    /// # Errors
    /// No zoom folder in it, or a `metadata.json` that is not JSON.
    pub fn open(root: &Path) -> Result<Self, String> {
        let zooms: Vec<u8> = std::fs::read_dir(root)
            .map_err(|e| e.to_string())?
            .filter_map(|e| e.ok())
            .filter(|e| e.path().is_dir())
            .filter_map(|e| e.file_name().to_str()?.parse::<u8>().ok())
            .filter(|z| *z <= 24)
            .collect();
        let (Some(&lo), Some(&hi)) = (zooms.iter().min(), zooms.iter().max()) else {
            return Err("no z/x/y tile folders in it (0/, 1/, … holding x/y.png)".into());
        };
        let meta_path = root.join("metadata.json");
        let meta: Value = if meta_path.exists() {
            let text = std::fs::read_to_string(&meta_path).map_err(|e| e.to_string())?;
            serde_json::from_str(&text).map_err(|e| format!("metadata.json: {e}"))?
        } else {
            Value::Null
        };
        let zoom = |key: &str| {
            meta.get(key)
                .and_then(|v| v.as_u64().or_else(|| v.as_str()?.trim().parse().ok()))
                .filter(|z| *z <= 24)
                .map(|z| z as u8)
        };
        let info = MapInfo {
            source: "folder".into(),
            tile_url: None,
            min_zoom: zoom("minzoom").unwrap_or(lo).min(lo),
            max_zoom: zoom("maxzoom").unwrap_or(hi).max(hi),
            bounds: meta.get("bounds").and_then(bounds_of),
            attribution: meta
                .get("attribution")
                .and_then(Value::as_str)
                .map(str::to_string),
            name: meta
                .get("name")
                .and_then(Value::as_str)
                .map(str::to_string)
                .or_else(|| root.file_name().map(|n| n.to_string_lossy().into_owned())),
        };
        Ok(TileFolder {
            root: root.to_path_buf(),
            tms: meta.get("scheme").and_then(Value::as_str) == Some("tms"),
            info,
        })
    }

    /// The tile at XYZ `z`/`x`/`y`, if the folder has it.
    ///
    /// # Errors
    /// A file that exists but cannot be read.
    pub fn tile(&self, z: u8, x: u32, y: u32) -> Result<Option<Vec<u8>>, String> {
        let row = if self.tms { tms_row(z, y) } else { y };
        for ext in EXTENSIONS {
            let p = self.root.join(format!("{z}/{x}/{row}.{ext}"));
            match std::fs::read(&p) {
                Ok(bytes) => return Ok(Some(bytes)),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
                Err(e) => return Err(format!("{}: {e}", p.display())),
            }
        }
        Ok(None)
    }
}
