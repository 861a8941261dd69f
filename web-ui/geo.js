// Geodesy of the plan view's map: the swarm frame (NED metres about the swarm origin)
// to latitude / longitude and back, on the WGS84 ellipsoid's local radii (what the swarm
// frame's tangent plane is to well under a centimetre over a few kilometres), and Web
// Mercator tiles (XYZ numbering: x from the west, y from the north, 256 px per tile).

const A = 6378137.0;             // WGS84 semi-major axis, m
const E2 = 0.00669437999014;     // WGS84 first eccentricity squared
const DEG = Math.PI / 180;
/** Metres per pixel at the equator at zoom 0 (256 px tiles). */
const EQUATOR_M_PER_PX = (2 * Math.PI * A) / 256;

/** Metres per degree of latitude and of longitude at latitude `latDeg`. */
function metresPerDegree(latDeg) {
  const s = Math.sin(latDeg * DEG);
  const w = 1 - E2 * s * s;
  const meridian = (A * (1 - E2)) / (w * Math.sqrt(w)); // radius of curvature N-S
  const prime = A / Math.sqrt(w);                        // radius of curvature E-W
  return { lat: meridian * DEG, lon: prime * Math.cos(latDeg * DEG) * DEG };
}

/** {lat_deg, lon_deg} of swarm-frame (north_m, east_m) about `origin` ({lat_deg, lon_deg}). */
export function nedToLatLon(origin, north, east) {
  const m = metresPerDegree(origin.lat_deg);
  return { lat_deg: origin.lat_deg + north / m.lat, lon_deg: origin.lon_deg + east / m.lon };
}

/** Swarm-frame {north_m, east_m} of (latDeg, lonDeg) about `origin`. */
export function latLonToNed(origin, latDeg, lonDeg) {
  const m = metresPerDegree(origin.lat_deg);
  return { north_m: (latDeg - origin.lat_deg) * m.lat, east_m: (lonDeg - origin.lon_deg) * m.lon };
}

/** Longitude of the west edge of tile column x at zoom z, degrees. */
export const tileLon = (x, z) => (x / 2 ** z) * 360 - 180;
/** Latitude of the north edge of tile row y at zoom z, degrees (Web Mercator). */
export const tileLat = (y, z) => Math.atan(Math.sinh(Math.PI * (1 - (2 * y) / 2 ** z))) / DEG;

/** The XYZ tile {x, y} holding (latDeg, lonDeg) at zoom z. */
export function tileOf(latDeg, lonDeg, z) {
  const n = 2 ** z;
  const x = Math.floor(((lonDeg + 180) / 360) * n);
  const r = latDeg * DEG;
  const y = Math.floor(((1 - Math.log(Math.tan(r) + 1 / Math.cos(r)) / Math.PI) / 2) * n);
  return { x: Math.min(n - 1, Math.max(0, x)), y: Math.min(n - 1, Math.max(0, y)) };
}

/**
 * The zoom level whose tiles show about one tile pixel per screen pixel at `pxPerM`
 * (device pixels per metre) and latitude `latDeg`.
 */
export function zoomFor(pxPerM, latDeg) {
  return Math.log2(EQUATOR_M_PER_PX * Math.cos(latDeg * DEG) * pxPerM);
}
