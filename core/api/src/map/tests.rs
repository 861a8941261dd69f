//! Tile sets on disk: an MBTiles file written here (TMS rows), a z/x/y folder, a file
//! that is no MBTiles, vector tiles; and the media type from a tile's bytes.

use super::*;

const PNG: &[u8] = &[0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A, 1, 2, 3];
const JPEG: &[u8] = &[0xFF, 0xD8, 0xFF, 0xE0, 0, 1];

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("skein-map-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// An MBTiles file with `tiles` given as XYZ `(z, x, y, bytes)`.
fn mbtiles(path: &FsPath, format: &str, tiles: &[(u8, u32, u32, &[u8])]) {
    let db = rusqlite::Connection::open(path).unwrap();
    db.execute_batch(
        "CREATE TABLE metadata (name TEXT, value TEXT);
         CREATE TABLE tiles (zoom_level INTEGER, tile_column INTEGER, tile_row INTEGER, tile_data BLOB);",
    )
    .unwrap();
    for (k, v) in [
        ("name", "field"),
        ("format", format),
        ("bounds", "8.5,47.3,8.6,47.4"),
        ("attribution", "test tiles"),
    ] {
        db.execute("INSERT INTO metadata VALUES (?1, ?2)", (k, v))
            .unwrap();
    }
    for (z, x, y, data) in tiles {
        db.execute(
            "INSERT INTO tiles VALUES (?1, ?2, ?3, ?4)",
            (
                i64::from(*z),
                i64::from(*x),
                i64::from(mbtiles::tms_row(*z, *y)),
                data.to_vec(),
            ),
        )
        .unwrap();
    }
}

#[test]
fn an_mbtiles_file_is_read_in_xyz_numbering_from_its_tms_rows() {
    let dir = scratch("mbtiles");
    let path = dir.join("field.mbtiles");
    mbtiles(&path, "png", &[(2, 1, 0, PNG), (3, 2, 1, JPEG)]);
    let map = MapTiles::from_config(&MapConfig {
        tiles: Some(path.clone()),
        ..MapConfig::default()
    })
    .unwrap();
    let info = map.info();
    assert_eq!(info.source, "mbtiles");
    assert_eq!((info.min_zoom, info.max_zoom), (2, 3));
    assert_eq!(info.bounds, Some([8.5, 47.3, 8.6, 47.4]));
    assert_eq!(info.attribution.as_deref(), Some("test tiles"));
    assert_eq!(info.tile_url.as_deref(), Some(LOCAL_TILE_URL));
    let set = map.local.as_ref().unwrap();
    assert_eq!(set.tile(2, 1, 0).unwrap().as_deref(), Some(PNG));
    // Row 0 from the north is TMS row 3: the tile at XYZ (2, 1, 3) is not there.
    assert_eq!(set.tile(2, 1, 3).unwrap(), None);
    assert_eq!(set.tile(3, 2, 1).unwrap().as_deref(), Some(JPEG));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn what_is_no_raster_tile_set_is_refused_with_the_reason() {
    let dir = scratch("refused");
    let junk = dir.join("junk.mbtiles");
    std::fs::write(&junk, vec![0x42u8; 4096]).unwrap();
    let e = TileSet::open(&junk).err().unwrap();
    assert!(e.contains("not an MBTiles file"), "{e}");
    let vector = dir.join("vector.mbtiles");
    mbtiles(&vector, "pbf", &[(1, 0, 0, &[0x1F, 0x8B])]);
    let e = TileSet::open(&vector).err().unwrap();
    assert!(e.contains("raster"), "{e}");
    let empty = dir.join("empty.mbtiles");
    mbtiles(&empty, "png", &[]);
    assert!(TileSet::open(&empty).err().unwrap().contains("no tile"));
    assert!(TileSet::open(&dir.join("missing.mbtiles")).is_err());
    let e = MapTiles::from_config(&MapConfig {
        online_url: Some("https://tiles.example/{z}/{x}.png".into()),
        ..MapConfig::default()
    })
    .err()
    .unwrap();
    assert!(e.contains("{y}"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_folder_of_tiles_xyz_or_tms() {
    let dir = scratch("folder");
    std::fs::create_dir_all(dir.join("5/10")).unwrap();
    std::fs::write(dir.join("5/10/7.png"), PNG).unwrap();
    let set = TileSet::open(&dir).unwrap();
    assert_eq!(set.info().source, "folder");
    assert_eq!((set.info().min_zoom, set.info().max_zoom), (5, 5));
    assert_eq!(set.tile(5, 10, 7).unwrap().as_deref(), Some(PNG));
    assert_eq!(set.tile(5, 10, 8).unwrap(), None);
    std::fs::write(
        dir.join("metadata.json"),
        r#"{"scheme": "tms", "attribution": "a"}"#,
    )
    .unwrap();
    let set = TileSet::open(&dir).unwrap();
    assert_eq!(
        set.tile(5, 10, 31 - 7).unwrap().as_deref(),
        Some(PNG),
        "TMS row 7"
    );
    assert!(TileSet::open(&dir.join("5/10")).is_err(), "no zoom folders");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn content_type_from_the_bytes() {
    assert_eq!(content_type(PNG), "image/png");
    assert_eq!(content_type(JPEG), "image/jpeg");
    assert_eq!(content_type(b"RIFF\0\0\0\0WEBPVP8 "), "image/webp");
    assert_eq!(content_type(b"hello"), "application/octet-stream");
}
