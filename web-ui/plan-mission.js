// A mission step on the plan (a layer of plan.js): the survey's polygon filled with the
// lanes the coordinator flies (lanes.js, each vehicle's block in its own colour once the
// step has vehicles), a patrol's closed route, a transit's waypoints as a line, a station's
// points as numbered markers. Two layers: `draft`, the step selected in the Mission tab's
// editor, whose points clicks add (a polygon or route closes on a click on its first
// point) and drags move, and where a point a refusal names (`steps[1].polygon[2]`) is
// ringed in red with the reason; `flight`, the step the selected mission flies.
//
// Test hooks on the plan's mirror list, per layer NAME (draft, flight):
// data-NAME-step (index shown, or ''), data-NAME-kind, data-NAME-points (JSON [[n, e],
// ...]), data-NAME-lanes (lanes drawn), data-NAME-drawing (the field clicks add to, or
// ''), data-NAME-error-point (JSON [n, e] of the point marked, or '').

import { lanes, split, surveySpacing } from './lanes.js';
import { vehicleColour } from './model.js';

/** The field holding each kind's points. */
export const GEOMETRY = { survey: 'polygon', patrol: 'route', transit: 'waypoints', station: 'points' };
/** Kinds whose points close into a ring (a click on the first point ends the drawing). */
const CLOSED = new Set(['survey', 'patrol']);
const FONT = '10px system-ui, -apple-system, "Segoe UI", sans-serif';
const ERR = '#ff5566';
/** A press this close to a point (CSS px) grabs it; a click this close to the first closes. */
const GRAB_PX = 9;
const round = (x) => Math.round(x * 10) / 10;

export class MissionLayer {
  /**
   * plan: the PlanView; name: the test hooks' prefix; colour: its lines (CSS colour, hex);
   * onChange(): the shown step's points changed by a click or a drag.
   */
  constructor(plan, { name, colour, onChange = () => {} }) {
    this.plan = plan;
    this.name = name;
    this.colour = colour;
    this.onChange = onChange;
    this.shown = null;     // {index, step, editable, vehicles, lanesDone, label}
    this.drawing = false;  // clicks add points to the shown step
    this.dragging = -1;
    this.errorPoint = null; // {n, e, text}
    this.drawnLanes = 0;
    plan.addLayer(this);
  }

  /**
   * Shows step `step` (a plan's step object, its points edited in place when `editable`)
   * of index `index`; null shows nothing. `vehicles`: the step's vehicles in order (the
   * survey's lane blocks); `lanesDone`: the survey's lanes flown so far; `spacing(step)`:
   * its lane spacing, metres (default: as the coordinator takes the API's step).
   */
  show(index, step, { editable = false, vehicles = [], lanesDone = null, label = '', spacing = surveySpacing } = {}) {
    const same = this.shown && step && this.shown.step === step;
    this.shown = step ? { index, step, editable, vehicles, lanesDone, label, spacing } : null;
    if (!same) { this.drawing = false; this.dragging = -1; }
    this.plan.kick();
  }

  /** The shown step's points (the array edited in place), or null. */
  pts() {
    const s = this.shown && this.shown.step;
    const f = s && GEOMETRY[s.kind];
    if (!f) return null;
    if (!Array.isArray(s[f])) s[f] = [];
    return s[f];
  }

  /** Clicks add points to the shown step (true), or stop adding (false). */
  setDrawing(on) {
    this.drawing = !!(on && this.shown && this.shown.editable && this.pts());
    this.plan.canvas.classList.toggle('picking', this.drawing);
    this.plan.kick();
  }

  /** Rings point `[n, e]` with `text` (a refusal's reason); null clears it. */
  markError(point, text) {
    this.errorPoint = point ? { n: point[0], e: point[1], text } : null;
    this.plan.kick();
  }

  points() {
    const out = (this.pts() || []).map(([n, e]) => ({ n, e }));
    if (this.errorPoint) out.push(this.errorPoint);
    return out;
  }

  nearPoint(pt) {
    return (this.pts() || []).findIndex(([n, e]) => {
      const [x, y] = this.plan.toPx(n, e);
      return Math.hypot(x - pt.x, y - pt.y) <= GRAB_PX;
    });
  }

  click(pt) {
    if (!this.drawing) return false;
    const pts = this.pts();
    if (CLOSED.has(this.shown.step.kind) && pts.length >= 3 && this.nearPoint(pt) === 0) {
      this.setDrawing(false);
    } else {
      pts.push([round(pt.north_m), round(pt.east_m)]);
    }
    this.onChange();
    this.plan.kick();
    return true;
  }

  down(pt) {
    if (this.drawing || !this.shown || !this.shown.editable) return false;
    this.dragging = this.nearPoint(pt);
    return this.dragging >= 0;
  }

  move(pt) {
    if (this.dragging < 0) return;
    this.pts()[this.dragging] = [round(pt.north_m), round(pt.east_m)];
    this.plan.kick();
  }

