// The geofence on the plan: the fence in force (the circle about the swarm origin, the
// inclusion polygon, exclusion areas, rally points) dashed in red, a ring round every
// vehicle skein finds outside it in the air, and the operator's draft while the fence is
// edited ([`FenceEditor`]: click to add the polygon's vertices, drag a vertex to move
// it, click a centre then a point on the rim for an exclusion circle).
//
// Test hooks: the plan's mirror list gets data-fence-vertices (the draft's polygon
// vertices, or the fence's when not editing) and data-fence-editing.

const FONT = '10px system-ui, -apple-system, "Segoe UI", sans-serif';
const RED = 'rgba(255,85,102,0.8)';
const DRAFT = '#ff9f43';
/** A click this close to a vertex (CSS px) grabs it; to the first one closes the polygon. */
const GRAB_PX = 9;

function polygonPath(p, vertices, close = true) {
  const { ctx } = p;
  ctx.beginPath();
  vertices.forEach(([n, e], i) => {
    const [x, y] = p.toPx(n, e);
    if (i) ctx.lineTo(x, y); else ctx.moveTo(x, y);
  });
  if (close) ctx.closePath();
}

function drawAreas(p, g, colour, dashed) {
  const { ctx } = p;
  ctx.setLineDash(dashed ? [8, 6] : []);
  ctx.strokeStyle = colour;
  if (Number.isFinite(g.radius_m) && g.radius_m > 0) {
    const [ox, oy] = p.toPx(0, 0);
    const r = g.radius_m * p.view.s;
    ctx.beginPath(); ctx.arc(ox, oy, r, 0, Math.PI * 2); ctx.stroke();
    ctx.fillStyle = colour;
    ctx.textAlign = 'center';
    ctx.fillText(`geofence ${g.radius_m} m · ceiling ${g.max_altitude_m} m`, ox, oy - r - 4);
  }
  if (Array.isArray(g.polygon) && g.polygon.length >= 2) {
    polygonPath(p, g.polygon, g.polygon.length >= 3);
    ctx.stroke();
  }
  for (const a of g.exclusions || []) {
    ctx.fillStyle = 'rgba(255,85,102,0.14)';
    if (a.polygon && a.polygon.length >= 3) {
      polygonPath(p, a.polygon);
    } else if (a.circle) {
      const [x, y] = p.toPx(a.circle.north_m, a.circle.east_m);
      ctx.beginPath(); ctx.arc(x, y, Math.max(2, a.circle.radius_m * p.view.s), 0, Math.PI * 2);
    } else {
      continue;
    }
    ctx.fill(); ctx.stroke();
  }
  ctx.setLineDash([]);
  for (const r of g.rally_points || []) {
    const [x, y] = p.toPx(r.north_m, r.east_m);
    ctx.fillStyle = 'rgba(62,207,142,0.9)';
    ctx.beginPath(); ctx.arc(x, y, 6, 0, Math.PI * 2); ctx.fill();
    ctx.fillStyle = '#0b1016';
    ctx.textAlign = 'center';
    ctx.fillText('R', x, y + 1);
  }
}

/** Draws the fence in force, the breach rings and the draft of plan `p`. */
export function drawFence(p) {
  if (!p.view) return;
  const { ctx } = p;
  ctx.save();
  ctx.font = FONT;
  ctx.lineWidth = 1.5;
  ctx.textBaseline = 'middle';
  if (p.geofence) drawAreas(p, p.geofence, RED, true);
  for (const t of p.tracks.values()) {
    if (!t.has || !t.v.fence || !t.v.fence.breached) continue;
    const [x, y] = p.toPx(t.n, t.e);
    ctx.strokeStyle = '#ff5566';
    ctx.lineWidth = 3;
    ctx.beginPath(); ctx.arc(x, y, 20, 0, Math.PI * 2); ctx.stroke();
    ctx.fillStyle = '#ff5566';
    ctx.textAlign = 'center';
    ctx.fillText('BREACH', x, y - 27);
    ctx.lineWidth = 1.5;
  }
  const d = p.editor && p.editor.draft;
  if (d) {
    drawAreas(p, { ...d, radius_m: null }, DRAFT, false);
    ctx.fillStyle = DRAFT;
    for (const [n, e] of d.polygon) {
      const [x, y] = p.toPx(n, e);
      ctx.fillRect(x - 4, y - 4, 8, 8);
    }
    const c = p.editor.circleCentre;
    if (c) {
      const [x, y] = p.toPx(c.north_m, c.east_m);
      ctx.beginPath(); ctx.arc(x, y, 4, 0, Math.PI * 2); ctx.fill();
    }
  }
  ctx.restore();
  ctx.textAlign = 'start';
}

