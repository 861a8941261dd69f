// Plan view: a top-down canvas map of the swarm frame (north up, east right).
// The view fits all vehicles, formation slots and live tracks with a margin and eases towards that fit
// (the wheel zooms around it, `follow` centres it on one vehicle, `fit` goes back);
// `pickPoint` turns the next click into a point of the swarm frame (go-to, gimbal ROI);
// vehicle markers ease towards each new 10 Hz fix, so motion looks continuous. Drawing runs
// on requestAnimationFrame only while something changes.
//
// Under the drawing lies the map (plan-map.js), on a canvas of its own; the geofence and
// its editor are plan-fence.js's. Further layers (`addLayer`: the mission's steps,
// plan-mission.js) draw over the fence and may take clicks and drags after its editor.
//
// Test/ARIA hook: the <ul> mirror gets one <li data-vehicle-id> per drawn vehicle with
// data-x / data-y (marker centre in CSS px inside the canvas), data-north / data-east
// (swarm frame, m), data-heading and data-state, refreshed at up to 10 Hz and whenever
// the picture settles; the list itself the view (data-cn, data-ce, data-scale) and
// data-moving ("false" once the picture settled).

import { stateClass, CLASS_COLOUR, compareIds, fmt } from './model.js';
import { drawHazards, drawMarks, drawScale, drawNorth, drawCursor } from './plan-overlays.js';
import { drawFence } from './plan-fence.js';
import { drawTargets } from './plan-targets.js';
import { drawSwarms } from './plan-swarms.js';

const MIN_SPAN_M = 16;        // never zoom in further than this many metres across
const PAD_PX = 48;            // room for labels around the fitted area
const TAU_MARKER_MS = 90;     // easing time constant of markers
const TAU_VIEW_MS = 350;      // easing time constant of the view
const TRAIL_POINTS = 240;     // per vehicle
const TRAIL_S = 60;           // trails show the last minute
const MIRROR_PERIOD_MS = 100;

const ease = (dt, tau) => 1 - Math.exp(-dt / tau);
const angleDiff = (a, b) => ((b - a + 540) % 360) - 180;

/** A "nice" length (1, 2 or 5 × 10^n) not below x. */
function niceStep(x) {
  const p = 10 ** Math.floor(Math.log10(x));
  for (const m of [1, 2, 5, 10]) if (m * p >= x) return m * p;
  return 10 * p;
}

export class PlanView {
  constructor(canvas, mirror, emptyEl, { onSelect }) {
    this.canvas = canvas;
    this.ctx = canvas.getContext('2d');
    this.mirror = mirror;
    this.emptyEl = emptyEl;
    this.onSelect = onSelect;
    this.tracks = new Map(); // id → track
    this.formation = null;   // last FormationStatus
    this.selected = null;
    this.view = null;        // {cn, ce, s}: centre north/east (m), scale (px/m)
    this.size = { w: 0, h: 0, dpr: 1 };
    this.cursor = null;      // {x, y} in CSS px
    this.raf = 0;
    this.lastT = 0;
    this.lastMirror = 0;
    this.zoom = 1;           // wheel zoom relative to the fit
    this.follow = null;      // id of the vehicle the view is centred on
    this.picking = null;     // {resolve} while a click is awaited as a point
    this.marks = new Map();  // key → {n, e, label}: go-to targets, gimbal ROIs …
    this.geofence = null;    // GET /api/v1/geofence
    this.targets = [];       // counter-UAS tracks (GET /api/v1/tracks)
    this.targetPx = new Map(); // track id → [x, y] where it was last drawn (CSS px)
    // Map, geofence editor, swarm origin (plan-map.js, plan-fence.js).
    this.mapLayer = null;
    this.editor = null;
    this.layers = [];        // addLayer: drawn over the fence, given clicks after the editor
    this.origin = null;      // {lat_deg, lon_deg} of the swarm frame's origin
    this.dragged = false;    // the last mouse press grabbed a vertex (the fence's, a layer's)
    this.swarms = [];        // hostile swarms (GET /api/v1/swarms)
    this.swarmPx = new Map(); // swarm id → {x, y, hull, cone, stations} as last drawn
    this.banner = document.createElement('div');
    this.banner.className = 'plan-banner';
    this.banner.dataset.testid = 'plan-banner';
    this.banner.hidden = true;
    canvas.parentElement.append(this.banner);
    canvas.addEventListener('wheel', (ev) => {
      ev.preventDefault();
      this.zoom = Math.min(50, Math.max(0.02, this.zoom * Math.exp(-ev.deltaY * 0.0015)));
      this.kick();
    }, { passive: false });

    new ResizeObserver(() => this.resize()).observe(canvas.parentElement);
    this.resize();
    canvas.addEventListener('click', (ev) => {
      if (this.picking) this.pickedPoint(ev);
      else if (this.dragged) this.dragged = false;
      else if (!(this.view && this.editors().some((e) => e.click && e.click(this.eventPoint(ev))))) this.pick(ev);
    });
    // The editors' vertex drags (the fence's, then the layers').
    canvas.addEventListener('mousedown', (ev) => {
      this.dragged = !!(this.view && this.editors().some((e) => e.down && e.down(this.eventPoint(ev))));
    });
    canvas.addEventListener('mouseup', () => { for (const e of this.editors()) if (e.up) e.up(); });
    canvas.addEventListener('mousemove', (ev) => {
      const r = canvas.getBoundingClientRect();
      this.cursor = { x: ev.clientX - r.left, y: ev.clientY - r.top };
      if (this.view) for (const e of this.editors()) if (e.move) e.move(this.eventPoint(ev));
      this.kick();
    });
    canvas.addEventListener('mouseleave', () => { this.cursor = null; this.kick(); });
  }