  up() {
    if (this.dragging < 0) return;
    this.dragging = -1;
    this.onChange();
  }

  draw(p) {
    this.drawnLanes = 0;
    const s = this.shown && this.shown.step;
    const pts = this.pts();
    const { ctx } = p;
    ctx.save();
    ctx.font = FONT;
    ctx.lineWidth = 2;
    ctx.textBaseline = 'middle';
    if (pts && pts.length) {
      const xy = pts.map(([n, e]) => p.toPx(n, e));
      const ring = CLOSED.has(s.kind) && !this.drawing;
      if (s.kind === 'survey') this.drawLanes(p);
      if (s.kind !== 'station') {
        ctx.beginPath();
        xy.forEach(([x, y], i) => (i ? ctx.lineTo(x, y) : ctx.moveTo(x, y)));
        if (ring) ctx.closePath();
        if (s.kind === 'survey' && pts.length >= 3) { ctx.globalAlpha = 0.13; ctx.fillStyle = this.colour; ctx.fill(); ctx.globalAlpha = 1; }
        ctx.strokeStyle = this.colour;
        ctx.setLineDash(s.kind === 'transit' ? [] : [6, 4]);
        ctx.stroke();
        ctx.setLineDash([]);
      }
      ctx.textAlign = 'center';
      xy.forEach(([x, y], i) => {
        ctx.fillStyle = this.colour;
        if (s.kind === 'station') {
          ctx.beginPath(); ctx.arc(x, y, 8, 0, Math.PI * 2); ctx.fill();
          ctx.fillStyle = '#0b1016';
          ctx.fillText(String(i + 1), x, y + 0.5);
        } else {
          ctx.fillRect(x - 3.5, y - 3.5, 7, 7);
          ctx.fillText(String(i + 1), x + 9, y - 9);
        }
      });
      // The caption above the top of the drawing, clear of the markers and their labels
      // (drawn under the points).
      const left = Math.min(...xy.map(([x]) => x));
      const top = Math.min(...xy.map(([, y]) => y));
      const text = this.caption();
      const w = ctx.measureText(text).width;
      ctx.textAlign = 'left';
      ctx.fillStyle = 'rgba(8,11,16,0.72)';
      ctx.fillRect(left - 3, top - 31, w + 6, 14);
      ctx.fillStyle = '#dfe6f0';
      ctx.fillText(text, left, top - 24);
    }
    this.drawErrorPoint(p);
    ctx.restore();
    ctx.textAlign = 'start';
  }

  /** One line above the drawing: the step, and the lanes (flown) of a survey. */
  caption() {
    const { index, step, label, lanesDone } = this.shown;
    let text = `${index + 1}. ${step.kind}${label ? ` · ${label}` : ''}`;
    if (step.kind === 'survey') {
      text += lanesDone == null ? ` · ${this.drawnLanes} lanes` : ` · ${lanesDone} of ${this.drawnLanes} lanes flown`;
    }
    return text;
  }

  /** The survey's lanes, each vehicle's block in its colour (one colour before a start). */
  drawLanes(p) {
    const { step, vehicles, spacing } = this.shown;
    const all = step.polygon.length >= 3 ? lanes(step.polygon, spacing(step)) : [];
    this.drawnLanes = all.length;
    const { ctx } = p;
    ctx.lineWidth = 1.5;
    split(all, vehicles.length || 1).forEach((block, b) => {
      ctx.strokeStyle = vehicles.length ? vehicleColour(b) : this.colour;
      ctx.beginPath();
      for (const l of block) {
        const [x0, y0] = p.toPx(l.start[0], l.start[1]);
        const [x1, y1] = p.toPx(l.end[0], l.end[1]);
        ctx.moveTo(x0, y0); ctx.lineTo(x1, y1);
      }
      ctx.stroke();
    });
    ctx.lineWidth = 2;
  }

  drawErrorPoint(p) {
    const m = this.errorPoint;
    if (!m) return;
    const { ctx } = p;
    const [x, y] = p.toPx(m.n, m.e);
    ctx.strokeStyle = ERR;
    ctx.lineWidth = 2.5;
    ctx.beginPath(); ctx.arc(x, y, 11, 0, Math.PI * 2); ctx.stroke();
    ctx.fillStyle = ERR;
    ctx.textAlign = 'left';
    const text = m.text.length > 70 ? `${m.text.slice(0, 69)}…` : m.text;
    ctx.fillText(text, x + 15, y - 12);
  }

  mirror(md) {
    const s = this.shown;
    const put = (key, value) => { md[this.name + key] = value; };
    put('Step', s ? String(s.index) : '');
    put('Kind', s ? s.step.kind : '');
    put('Points', JSON.stringify(this.pts() || []));
    put('Lanes', String(this.drawnLanes));
    put('Drawing', this.drawing ? GEOMETRY[s.step.kind] : '');
    put('ErrorPoint', this.errorPoint ? JSON.stringify([this.errorPoint.n, this.errorPoint.e]) : '');
  }
}
