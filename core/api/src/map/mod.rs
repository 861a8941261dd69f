//! The map under the plan view: raster tiles for places without internet, served by
//! skein from an MBTiles file or a `z/x/y` folder (`--map-tiles PATH`, `[map] tiles`), or,
//! opt in, an online tile server the browser fetches from (`[map] online_url`, never
//! contacted unless configured, and never by skein itself).
//!
//! - `GET /api/v1/map`: what the dashboard draws ([`MapInfo`]: source, tile URL, zoom
//!   range, bounds, attribution);
//! - `GET /api/v1/map/tiles/{z}/{x}/{y}`: one tile, XYZ (slippy map) numbering, y from the
//!   north; the content type from the tile's own bytes, cached by the browser for a day,
//!   404 outside the set.
//!
//! [`mbtiles`] reads the SQLite file (TMS rows: y counted from the south), [`folder`] the
//! directory tree; both are opened and checked at start, so a file that is not a tile
//! set stops skein with the reason.

pub mod folder;
pub mod mbtiles;

use crate::ApiState;
use crate::error::ApiError;
use crate::responses::Binary;
use axum::Json;
use axum::extract::{Path, State};
use axum::http::header;
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};
use std::path::{Path as FsPath, PathBuf};
use utoipa::ToSchema;

/// What the dashboard needs to draw the map (`GET /api/v1/map`).
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct MapInfo {
    /// `mbtiles`, `folder`, `online`, or `none` (the plan draws its grid alone).
    pub source: String,
    /// The tile URL template with `{z}`, `{x}`, `{y}` (XYZ numbering): skein's own
    /// `/api/v1/map/tiles/{z}/{x}/{y}` for local tiles, the configured template online;
    /// `null` without tiles.
    pub tile_url: Option<String>,
    /// Lowest zoom level of the set.
    pub min_zoom: u8,
    /// Deepest zoom level of the set: beyond it the dashboard enlarges these tiles.
    pub max_zoom: u8,
    /// `[west, south, east, north]`, degrees, when the set says (MBTiles `bounds`).
    pub bounds: Option<[f64; 4]>,
    /// What the map must credit (MBTiles `attribution`, the online server's).
    pub attribution: Option<String>,
    /// The set's name (MBTiles `name`, the file or folder name).
    pub name: Option<String>,
}

impl MapInfo {
    /// No map: the plan draws its metric grid.
    pub fn none() -> Self {
        MapInfo {
            source: "none".into(),
            tile_url: None,
            min_zoom: 0,
            max_zoom: 0,
            bounds: None,
            attribution: None,
            name: None,
        }
    }
}

/// `[map]` of the configuration: where tiles come from.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapConfig {
    /// An MBTiles file or a `z/x/y` folder (relative to the config file's directory);
    /// `--map-tiles` overrides it.
    pub tiles: Option<PathBuf>,
    /// An online tile server's URL template (`https://…/{z}/{x}/{y}.png`), fetched by the
    /// browser only, and only when no local tiles are set.
    pub online_url: Option<String>,
    /// What the online server's tiles must credit (`© OpenStreetMap contributors`).
    pub online_attribution: Option<String>,
    /// Deepest zoom of the online server (default 19).
    pub online_max_zoom: Option<u8>,
}

/// A local tile set.
pub enum TileSet {
    /// An MBTiles file.
    MbTiles(mbtiles::MbTiles),
    /// A `z/x/y` folder.
    Folder(folder::TileFolder),
}

impl TileSet {
    /// Opens `path`: a directory is a `z/x/y` folder, a file an MBTiles database.
    ///
    /// # Errors
    /// Why `path` is no tile set skein can draw (missing, not SQLite, no `tiles` table,
    /// vector tiles, no tile at all), naming it.
    pub fn open(path: &FsPath) -> Result<Self, String> {
        let what = path.display();
        let meta = std::fs::metadata(path).map_err(|e| format!("{what}: {e}"))?;
        if meta.is_dir() {
            folder::TileFolder::open(path).map(TileSet::Folder)
        } else {
            mbtiles::MbTiles::open(path).map(TileSet::MbTiles)
        }
        .map_err(|e| format!("{what}: {e}"))
    }

    fn info(&self) -> MapInfo {
        match self {
            TileSet::MbTiles(m) => m.info.clone(),
            TileSet::Folder(f) => f.info.clone(),
        }
    }

    fn tile(&self, z: u8, x: u32, y: u32) -> Result<Option<Vec<u8>>, String> {
        match self {
            TileSet::MbTiles(m) => m.tile(z, x, y),
            TileSet::Folder(f) => f.tile(z, x, y),
        }
    }
}

/// The map skein serves: a local tile set, an online template, or nothing.
pub struct MapTiles {
    info: MapInfo,
    local: Option<TileSet>,
}

/// The URL template of skein's own tiles.
pub const LOCAL_TILE_URL: &str = "/api/v1/map/tiles/{z}/{x}/{y}";

