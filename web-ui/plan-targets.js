// Counter-UAS tracks on the plan view: a diamond per track (red confirmed, amber
// tentative, grey lost) with its id, status and speed, the velocity vector (where it will
// be in 2 s) and the 2-sigma uncertainty ellipse of its horizontal position (from the
// track's north/east covariance). Where each was drawn goes to p.targetPx.

import { fmt } from './model.js';

const COLOURS = { confirmed: '#ff5566', tentative: '#ffb020', lost: '#8a94a6' };
const VECTOR_S = 2;

/** Semi-axes (m) and the angle of the major one (rad, from north towards east) of the
 * 2-sigma ellipse of a 2×2 north/east covariance. */
export function ellipse2Sigma(cov) {
  const a = cov[0][0], b = cov[0][1], d = cov[1][1];
  const mid = (a + d) / 2, r = Math.hypot((a - d) / 2, b);
  const l1 = Math.max(0, mid + r), l2 = Math.max(0, mid - r);
  return { major: 2 * Math.sqrt(l1), minor: 2 * Math.sqrt(l2), angle: 0.5 * Math.atan2(2 * b, a - d) };
}

export function drawTargets(p) {
  p.targetPx.clear();
  if (!p.view || !p.targets.length) return;
  const { ctx } = p;
  ctx.save();
  ctx.font = '10px system-ui, -apple-system, "Segoe UI", sans-serif';
  for (const t of p.targets) {
    const pos = t.position;
    if (!pos || !Number.isFinite(pos.north_m) || !Number.isFinite(pos.east_m)) continue;
    const colour = COLOURS[t.status] || COLOURS.tentative;
    const [x, y] = p.toPx(pos.north_m, pos.east_m);
    p.targetPx.set(t.id, [x, y]);
    ctx.strokeStyle = colour;
    ctx.fillStyle = colour;
    ctx.lineWidth = 1.5;
    // Uncertainty: traced in the swarm frame, so it is right whatever the view's axes.
    if (Array.isArray(t.covariance_ne_m2)) {
      const e = ellipse2Sigma(t.covariance_ne_m2);
      const [ca, sa] = [Math.cos(e.angle), Math.sin(e.angle)];
      ctx.setLineDash([4, 3]);
      ctx.beginPath();
      for (let i = 0; i <= 36; i++) {
        const u = (i / 36) * 2 * Math.PI;
        const an = e.major * Math.cos(u), bn = e.minor * Math.sin(u);
        const [ex, ey] = p.toPx(pos.north_m + an * ca - bn * sa, pos.east_m + an * sa + bn * ca);
        if (i) ctx.lineTo(ex, ey); else ctx.moveTo(ex, ey);
      }
      ctx.stroke();
      ctx.setLineDash([]);
    }
    const v = t.velocity || {};
    const vn = v.north_m_s || 0, ve = v.east_m_s || 0;
    if (Math.hypot(vn, ve) > 0.2) {
      const [vx, vy] = p.toPx(pos.north_m + vn * VECTOR_S, pos.east_m + ve * VECTOR_S);
      ctx.beginPath(); ctx.moveTo(x, y); ctx.lineTo(vx, vy); ctx.stroke();
      const ang = Math.atan2(vy - y, vx - x);
      ctx.beginPath();
      ctx.moveTo(vx, vy);
      ctx.lineTo(vx - 7 * Math.cos(ang - 0.4), vy - 7 * Math.sin(ang - 0.4));
      ctx.lineTo(vx - 7 * Math.cos(ang + 0.4), vy - 7 * Math.sin(ang + 0.4));
      ctx.closePath(); ctx.fill();
    }
    ctx.beginPath();
    ctx.moveTo(x, y - 7); ctx.lineTo(x + 7, y); ctx.lineTo(x, y + 7); ctx.lineTo(x - 7, y); ctx.closePath();
    if (t.status === 'confirmed') ctx.fill(); else ctx.stroke();
    ctx.textAlign = 'left';
    const observed = (t.observed_by || []).length ? ' · observed' : '';
    ctx.fillText(`${t.id} ${t.status} ${fmt(Math.hypot(vn, ve), 1)} m/s${observed}`, x + 10, y - 8);
  }
  ctx.restore();
  ctx.textAlign = 'start';
}
