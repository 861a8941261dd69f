// Hostile swarms and forecasts on the plan view: each swarm as the convex hull of its
// members' tracks (magenta), its centroid with its id, shape and speed, and its forecast
// cone (the centroid's predicted path through 5, 10 and 20 s, as wide as ±1 σ of each
// forecast, with a tick at each horizon); lone confirmed tracks get a thinner cone of
// their own. Observers on stations are squares joined to what they observe. Where each
// swarm was drawn goes to p.swarmPx (id → {x, y, hull, cone}), for the Tracks view's test
// hooks.

import { fmt } from './model.js';

const SWARM = '#e05cff';
const SWARM_FILL = 'rgba(224,92,255,0.12)';
const CONE_FILL = 'rgba(224,92,255,0.10)';
const TRACK_CONE = 'rgba(255,85,102,0.10)';

/** Convex hull of [x, y] points, counter-clockwise (Andrew's monotone chain). */
export function convexHull(points) {
  const pts = [...points].sort((a, b) => a[0] - b[0] || a[1] - b[1]);
  if (pts.length <= 2) return pts;
  const cross = (o, a, b) => (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
  const half = (list) => {
    const out = [];
    for (const p of list) {
      while (out.length >= 2 && cross(out[out.length - 2], out[out.length - 1], p) <= 0) out.pop();
      out.push(p);
    }
    out.pop();
    return out;
  };
  return half(pts).concat(half([...pts].reverse()));
}

/**
 * The outline of a forecast cone in the swarm frame: from `start` (north, east) through
 * each forecast point, `±sigma_m` across the path there; null without forecast points.
 */
export function coneOutline(start, forecast) {
  const pts = (forecast || [])
    .filter((f) => f.position && Number.isFinite(f.position.north_m))
    .sort((a, b) => a.horizon_s - b.horizon_s);
  if (!pts.length) return null;
  const path = [[start[0], start[1], 0], ...pts.map((f) => [f.position.north_m, f.position.east_m, f.sigma_m || 0])];
  const left = [], right = [];
  for (let i = 0; i < path.length; i++) {
    const a = path[Math.max(0, i - 1)], b = path[Math.min(path.length - 1, i + 1)];
    let dn = b[0] - a[0], de = b[1] - a[1];
    const len = Math.hypot(dn, de) || 1;
    dn /= len; de /= len;
    const w = path[i][2];
    // Left of the direction of travel (north → east clockwise): (de, -dn) is right.
    left.push([path[i][0] - de * w, path[i][1] + dn * w]);
    right.push([path[i][0] + de * w, path[i][1] - dn * w]);
  }
  return { path, outline: left.concat(right.reverse()) };
}

function fillOutline(p, outline, fill, stroke) {
  const { ctx } = p;
  ctx.beginPath();
  outline.forEach(([n, e], i) => {
    const [x, y] = p.toPx(n, e);
    if (i) ctx.lineTo(x, y); else ctx.moveTo(x, y);
  });
  ctx.closePath();
  ctx.fillStyle = fill;
  ctx.fill();
  if (stroke) { ctx.strokeStyle = stroke; ctx.stroke(); }
}

function drawCone(p, start, forecast, fill, stroke, ticks) {
  const cone = coneOutline(start, forecast);
  if (!cone) return false;
  const { ctx } = p;
  ctx.lineWidth = 1;
  ctx.setLineDash([]);
  fillOutline(p, cone.outline, fill, null);
  ctx.setLineDash([5, 4]);
  ctx.strokeStyle = stroke;
  ctx.beginPath();
  cone.path.forEach(([n, e], i) => {
    const [x, y] = p.toPx(n, e);
    if (i) ctx.lineTo(x, y); else ctx.moveTo(x, y);
  });
  ctx.stroke();
  ctx.setLineDash([]);
  if (ticks) {
    ctx.fillStyle = stroke;
    ctx.textAlign = 'left';
    for (const f of forecast) {
      const [x, y] = p.toPx(f.position.north_m, f.position.east_m);
      ctx.beginPath(); ctx.arc(x, y, 2.5, 0, Math.PI * 2); ctx.fill();
      ctx.fillText(`${fmt(f.horizon_s, 0)} s`, x + 5, y + 10);
    }
  }
  return true;
}

export function drawSwarms(p) {
  p.swarmPx.clear();
  if (!p.view) return;
  const { ctx } = p;
  const byId = new Map(p.targets.map((t) => [t.id, t]));
  ctx.save();
  ctx.font = '10px system-ui, -apple-system, "Segoe UI", sans-serif';
  // Lone confirmed tracks: their own thin cone.
  for (const t of p.targets) {
    if (t.status !== 'confirmed' || t.swarm || !t.position) continue;
    drawCone(p, [t.position.north_m, t.position.east_m], t.forecast, TRACK_CONE, 'rgba(255,85,102,0.6)', false);
  }
  for (const s of p.swarms) {
    const c = s.centroid;
    if (!c || !Number.isFinite(c.north_m)) continue;
    const members = (s.members || []).map((id) => byId.get(id)).filter((t) => t && t.position);
    const hullNe = convexHull(members.map((t) => [t.position.north_m, t.position.east_m]));
    ctx.lineWidth = 1.5;
    ctx.strokeStyle = SWARM;
    if (hullNe.length >= 3) {
      fillOutline(p, hullNe, SWARM_FILL, SWARM);
    } else if (hullNe.length === 2) {
      const [a, b] = hullNe.map(([n, e]) => p.toPx(n, e));
      ctx.beginPath(); ctx.moveTo(a[0], a[1]); ctx.lineTo(b[0], b[1]); ctx.stroke();
    }
    const cone = drawCone(p, [c.north_m, c.east_m], s.forecast, CONE_FILL, SWARM, true);
    const [x, y] = p.toPx(c.north_m, c.east_m);
    ctx.strokeStyle = SWARM;
    ctx.lineWidth = 2;
    ctx.beginPath(); ctx.arc(x, y, 5, 0, Math.PI * 2); ctx.stroke();
    ctx.beginPath(); ctx.moveTo(x - 8, y); ctx.lineTo(x + 8, y); ctx.moveTo(x, y - 8); ctx.lineTo(x, y + 8); ctx.stroke();
    const v = s.velocity || {};
    if (Math.hypot(v.north_m_s || 0, v.east_m_s || 0) > 0.2) {
      const [vx, vy] = p.toPx(c.north_m + (v.north_m_s || 0) * 2, c.east_m + (v.east_m_s || 0) * 2);
      ctx.beginPath(); ctx.moveTo(x, y); ctx.lineTo(vx, vy); ctx.stroke();
    }
    ctx.fillStyle = SWARM;
    ctx.textAlign = 'left';
    ctx.fillText(`${s.id} ${s.shape} · ${(s.members || []).length} tracks · ${fmt(s.speed_m_s, 1)} m/s`, x + 10, y + 14);
    // Observers on their stations.
    const st = s.stations && Array.isArray(s.stations.stations) ? s.stations.stations : [];
    for (const o of st) {
      const [sx, sy] = p.toPx(o.position.north_m, o.position.east_m);
      ctx.strokeStyle = SWARM;
      ctx.lineWidth = 1;
      ctx.setLineDash([2, 4]);
      ctx.beginPath(); ctx.moveTo(sx, sy); ctx.lineTo(x, y); ctx.stroke();
      ctx.setLineDash([]);
      ctx.strokeRect(sx - 5, sy - 5, 10, 10);
      ctx.fillText(`${o.vehicle} station`, sx + 8, sy - 6);
    }
    p.swarmPx.set(s.id, { x, y, hull: hullNe.length, cone, stations: st.length });
  }
  ctx.restore();
  ctx.textAlign = 'start';
}