impl MapTiles {
    /// The map of `config` (`tiles` already resolved against the config's directory, or
    /// replaced by `--map-tiles`).
    ///
    /// # Errors
    /// A local set that cannot be opened ([`TileSet::open`]), an online template without
    /// its `{z}`, `{x}` and `{y}`.
    pub fn from_config(config: &MapConfig) -> Result<Self, String> {
        if let Some(path) = &config.tiles {
            let set = TileSet::open(path)?;
            let mut info = set.info();
            info.tile_url = Some(LOCAL_TILE_URL.into());
            return Ok(MapTiles {
                info,
                local: Some(set),
            });
        }
        if let Some(url) = &config.online_url {
            if !["{z}", "{x}", "{y}"].iter().all(|k| url.contains(k)) {
                return Err(format!(
                    "map.online_url `{url}` needs {{z}}, {{x}} and {{y}}"
                ));
            }
            return Ok(MapTiles {
                info: MapInfo {
                    source: "online".into(),
                    tile_url: Some(url.clone()),
                    min_zoom: 0,
                    max_zoom: config.online_max_zoom.unwrap_or(19).min(24),
                    bounds: None,
                    attribution: config.online_attribution.clone(),
                    name: None,
                },
                local: None,
            });
        }
        Ok(MapTiles::none())
    }

    /// No map.
    pub fn none() -> Self {
        MapTiles {
            info: MapInfo::none(),
            local: None,
        }
    }

    /// What `GET /api/v1/map` answers.
    pub fn info(&self) -> &MapInfo {
        &self.info
    }
}

/// The media type of a tile, from its first bytes.
pub fn content_type(tile: &[u8]) -> &'static str {
    match tile {
        [0x89, b'P', b'N', b'G', ..] => "image/png",
        [0xFF, 0xD8, 0xFF, ..] => "image/jpeg",
        [
            b'R',
            b'I',
            b'F',
            b'F',
            _,
            _,
            _,
            _,
            b'W',
            b'E',
            b'B',
            b'P',
            ..,
        ] => "image/webp",
        [b'G', b'I', b'F', b'8', ..] => "image/gif",
        _ => "application/octet-stream",
    }
}

/// `{z}`, `{x}` and `{y}` of a tile path (XYZ numbering). Parsed by the handler, so that
/// a path that is no number is a 400 naming it.
#[derive(Debug, Clone, Deserialize, utoipa::IntoParams)]
#[into_params(parameter_in = Path)]
pub struct TilePath {
    /// Zoom level, 0 to 24.
    #[param(value_type = u32, minimum = 0, maximum = 24, example = 18)]
    pub z: String,
    /// Column, 0 to 2^z - 1, from the west.
    #[param(value_type = u32, minimum = 0, example = 137293)]
    pub x: String,
    /// Row, 0 to 2^z - 1, from the north (XYZ; MBTiles files count from the south).
    #[param(value_type = u32, minimum = 0, example = 91822)]
    pub y: String,
}

fn number(field: &str, s: &str) -> Result<u32, ApiError> {
    s.parse()
        .map_err(|_| ApiError::field(field, format!("{field} must be a whole number, got `{s}`")))
}

/// The map the dashboard draws under the plan
#[utoipa::path(get, path = "/api/v1/map",
    responses((status = 200, body = MapInfo)))]
pub(crate) async fn map_info(State(s): State<ApiState>) -> Json<MapInfo> {
    Json(s.map.info().clone())
}

/// One map tile (XYZ numbering)
///
/// 404 outside the set (a zoom level, column or row it does not have).
#[utoipa::path(get, path = "/api/v1/map/tiles/{z}/{x}/{y}", params(TilePath),
    responses((status = 200, content(
        (Binary = "image/png"), (Binary = "image/jpeg"), (Binary = "image/webp"))),
        (status = 400), (status = 404)))]
pub(crate) async fn map_tile(
    State(s): State<ApiState>,
    Path(TilePath { z, x, y }): Path<TilePath>,
) -> Result<Response, ApiError> {
    let (zn, xn, yn) = (number("z", &z)?, number("x", &x)?, number("y", &y)?);
    let Some(set) = &s.map.local else {
        return Err(ApiError::not_found(
            "no map tiles here (skein up --map-tiles FILE.mbtiles or a z/x/y folder)",
        ));
    };
    let missing = || ApiError::not_found(format!("no tile {z}/{x}/{y} in the map's tile set"));
    let info = &s.map.info;
    if zn > 24 || zn < u32::from(info.min_zoom) || zn > u32::from(info.max_zoom) {
        return Err(missing());
    }
    let zn = zn as u8;
    if xn >= 1 << zn || yn >= 1 << zn {
        return Err(missing());
    }
    let tile = set
        .tile(zn, xn, yn)
        .map_err(|e| ApiError::status(axum::http::StatusCode::INTERNAL_SERVER_ERROR, e))?
        .ok_or_else(missing)?;
    Ok((
        [
            (header::CONTENT_TYPE, content_type(&tile)),
            // A tile set does not change while skein runs: a day in the browser's cache
            // (private: the request may carry a token).
            (header::CACHE_CONTROL, "private, max-age=86400"),
        ],
        tile,
    )
        .into_response())
}

#[cfg(test)]
mod tests;
