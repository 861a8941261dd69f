//! An MBTiles file (the MBTiles 1.3 specification): a SQLite database with a `metadata`
//! table (`name`, `format`, `bounds`, `minzoom`, `maxzoom`, `attribution` …) and a `tiles`
//! table (or view) of `zoom_level`, `tile_column`, `tile_row`, `tile_data`, whose rows
//! count from the *south* (TMS): XYZ row `y` is `tile_row = 2^z - 1 - y`. Opened read-only
//! and checked at start.

use super::MapInfo;
use rusqlite::{Connection, OpenFlags, OptionalExtension};
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Mutex;

/// An open MBTiles file.
pub struct MbTiles {
    db: Mutex<Connection>,
    /// What it holds (the tile URL is set by the caller).
    pub info: MapInfo,
}

/// The TMS row of XYZ row `y` at zoom `z`.
pub fn tms_row(z: u8, y: u32) -> u32 {
    (1u32 << z) - 1 - y
}

fn parse_bounds(s: &str) -> Option<[f64; 4]> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .ok()?;
    let b: [f64; 4] = v.try_into().ok()?;
    (b.iter().all(|x| x.is_finite()) && b[0] < b[2] && b[1] < b[3]).then_some(b)
}

impl MbTiles {
    /// Opens and checks `path`: a SQLite database with MBTiles' tables, raster tiles, at
    /// least one tile.
    ///
    /// # Errors
    /// Why it is not an MBTiles file skein can draw.
    pub fn open(path: &Path) -> Result<Self, String> {
        let not = |e: rusqlite::Error| format!("not an MBTiles file: {e}");
        let db = Connection::open_with_flags(
            path,
            OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
        )
        .map_err(not)?;
        let mut meta = BTreeMap::new();
        {
            let mut stmt = db
                .prepare("SELECT name, value FROM metadata")
                .map_err(not)?;
            let rows = stmt
                .query_map([], |r| Ok((r.get::<_, String>(0)?, r.get::<_, String>(1)?)))
                .map_err(not)?;
            for row in rows {
                let (k, v) = row.map_err(not)?;
                meta.insert(k, v);
            }
        }
        if let Some(f) = meta.get("format")
            && !matches!(f.as_str(), "png" | "jpg" | "jpeg" | "webp")
        {
            return Err(format!(
                "its tiles are `{f}`: skein draws raster tiles (png, jpg, webp)"
            ));
        }
        let (lo, hi): (Option<i64>, Option<i64>) = db
            .query_row(
                "SELECT MIN(zoom_level), MAX(zoom_level) FROM tiles",
                [],
                |r| Ok((r.get(0)?, r.get(1)?)),
            )
            .map_err(not)?;
        let (Some(lo), Some(hi)) = (lo, hi) else {
            return Err("it holds no tile".into());
        };
        if !(0..=24).contains(&lo) || !(0..=24).contains(&hi) {
            return Err(format!("zoom levels {lo} to {hi} outside 0 to 24"));
        }
        let zoom = |key: &str, found: i64| {
            meta.get(key)
                .and_then(|v| v.trim().parse::<i64>().ok())
                .filter(|z| (0..=24).contains(z))
                .unwrap_or(found) as u8
        };
        let info = MapInfo {
            source: "mbtiles".into(),
            tile_url: None,
            min_zoom: zoom("minzoom", lo).min(lo as u8),
            max_zoom: zoom("maxzoom", hi).max(hi as u8),
            bounds: meta.get("bounds").and_then(|b| parse_bounds(b)),
            attribution: meta.get("attribution").cloned().filter(|a| !a.is_empty()),
            name: meta
                .get("name")
                .cloned()
                .or_else(|| path.file_stem().map(|s| s.to_string_lossy().into_owned())),
        };
        Ok(MbTiles {
            db: Mutex::new(db),
            info,
        })
    }

    /// The tile at XYZ `z`/`x`/`y`, if the file has it.
    ///
    /// # Errors
    /// A read that failed (the file changed or broke under skein).
    pub fn tile(&self, z: u8, x: u32, y: u32) -> Result<Option<Vec<u8>>, String> {
        let db = self
            .db
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        db.query_row(
            "SELECT tile_data FROM tiles WHERE zoom_level = ?1 AND tile_column = ?2 AND tile_row = ?3",
            (i64::from(z), i64::from(x), i64::from(tms_row(z, y))),
            |r| r.get::<_, Vec<u8>>(0),
        )
        .optional()
        .map_err(|e| format!("reading tile {z}/{x}/{y}: {e}"))
    }
}