/** The operator's draft of a new fence on the plan (see the module comment). */
export class FenceEditor {
  /** plan: the PlanView; onChange(): the draft changed (the panel refreshes). */
  constructor(plan, onChange) {
    this.plan = plan;
    this.onChange = onChange;
    this.draft = null;       // the fence being edited (the PUT body)
    this.mode = 'move';      // 'polygon' | 'circle' | 'move'
    this.circleCentre = null;
    this.dragging = -1;
  }

  get editing() { return !!this.draft; }

  /** Starts editing a copy of `fence` (the fence in force). */
  start(fence) {
    const f = fence || {};
    this.draft = {
      radius_m: f.radius_m ?? 500,
      max_altitude_m: f.max_altitude_m ?? 120,
      min_altitude_m: f.min_altitude_m ?? 0,
      polygon: (f.polygon || []).map(([n, e]) => [n, e]),
      exclusions: JSON.parse(JSON.stringify(f.exclusions || [])),
      rally_points: JSON.parse(JSON.stringify(f.rally_points || [])),
      breach_action: f.breach_action || 'hold',
    };
    this.mode = 'move';
    this.changed();
  }

  stop() {
    this.draft = null;
    this.mode = 'move';
    this.circleCentre = null;
    this.changed();
  }

  /** Next clicks add polygon vertices (a new polygon). */
  drawPolygon() {
    if (!this.draft) return;
    this.draft.polygon = [];
    this.mode = 'polygon';
    this.changed();
  }

  /** The next two clicks: an exclusion circle's centre, then a point on its rim. */
  addCircle() {
    if (!this.draft) return;
    this.mode = 'circle';
    this.circleCentre = null;
    this.changed();
  }

  changed() {
    this.plan.kick();
    this.onChange();
  }

  /** Swarm-frame points the plan keeps in view while editing. */
  points() {
    if (!this.draft) return [];
    const pts = this.draft.polygon.map(([n, e]) => ({ n, e }));
    for (const a of this.draft.exclusions) if (a.circle) pts.push({ n: a.circle.north_m, e: a.circle.east_m });
    return pts;
  }

  nearVertex(pt) {
    const [px, py] = [pt.x, pt.y];
    return this.draft.polygon.findIndex(([n, e]) => {
      const [x, y] = this.plan.toPx(n, e);
      return Math.hypot(x - px, y - py) <= GRAB_PX;
    });
  }

  /** A click on the plan at `pt` ({x, y, north_m, east_m}); true when the editor took it. */
  click(pt) {
    if (!this.draft) return false;
    const round = (x) => Math.round(x * 10) / 10;
    if (this.mode === 'polygon') {
      const poly = this.draft.polygon;
      if (poly.length >= 3 && this.nearVertex(pt) === 0) {
        this.mode = 'move'; // closed on its first vertex
      } else {
        poly.push([round(pt.north_m), round(pt.east_m)]);
      }
      this.changed();
      return true;
    }
    if (this.mode === 'circle') {
      if (!this.circleCentre) {
        this.circleCentre = { north_m: round(pt.north_m), east_m: round(pt.east_m) };
      } else {
        const c = this.circleCentre;
        const r = Math.hypot(pt.north_m - c.north_m, pt.east_m - c.east_m);
        if (r > 0.5) this.draft.exclusions.push({ circle: { ...c, radius_m: round(r) } });
        this.circleCentre = null;
        this.mode = 'move';
      }
      this.changed();
      return true;
    }
    return false;
  }

  /** Mouse down: grabs a vertex of the draft; true when it did. */
  down(pt) {
    if (!this.draft || this.mode !== 'move') return false;
    this.dragging = this.nearVertex(pt);
    return this.dragging >= 0;
  }

  move(pt) {
    if (this.dragging < 0) return false;
    this.draft.polygon[this.dragging] = [Math.round(pt.north_m * 10) / 10, Math.round(pt.east_m * 10) / 10];
    this.plan.kick();
    return true;
  }

  up() {
    if (this.dragging < 0) return false;
    this.dragging = -1;
    this.changed();
    return true;
  }

  /** Ends a polygon being drawn (the panel's Finish). */
  finish() {
    if (this.mode !== 'move') {
      this.mode = 'move';
      this.circleCentre = null;
      this.changed();
    }
  }
}
