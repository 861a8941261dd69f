// The map under the plan view: raster tiles (GET /api/v1/map says where from: skein's
// own /api/v1/map/tiles/{z}/{x}/{y}, an online server, or none) drawn on a canvas of
// their own beneath the plan's, in the plan's own projection: each tile's corners go from
// Web Mercator to latitude / longitude to the swarm frame, so vehicles, trails, slots,
// tracks and hazards stay where they are and the map lies under them. The zoom level is
// the one whose pixels match the screen's, capped at the set's deepest (overzoom: its
// tiles are enlarged) and floored at its shallowest. A tile that is missing (404) leaves
// the plan's grid showing there. The attribution sits in the corner.
//
// Test hooks on the plan's mirror list: data-map-source, data-map-zoom (the zoom level
// drawn), data-map-tiles (tiles drawn), data-map-missing (tiles in view that are not in
// the set), data-origin-lat / data-origin-lon (the swarm origin).

import { withToken } from './api.js';
import { latLonToNed, nedToLatLon, tileLat, tileLon, tileOf, zoomFor } from './geo.js';

const CACHE_TILES = 400;
/** Tiles drawn per frame at most (a far zoom-out beyond the set's shallowest level). */
const MAX_TILES = 200;

export class MapLayer {
  /** canvas: the map's own canvas under the plan; attribution: element for the credit. */
  constructor(canvas, attribution, onTile) {
    this.canvas = canvas;
    this.ctx = canvas.getContext('2d');
    this.attribution = attribution;
    this.onTile = onTile;   // a tile arrived: the plan should draw again
    this.info = null;       // GET /api/v1/map
    this.origin = null;     // swarm origin {lat_deg, lon_deg}
    this.tiles = new Map(); // "z/x/y" → {img, state: 'loading' | 'ok' | 'missing'}
    this.stats = { zoom: null, drawn: 0, missing: 0 };
  }

  /** What GET /api/v1/map answered. */
  setInfo(info) {
    this.info = info && info.source !== 'none' && info.tile_url ? info : null;
    this.tiles.clear();
    const credit = this.info && this.info.attribution;
    this.attribution.textContent = credit || '';
    this.attribution.hidden = !credit;
    this.onTile();
  }

  /** The swarm origin (GET /api/v1/health's swarm_origin), or null while unknown. */
  setOrigin(origin) {
    const same = origin && this.origin && origin.lat_deg === this.origin.lat_deg && origin.lon_deg === this.origin.lon_deg;
    if (same || (!origin && !this.origin)) return;
    this.origin = origin || null;
    this.onTile();
  }

  url(z, x, y) {
    const u = this.info.tile_url.replace('{z}', z).replace('{x}', x).replace('{y}', y);
    return this.info.source === 'online' ? u : withToken(u);
  }

  tile(z, x, y) {
    const key = `${z}/${x}/${y}`;
    let t = this.tiles.get(key);
    if (t) {
      // Most recently used last (the cache drops from the front).
      this.tiles.delete(key);
      this.tiles.set(key, t);
      return t;
    }
    const img = new Image();
    t = { img, state: 'loading' };
    img.onload = () => { t.state = 'ok'; this.onTile(); };
    img.onerror = () => { t.state = 'missing'; this.onTile(); };
    img.src = this.url(z, x, y);
    this.tiles.set(key, t);
    while (this.tiles.size > CACHE_TILES) this.tiles.delete(this.tiles.keys().next().value);
    return t;
  }

  /** Draws the tiles under plan `p` (its view, size and toPx), or clears the canvas. */
  draw(p) {
    const { w, h, dpr } = p.size;
    if (this.canvas.width !== Math.round(w * dpr) || this.canvas.height !== Math.round(h * dpr)) {
      this.canvas.width = Math.round(w * dpr);
      this.canvas.height = Math.round(h * dpr);
      this.canvas.style.width = `${w}px`;
      this.canvas.style.height = `${h}px`;
    }
    const ctx = this.ctx;
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.clearRect(0, 0, w, h);
    this.stats = { zoom: null, drawn: 0, missing: 0 };
    const v = p.view;
    if (!this.info || !this.origin || !v) return;
    const o = this.origin;
    const ideal = Math.round(zoomFor(v.s * dpr, o.lat_deg));
    const z = Math.max(this.info.min_zoom, Math.min(this.info.max_zoom, ideal));
    this.stats.zoom = z;
    // The view's corners in latitude / longitude (north up: two corners suffice).
    const corner = (x, y) => nedToLatLon(o, v.cn - (y - h / 2) / v.s, v.ce + (x - w / 2) / v.s);
    const nw = corner(0, 0);
    const se = corner(w, h);
    const a = tileOf(nw.lat_deg, nw.lon_deg, z);
    const b = tileOf(se.lat_deg, se.lon_deg, z);
    if ((b.x - a.x + 1) * (b.y - a.y + 1) > MAX_TILES) return;
    // Overzoomed tiles are enlarged without blurring them.
    ctx.imageSmoothingEnabled = z >= ideal;
    for (let y = a.y; y <= b.y; y++) {
      for (let x = a.x; x <= b.x; x++) {
        const t = this.tile(z, x, y);
        if (t.state === 'missing') { this.stats.missing++; continue; }
        if (t.state !== 'ok') continue;
        const top = latLonToNed(o, tileLat(y, z), tileLon(x, z));
        const bottom = latLonToNed(o, tileLat(y + 1, z), tileLon(x + 1, z));
        const [x0, y0] = p.toPx(top.north_m, top.east_m);
        const [x1, y1] = p.toPx(bottom.north_m, bottom.east_m);
        // A hair of overlap hides the seams between tiles.
        ctx.drawImage(t.img, x0, y0, x1 - x0 + 0.5, y1 - y0 + 0.5);
        this.stats.drawn++;
      }
    }
  }

  /** Writes the test hooks onto the plan's mirror element's dataset. */
  mirror(md) {
    md.mapSource = this.info ? this.info.source : 'none';
    md.mapZoom = this.stats.zoom == null ? '' : String(this.stats.zoom);
    md.mapTiles = String(this.stats.drawn);
    md.mapMissing = String(this.stats.missing);
    md.originLat = this.origin ? String(this.origin.lat_deg) : '';
    md.originLon = this.origin ? String(this.origin.lon_deg) : '';
  }
}

