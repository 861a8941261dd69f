//! A field's tiles for the map tests: an MBTiles file (the format GDAL writes, rows in
//! TMS order) of solid-colour JPEG tiles whose colour says which tile it is, written here
//! with SQLite, so a test (and the browser) can tell from a pixel which tile lies under
//! it: red `24 + 8·(x mod 16)`, green `24 + 8·(y mod 16)` (XYZ row, from the north), blue
//! `24 + 8·(z mod 16)` (dark, so the plan stays readable on them). A hole can be left at
//! one point: no tile holds it at any zoom.

use std::path::Path;

/// The colour of XYZ tile (z, x, y).
pub fn tile_colour(z: u8, x: u32, y: u32) -> [u8; 3] {
    let c = |v: u32| 24 + 8 * (v % 16) as u8;
    [c(x), c(y), c(u32::from(z))]
}

/// The XYZ tile holding (lat, lon) at zoom z (Web Mercator).
pub fn tile_of(lat_deg: f64, lon_deg: f64, z: u8) -> (u32, u32) {
    let n = f64::from(1u32 << z);
    let x = ((lon_deg + 180.0) / 360.0 * n).floor();
    let r = lat_deg.to_radians();
    let y = ((1.0 - (r.tan() + 1.0 / r.cos()).ln() / std::f64::consts::PI) / 2.0 * n).floor();
    (x as u32, y as u32)
}

fn jpeg(rgb: [u8; 3]) -> Vec<u8> {
    let mut pixels = vec![0u8; 256 * 256 * 3];
    for p in pixels.chunks_exact_mut(3) {
        p.copy_from_slice(&rgb);
    }
    let mut out = Vec::new();
    jpeg_encoder::Encoder::new(&mut out, 95)
        .encode(&pixels, 256, 256, jpeg_encoder::ColorType::Rgb)
        .expect("encode a tile");
    out
}

/// Degrees of latitude and longitude per metre at `lat_deg` (a sphere is plenty for
/// choosing tiles).
fn deg_per_m(lat_deg: f64) -> (f64, f64) {
    let m = 111_195.0;
    (1.0 / m, 1.0 / (m * lat_deg.to_radians().cos()))
}

/// Writes `path`: for each `(zoom, half_m)` of `zooms`, every tile of that zoom level
/// within `half_m` metres (each way) of `centre` (lat, lon), except those holding `hole`
/// (lat, lon) if given. Returns the number of tiles.
pub fn write_mbtiles(
    path: &Path,
    centre: (f64, f64),
    zooms: &[(u8, f64)],
    hole: Option<(f64, f64)>,
) -> usize {
    let _ = std::fs::remove_file(path);
    let db = rusqlite::Connection::open(path).expect("create the MBTiles file");
    db.execute_batch(
        "CREATE TABLE metadata (name TEXT, value TEXT);
         CREATE TABLE tiles (zoom_level INTEGER, tile_column INTEGER, tile_row INTEGER,
                             tile_data BLOB);
         CREATE UNIQUE INDEX tile_index ON tiles (zoom_level, tile_column, tile_row);",
    )
    .expect("schema");
    let (dlat, dlon) = deg_per_m(centre.0);
    let extent = |half_m: f64| {
        (
            centre.0 + half_m * dlat,
            centre.0 - half_m * dlat,
            centre.1 - half_m * dlon,
            centre.1 + half_m * dlon,
        )
    };
    let widest = zooms.iter().map(|z| z.1).fold(0.0, f64::max);
    let (n, s, w, e) = extent(widest);
    let bounds = format!("{w},{s},{e},{n}");
    let min_zoom = zooms.iter().map(|z| z.0).min().unwrap_or(0);
    let max_zoom = zooms.iter().map(|z| z.0).max().unwrap_or(0);
    for (k, v) in [
        ("name", "test field"),
        ("format", "jpg"),
        ("bounds", bounds.as_str()),
        ("minzoom", &min_zoom.to_string()),
        ("maxzoom", &max_zoom.to_string()),
        ("attribution", "test tiles: colour = tile"),
    ] {
        db.execute("INSERT INTO metadata VALUES (?1, ?2)", (k, v))
            .expect("metadata");
    }
    let mut count = 0;
    let tx = db.unchecked_transaction().expect("transaction");
    for &(z, half_m) in zooms {
        let (north, south, west, east) = extent(half_m);
        let (x0, y0) = tile_of(north, west, z);
        let (x1, y1) = tile_of(south, east, z);
        let skip = hole.map(|(lat, lon)| tile_of(lat, lon, z));
        for x in x0..=x1 {
            for y in y0..=y1 {
                if skip == Some((x, y)) {
                    continue;
                }
                let tms_row = (1u32 << z) - 1 - y;
                tx.execute(
                    "INSERT INTO tiles VALUES (?1, ?2, ?3, ?4)",
                    (z, x, tms_row, jpeg(tile_colour(z, x, y))),
                )
                .expect("tile");
                count += 1;
            }
        }
    }
    tx.commit().expect("commit");
    count
}
