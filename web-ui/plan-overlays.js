// What the plan view draws over the swarm: operator marks (go-to targets, gimbal points),
// hazards, the scale bar, the north arrow and the cursor's coordinates (swarm frame, and
// latitude / longitude once the swarm origin is known). Each takes the PlanView (its ctx,
// size, view and toPx). The geofence is plan-fence.js's.

import { fmt } from './model.js';
import { nedToLatLon } from './geo.js';

/** Marks: go-to targets and gimbal points, as labelled crosses. */
export function drawMarks(p) {
  const { ctx } = p;
  ctx.font = '10px system-ui, -apple-system, "Segoe UI", sans-serif';
  for (const m of p.marks.values()) {
    const [x, y] = p.toPx(m.n, m.e);
    ctx.strokeStyle = '#ff8a5b';
    ctx.lineWidth = 1.5;
    ctx.beginPath();
    ctx.moveTo(x - 7, y - 7); ctx.lineTo(x + 7, y + 7); ctx.moveTo(x + 7, y - 7); ctx.lineTo(x - 7, y + 7);
    ctx.stroke();
    ctx.fillStyle = '#ff8a5b';
    ctx.textAlign = 'left';
    ctx.fillText(m.label, x + 9, y - 6);
  }
}

/**
 * Hazards: vehicles lost in the air (or in PX4's failsafe), at their last known position,
 * as a red disc of their uncertainty radius plus the separation the formation keeps
 * from it, with the vehicle's id and how long it has been unseen.
 */
export function drawHazards(p) {
  const f = p.formation;
  if (!f || !Array.isArray(f.hazards) || !f.hazards.length) return;
  const { ctx } = p;
  ctx.save();
  ctx.font = '10px system-ui, -apple-system, "Segoe UI", sans-serif';
  ctx.textAlign = 'center';
  for (const h of f.hazards) {
    const [x, y] = p.toPx(h.position.north_m, h.position.east_m);
    const r = Math.max(3, h.radius_m * p.view.s);
    ctx.fillStyle = 'rgba(255,85,102,0.16)';
    ctx.strokeStyle = 'rgba(255,85,102,0.9)';
    ctx.lineWidth = 1.5;
    ctx.beginPath(); ctx.arc(x, y, r, 0, Math.PI * 2); ctx.fill(); ctx.stroke();
    ctx.fillStyle = 'rgba(255,85,102,0.95)';
    ctx.fillText(`${h.id} ${h.reason.toLowerCase()} · ${fmt(h.unseen_s, 0)} s`, x, y - r - 4);
  }
  if (f.blocked) {
    ctx.textAlign = 'left';
    ctx.fillText('formation blocked by hazards: holding', 16, 20);
  }
  ctx.restore();
  ctx.textAlign = 'start';
}

/** Scale bar: one grid cell, bottom left. */
export function drawScale(p, step) {
  const { ctx } = p;
  const { h } = p.size;
  const px = step * p.view.s;
  const x0 = 16, y0 = h - 18;
  ctx.fillStyle = 'rgba(8,11,16,0.6)';
  ctx.fillRect(x0 - 6, y0 - 24, px + 12, 30);
  ctx.strokeStyle = '#c9d3e0';
  ctx.lineWidth = 2;
  ctx.beginPath();
  ctx.moveTo(x0, y0 - 5); ctx.lineTo(x0, y0); ctx.lineTo(x0 + px, y0); ctx.lineTo(x0 + px, y0 - 5);
  ctx.stroke();
  ctx.fillStyle = '#c9d3e0';
  ctx.font = '11px system-ui, -apple-system, "Segoe UI", sans-serif';
  ctx.textBaseline = 'bottom';
  ctx.fillText(step >= 1000 ? `${+(step / 1000).toPrecision(3)} km` : `${+step.toPrecision(3)} m`, x0, y0 - 7);
  ctx.textBaseline = 'middle';
}

export function drawNorth(p) {
  const { ctx } = p;
  const { w } = p.size;
  const x = w - 24, y = 30;
  ctx.fillStyle = '#c9d3e0';
  ctx.beginPath();
  ctx.moveTo(x, y - 14); ctx.lineTo(x + 6, y + 2); ctx.lineTo(x, y - 2); ctx.lineTo(x - 6, y + 2);
  ctx.closePath(); ctx.fill();
  ctx.font = 'bold 11px system-ui, -apple-system, "Segoe UI", sans-serif';
  ctx.textAlign = 'center';
  ctx.fillText('N', x, y + 12);
  ctx.textAlign = 'start';
}

export function drawCursor(p) {
  if (!p.cursor || !p.view) return;
  const { ctx } = p;
  const { w, h } = p.size;
  const v = p.view;
  const e = v.ce + (p.cursor.x - w / 2) / v.s;
  const n = v.cn - (p.cursor.y - h / 2) / v.s;
  const geo = p.origin ? nedToLatLon(p.origin, n, e) : null;
  // Test hook: the cursor's latitude / longitude on the plan's mirror list.
  p.mirror.dataset.cursorGeo = geo ? `${geo.lat_deg.toFixed(7)},${geo.lon_deg.toFixed(7)}` : '';
  const txt = `N ${fmt(n, 1)}  E ${fmt(e, 1)} m${geo ? `  ·  ${geo.lat_deg.toFixed(6)}°, ${geo.lon_deg.toFixed(6)}°` : ''}`;
  ctx.font = '11px ui-monospace, "SF Mono", Menlo, Consolas, monospace';
  ctx.fillStyle = '#8d97a8';
  ctx.textAlign = 'right';
  ctx.textBaseline = 'bottom';
  ctx.fillText(txt, w - 12, h - 10);
  ctx.textAlign = 'start';
  ctx.textBaseline = 'middle';
}