  /** New vehicle snapshots (the full list). */
  setVehicles(list) {
    const seen = new Set();
    for (const v of list) {
      seen.add(v.id);
      let t = this.tracks.get(v.id);
      const p = v.position;
      if (!t) {
        t = { id: v.id, v, n: 0, e: 0, hdg: 0, has: false, trail: [], li: null };
        this.tracks.set(v.id, t);
      }
      t.v = v;
      if (p && Number.isFinite(p.north_m) && Number.isFinite(p.east_m)) {
        if (!t.has) { // first fix: no easing from the origin
          t.n = p.north_m; t.e = p.east_m; t.hdg = v.heading_deg || 0; t.has = true;
        }
        const last = t.trail[t.trail.length - 1];
        const now = performance.now();
        if (!last || Math.hypot(last[0] - p.north_m, last[1] - p.east_m) > 0.25) {
          t.trail.push([p.north_m, p.east_m, now]);
          if (t.trail.length > TRAIL_POINTS) t.trail.shift();
        }
        while (t.trail.length > 1 && now - t.trail[0][2] > TRAIL_S * 1000) t.trail.shift();
      }
    }
    for (const [id, t] of this.tracks) {
      if (!seen.has(id)) {
        if (t.li) t.li.remove();
        this.tracks.delete(id);
      }
    }
    this.kick();
  }

  /** The counter-UAS tracks and hostile swarms as GET /api/v1/tracks and
   * GET /api/v1/swarms list them (swarm frame). */
  setTargets(tracks, swarms) {
    this.targets = Array.isArray(tracks) ? tracks : [];
    this.swarms = Array.isArray(swarms) ? swarms : [];
    this.kick();
  }

  /** The formation as GET /api/v1/formation or a formation_changed event shows it. */
  setFormation(status) {
    this.formation = status || null;
    this.kick();
  }

  setSelected(id) {
    this.selected = id;
    this.kick();
  }

  /** Centres the view on a vehicle (null: back to the whole swarm). */
  setFollow(id) {
    this.follow = id;
    this.kick();
  }

  /** The geofence (radius around the swarm origin, optional polygon), drawn dashed red. */
  setGeofence(fence) {
    this.geofence = fence || null;
    this.kick();
  }

  /** The map drawn under the plan (a MapLayer of plan-map.js). */
  setMapLayer(layer) {
    this.mapLayer = layer;
    if (this.origin) layer.setOrigin(this.origin);
    this.kick();
  }

  /** The fence editor (a FenceEditor of plan-fence.js): it gets clicks and drags first. */
  setEditor(editor) {
    this.editor = editor;
  }

  /**
   * A layer drawn over the fence: `draw(plan)`, and optionally `points()` (swarm-frame
   * {n, e} the fit keeps in view), `click(pt)` / `down(pt)` (true when taken), `move(pt)`,
   * `up()` and `mirror(dataset)` (its test hooks on the mirror list).
   */
  addLayer(layer) {
    this.layers.push(layer);
    this.kick();
  }

  /** What gets clicks and drags before a vehicle is picked: the fence editor, the layers. */
  editors() {
    return this.editor ? [this.editor, ...this.layers] : this.layers;
  }

