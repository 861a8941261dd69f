// A survey's lanes, computed as the coordinator computes them (core/mission/src/lanes.rs,
// ported operation for operation): the polygon swept in parallel lanes along its longest
// edge, evenly spaced no further apart than asked, each lane the stretch of its line inside
// the polygon (even-odd rule), alternating direction; then split among the step's vehicles
// in contiguous blocks, the first blocks a lane longer. Points are swarm-frame
// [north_m, east_m].

const dist = (a, b) => Math.hypot(a[0] - b[0], a[1] - b[1]);

/** `p` turned by `angle` radians (north toward east). */
function rotate(p, angle) {
  const s = Math.sin(angle), c = Math.cos(angle);
  return [p[0] * c - p[1] * s, p[0] * s + p[1] * c];
}

/** The direction of the polygon's longest edge, radians from the north axis. */
function longestEdgeHeading(polygon) {
  const n = polygon.length;
  let best = null, bestLen = -Infinity;
  for (let i = 0; i < n; i++) {
    const a = polygon[i], b = polygon[(i + 1) % n];
    // Rust's max_by keeps the last of equal maxima.
    const len = dist(a, b);
    if (len >= bestLen) { bestLen = len; best = [a, b]; }
  }
  const [a, b] = best;
  return Math.atan2(b[1] - a[1], b[0] - a[0]);
}

/** The stretches [x_from, x_to] of the line `y` inside `polygon`, west to east. */
function crossings(polygon, y) {
  const n = polygon.length;
  const xs = [];
  for (let i = 0; i < n; i++) {
    const a = polygon[i], b = polygon[(i + 1) % n];
    if ((a[1] <= y && y < b[1]) || (b[1] <= y && y < a[1])) {
      xs.push(a[0] + ((y - a[1]) * (b[0] - a[0])) / (b[1] - a[1]));
    }
  }
  xs.sort((p, q) => p - q);
  const out = [];
  for (let i = 0; i + 1 < xs.length; i += 2) out.push([xs[i], xs[i + 1]]);
  return out;
}

/**
 * The lanes sweeping `polygon` (at least 3 vertices) no more than `spacingM` apart, in
 * sweep order: [{start: [n, e], end: [n, e]}]. Empty for fewer vertices or no spacing.
 */
export function lanes(polygon, spacingM) {
  if (!Array.isArray(polygon) || polygon.length < 3 || !(spacingM > 0)) return [];
  const heading = longestEdgeHeading(polygon);
  const turned = polygon.map((p) => rotate(p, -heading));
  let ymin = Number.MAX_VALUE, ymax = -Number.MAX_VALUE;
  for (const p of turned) { ymin = Math.min(ymin, p[1]); ymax = Math.max(ymax, p[1]); }
  // (Less a hair: a width of exactly n spacings, turned, gives n lanes, not n + 1.)
  const n = Math.max(1, Math.ceil((ymax - ymin) / spacingM - 1e-9));
  const step = (ymax - ymin) / n;
  const out = [];
  for (let k = 0; k < n; k++) {
    const y = ymin + (k + 0.5) * step;
    for (const [x0, x1] of crossings(turned, y)) {
      const [a, b] = out.length % 2 === 0 ? [x0, x1] : [x1, x0];
      out.push({ start: rotate([a, y], heading), end: rotate([b, y], heading) });
    }
  }
  return out;
}

/** `all` split among `vehicles` in contiguous blocks; block i is vehicle i's. */
export function split(all, vehicles) {
  const v = Math.max(1, vehicles);
  const base = Math.floor(all.length / v), extra = all.length % v;
  const out = [];
  let at = 0;
  for (let i = 0; i < v; i++) {
    const n = base + (i < extra ? 1 : 0);
    out.push(all.slice(at, at + n));
    at += n;
  }
  return out;
}

/**
 * The lane spacing of a survey step as the coordinator takes it: `lane_spacing_m`, else
 * the camera's footprint at the step's altitude less the overlap; null without either.
 */
export function surveySpacing(step) {
  if (Number.isFinite(step.lane_spacing_m)) return step.lane_spacing_m;
  const c = step.camera;
  if (c && Number.isFinite(c.hfov_deg) && Number.isFinite(c.overlap) && Number.isFinite(step.altitude_m)) {
    return 2 * step.altitude_m * Math.tan((c.hfov_deg * (Math.PI / 180)) / 2) * (1 - c.overlap);
  }
  return null;
}