  /** The swarm origin ({lat_deg, lon_deg}): the cursor's latitude / longitude, the map. */
  setOrigin(origin) {
    this.origin = origin || null;
    if (this.mapLayer) this.mapLayer.setOrigin(this.origin);
    this.kick();
  }

  /** The point of a mouse event: CSS px in the canvas and the swarm frame. */
  eventPoint(ev) {
    const r = this.canvas.getBoundingClientRect();
    const x = ev.clientX - r.left, y = ev.clientY - r.top;
    const { w, h } = this.size;
    const v = this.view;
    return { x, y, north_m: v.cn - (y - h / 2) / v.s, east_m: v.ce + (x - w / 2) / v.s };
  }

  /** Back to the view that fits the whole swarm. */
  fit() {
    this.zoom = 1;
    this.follow = null;
    this.kick();
  }

  /** A labelled cross on the plan (key replaces an earlier mark of the same key). */
  setMark(key, n, e, label) {
    this.marks.set(key, { n, e, label });
    this.kick();
  }

  clearMark(key) {
    if (this.marks.delete(key)) this.kick();
  }

  /** Resolves to the swarm-frame point of the next click on the plan ({north_m, east_m}), or null. */
  pickPoint(label) {
    this.cancelPick();
    this.banner.textContent = label;
    this.banner.hidden = false;
    this.canvas.classList.add('picking');
    // On a narrow screen the plan may be scrolled away from the button that asked.
    this.canvas.parentElement.scrollIntoView({ block: 'nearest' });
    return new Promise((resolve) => { this.picking = { resolve }; });
  }

  /** Ends a pending pickPoint with null; true when one was pending. */
  cancelPick() {
    if (!this.picking) return false;
    this.endPick(null);
    return true;
  }

  endPick(point) {
    const { resolve } = this.picking;
    this.picking = null;
    this.banner.hidden = true;
    this.canvas.classList.remove('picking');
    resolve(point);
  }

  pickedPoint(ev) {
    if (!this.view) return;
    const r = this.canvas.getBoundingClientRect();
    const x = ev.clientX - r.left, y = ev.clientY - r.top;
    const { w, h } = this.size;
    const v = this.view;
    this.endPick({ north_m: v.cn - (y - h / 2) / v.s, east_m: v.ce + (x - w / 2) / v.s });
  }

  resize() {
    const r = this.canvas.parentElement.getBoundingClientRect();
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.floor(r.width));
    const h = Math.max(1, Math.floor(r.height));
    if (w === this.size.w && h === this.size.h && dpr === this.size.dpr) return;
    this.size = { w, h, dpr };
    this.canvas.width = Math.round(w * dpr);
    this.canvas.height = Math.round(h * dpr);
    this.canvas.style.width = `${w}px`;
    this.canvas.style.height = `${h}px`;
    this.view = null; // refit at once
    this.kick();
  }

  /** Schedules a frame if none is pending. */
  kick() {
    if (!this.raf) this.raf = requestAnimationFrame((t) => this.frame(t));
  }

  // Slot targets to draw: from the vehicles' own formation slots (fresh at 10 Hz), else
  // from the formation status.
  slots() {
    const out = [];
    for (const t of this.tracks.values()) {
      const f = t.v.formation;
      if (f && f.target) out.push({ id: t.id, n: f.target.north_m, e: f.target.east_m, leader: !!f.leader, slot: f.slot });
    }
    if (!out.length && this.formation && this.formation.active && Array.isArray(this.formation.members)) {
      for (const m of this.formation.members) {
        if (m.target) out.push({ id: m.id, n: m.target.north_m, e: m.target.east_m, leader: m.slot === 0, slot: m.slot });
      }
    }
    return out;
  }

  leaderId() {
    for (const t of this.tracks.values()) if (t.v.formation && t.v.formation.leader) return t.id;
    return this.formation && this.formation.active ? this.formation.leader_id : null;
  }

  /** The view that fits every vehicle, slot and live (not lost) counter-UAS track. */
  fitView(slots) {
    let minN = Infinity, maxN = -Infinity, minE = Infinity, maxE = -Infinity;
    const add = (n, e) => {
      minN = Math.min(minN, n); maxN = Math.max(maxN, n);
      minE = Math.min(minE, e); maxE = Math.max(maxE, e);
    };
    for (const t of this.tracks.values()) {
      const p = t.v.position;
      if (t.has && p) add(p.north_m, p.east_m);
    }
    for (const s of slots) add(s.n, s.e);
    for (const ed of this.editors()) if (ed.points) for (const q of ed.points()) add(q.n, q.e);
    for (const t of this.targets) {
      const p = t.position;
      if (t.status !== 'lost' && p && Number.isFinite(p.north_m) && Number.isFinite(p.east_m)) add(p.north_m, p.east_m);
    }
    if (minN === Infinity) return null;
    const cn = (minN + maxN) / 2;
    const ce = (minE + maxE) / 2;
    const spanN = Math.max(MIN_SPAN_M, (maxN - minN) * 1.15);
    const spanE = Math.max(MIN_SPAN_M, (maxE - minE) * 1.15);
    const { w, h } = this.size;
    const s = Math.max(1e-3, Math.min((w - 2 * PAD_PX) / spanE, (h - 2 * PAD_PX) / spanN)) * this.zoom;
    const f = this.follow && this.tracks.get(this.follow);
    if (f && f.has && f.v.position) return { cn: f.v.position.north_m, ce: f.v.position.east_m, s };
    return { cn, ce, s };
  }

  frame(t) {
    this.raf = 0;
    const dt = this.lastT ? Math.min(200, t - this.lastT) : 16;
    this.lastT = t;
    let moving = false;

    // Ease markers towards their latest fix.
    const km = ease(dt, TAU_MARKER_MS);
    for (const tr of this.tracks.values()) {
      const p = tr.v.position;
      if (!tr.has || !p) continue;
      const dn = p.north_m - tr.n;
      const de = p.east_m - tr.e;
      const dh = angleDiff(tr.hdg, tr.v.heading_deg || 0);
      if (Math.abs(dn) + Math.abs(de) > 0.005 || Math.abs(dh) > 0.2) {
        tr.n += dn * km; tr.e += de * km; tr.hdg = (tr.hdg + dh * km + 360) % 360;
        moving = true;
      } else {
        tr.n = p.north_m; tr.e = p.east_m; tr.hdg = tr.v.heading_deg || 0;
      }
    }

    // Ease the view towards the fit (scale in log space).
    const slots = this.slots();
    const fit = this.fitView(slots);
    if (fit) {
      if (!this.view) {
        this.view = { ...fit };
      } else {
        const kv = ease(dt, TAU_VIEW_MS);
        const v = this.view;
        const ds = Math.log(fit.s / v.s);
        const px = Math.hypot(fit.cn - v.cn, fit.ce - v.ce) * v.s;
        if (Math.abs(ds) > 0.002 || px > 0.3) {
          v.s *= Math.exp(ds * kv);
          v.cn += (fit.cn - v.cn) * kv;
          v.ce += (fit.ce - v.ce) * kv;
          moving = true;
        } else {
          Object.assign(v, fit);
        }
      }
    }

    this.draw(slots);
    // The mirror follows at up to 10 Hz while moving and exactly once it settles.
    if (!moving || t - this.lastMirror >= MIRROR_PERIOD_MS) {
      this.updateMirror(moving);
      this.lastMirror = t;
    }
    if (moving) this.kick();
    else this.lastT = 0;
  }

  toPx(n, e) {
    const { w, h } = this.size;
    const v = this.view;
    return [w / 2 + (e - v.ce) * v.s, h / 2 - (n - v.cn) * v.s];
  }

  draw(slots) {
    const { ctx } = this;
    const { w, h, dpr } = this.size;
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.clearRect(0, 0, w, h);
    if (this.mapLayer) this.mapLayer.draw(this);
    const drawn = [...this.tracks.values()].filter((t) => t.has && t.v.position);
    this.emptyEl.hidden = drawn.length > 0;
    if (!this.view || !drawn.length) return;
    const v = this.view;

    // Grid at a nice step of about 70 px, brighter axes through the swarm origin.
    const step = niceStep(70 / v.s);
    ctx.lineWidth = 1;
    const e0 = v.ce - w / 2 / v.s, e1 = v.ce + w / 2 / v.s;
    const n0 = v.cn - h / 2 / v.s, n1 = v.cn + h / 2 / v.s;
    ctx.strokeStyle = 'rgba(140,160,190,0.08)';
    ctx.beginPath();
    for (let e = Math.ceil(e0 / step) * step; e <= e1; e += step) {
      const [x] = this.toPx(0, e);
      ctx.moveTo(Math.round(x) + 0.5, 0); ctx.lineTo(Math.round(x) + 0.5, h);
    }
    for (let n = Math.ceil(n0 / step) * step; n <= n1; n += step) {
      const [, y] = this.toPx(n, 0);
      ctx.moveTo(0, Math.round(y) + 0.5); ctx.lineTo(w, Math.round(y) + 0.5);
    }
    ctx.stroke();
    const [ox, oy] = this.toPx(0, 0);
    ctx.strokeStyle = 'rgba(140,160,190,0.22)';
    ctx.beginPath();
    ctx.moveTo(Math.round(ox) + 0.5, 0); ctx.lineTo(Math.round(ox) + 0.5, h);
    ctx.moveTo(0, Math.round(oy) + 0.5); ctx.lineTo(w, Math.round(oy) + 0.5);
    ctx.stroke();

    drawFence(this);
    for (const l of this.layers) l.draw(this);
    drawHazards(this);
    drawSwarms(this);
    drawTargets(this);

    // Trails.
    ctx.lineWidth = 1.5;
    ctx.lineJoin = 'round';
    for (const t of drawn) {
      if (t.trail.length < 2) continue;
      ctx.strokeStyle = CLASS_COLOUR[stateClass(t.v)];
      ctx.globalAlpha = 0.22;
      ctx.beginPath();
      t.trail.forEach(([n, e], i) => {
        const [x, y] = this.toPx(n, e);
        if (i) ctx.lineTo(x, y); else ctx.moveTo(x, y);
      });
      const [x, y] = this.toPx(t.n, t.e);
      ctx.lineTo(x, y);
      ctx.stroke();
    }
    ctx.globalAlpha = 1;

    // Formation slots: hollow circles (leader's slot: a hollow diamond), with a dashed
    // line from each member to its slot while it is off by more than half a metre.
    const formCol = CLASS_COLOUR.formation;
    for (const s of slots) {
      const [x, y] = this.toPx(s.n, s.e);
      const tr = this.tracks.get(s.id);
      if (tr && tr.has) {
        const [vx, vy] = this.toPx(tr.n, tr.e);
        if (Math.hypot(vx - x, vy - y) > Math.max(4, 0.5 * v.s)) {
          ctx.setLineDash([3, 4]);
          ctx.strokeStyle = 'rgba(62,207,142,0.45)';
          ctx.lineWidth = 1;
          ctx.beginPath(); ctx.moveTo(vx, vy); ctx.lineTo(x, y); ctx.stroke();
          ctx.setLineDash([]);
        }
      }
      ctx.strokeStyle = formCol;
      ctx.lineWidth = 1.5;
      ctx.beginPath();
      if (s.leader) {
        ctx.moveTo(x, y - 8); ctx.lineTo(x + 8, y); ctx.lineTo(x, y + 8); ctx.lineTo(x - 8, y); ctx.closePath();
      } else {
        ctx.arc(x, y, 6, 0, Math.PI * 2);
      }
      ctx.stroke();
    }

    drawMarks(this);

    // Vehicles: heading arrows, selection ring, leader ring, labels.
    const leader = this.leaderId();
    const many = drawn.length > 24;
    const size = many ? 8 : 11;
    ctx.font = `${many ? 10 : 11}px system-ui, -apple-system, "Segoe UI", sans-serif`;
    ctx.textBaseline = 'middle';
    for (const t of drawn.sort((a, b) => compareIds(a.id, b.id))) {
      const [x, y] = this.toPx(t.n, t.e);
      t.px = x; t.py = y;
      const cls = stateClass(t.v);
      const col = CLASS_COLOUR[cls];
      if (t.id === this.selected) {
        ctx.strokeStyle = '#ffffff';
        ctx.lineWidth = 1.5;
        ctx.beginPath(); ctx.arc(x, y, size + 7, 0, Math.PI * 2); ctx.stroke();
      }
      if (t.id === leader) {
        ctx.strokeStyle = '#ffd166';
        ctx.lineWidth = 2;
        ctx.beginPath(); ctx.arc(x, y, size + 3, 0, Math.PI * 2); ctx.stroke();
      }
      ctx.save();
      ctx.translate(x, y);
      ctx.rotate((t.hdg * Math.PI) / 180);
      ctx.beginPath();
      ctx.moveTo(0, -size);
      ctx.lineTo(size * 0.7, size * 0.75);
      ctx.lineTo(0, size * 0.35);
      ctx.lineTo(-size * 0.7, size * 0.75);
      ctx.closePath();
      if (cls === 'alert' && t.v.link && t.v.link.connected === false) {
        ctx.setLineDash([2, 2]);
        ctx.strokeStyle = col; ctx.lineWidth = 1.5; ctx.stroke();
        ctx.setLineDash([]);
      } else {
        ctx.fillStyle = col; ctx.fill();
        ctx.strokeStyle = 'rgba(0,0,0,0.55)'; ctx.lineWidth = 1; ctx.stroke();
      }
      ctx.restore();
    }

    // Labels under the markers: id (★ for the leader), then the height above home. A label
    // that would overlap one already placed is left out (selected and leader go first).
    const prio = (t) => (t.id === this.selected ? 0 : t.id === leader ? 1 : 2);
    const placed = [];
    ctx.textAlign = 'center';
    for (const t of [...drawn].sort((a, b) => prio(a) - prio(b))) {
      const id = t.id === leader ? `${t.id} ★` : t.id;
      const alt = `${fmt(t.v.position.relative_alt_m, 1)} m`;
      const tw = Math.max(ctx.measureText(id).width, many ? 0 : ctx.measureText(alt).width);
      const r = { x: t.px - tw / 2 - 3, y: t.py + size + 4, w: tw + 6, h: many ? 14 : 27 };
      if (placed.some((q) => r.x < q.x + q.w && q.x < r.x + r.w && r.y < q.y + q.h && q.y < r.y + r.h)) continue;
      placed.push(r);
      ctx.fillStyle = 'rgba(8,11,16,0.72)';
      ctx.fillRect(r.x, r.y, r.w, r.h);
      ctx.fillStyle = t.id === leader ? '#ffd166' : '#dfe6f0';
      ctx.fillText(id, t.px, r.y + 7);
      if (!many) {
        ctx.fillStyle = '#8d97a8';
        ctx.fillText(alt, t.px, r.y + 20);
      }
    }
    ctx.textAlign = 'start';

    drawScale(this, step);
    drawNorth(this);
    drawCursor(this);
  }

  /**
   * Mirrors every drawn marker into the hidden list (ids, pixel and metric positions);
   * `moving`: the picture is still easing (markers or view).
   */
  updateMirror(moving = false) {
    if (this.view) {
      // The view itself: the canvas centre in the swarm frame and the scale (px per m),
      // and whether it is still easing towards its fit (data-moving).
      const md = this.mirror.dataset;
      md.moving = moving ? 'true' : 'false';
      md.cn = this.view.cn.toFixed(2);
      md.ce = this.view.ce.toFixed(2);
      md.scale = this.view.s.toFixed(4);
      md.geofenceRadius = this.geofence ? String(this.geofence.radius_m) : '';
      const d = this.editor && this.editor.draft;
      md.fenceEditing = d ? 'true' : 'false';
      md.fenceVertices = JSON.stringify((d || this.geofence || {}).polygon || []);
      if (this.mapLayer) this.mapLayer.mirror(md);
      for (const l of this.layers) if (l.mirror) l.mirror(md);
    }
    const ids = [...this.tracks.keys()].sort(compareIds);
    let prev = null;
    for (const id of ids) {
      const t = this.tracks.get(id);
      const shown = t.has && t.v.position && this.view && Number.isFinite(t.px);
      if (!shown) {
        if (t.li) { t.li.remove(); t.li = null; }
        continue;
      }
      if (!t.li) {
        t.li = document.createElement('li');
        t.li.dataset.vehicleId = id;
        t.li.dataset.testid = 'plan-marker';
      }
      const want = prev ? prev.nextSibling : this.mirror.firstChild;
      if (want !== t.li) this.mirror.insertBefore(t.li, want);
      prev = t.li;
      const d = t.li.dataset;
      const attrs = {
        x: t.px.toFixed(1), y: t.py.toFixed(1),
        north: t.n.toFixed(2), east: t.e.toFixed(2),
        heading: t.hdg.toFixed(0), state: String(t.v.state),
      };
      for (const k in attrs) if (d[k] !== attrs[k]) d[k] = attrs[k];
      const text = `${id} ${attrs.state}, north ${fmt(t.n, 1)} m, east ${fmt(t.e, 1)} m, heading ${attrs.heading}°`;
      if (t.li.textContent !== text) t.li.textContent = text;
    }
  }

  /** Click: select the nearest vehicle within 18 px, or clear the selection. */
  pick(ev) {
    const r = this.canvas.getBoundingClientRect();
    const x = ev.clientX - r.left, y = ev.clientY - r.top;
    let best = null, bestD = 18;
    for (const t of this.tracks.values()) {
      if (!Number.isFinite(t.px)) continue;
      const d = Math.hypot(t.px - x, t.py - y);
      if (d < bestD) { best = t.id; bestD = d; }
    }
    this.onSelect(best);
  }
}
