// The geofence panel of the Swarm tab: what is in force (version, polygon, exclusions,
// ceiling, breach action), and the editor's controls: Edit copies the fence in force into
// a draft drawn on the plan (plan-fence.js), Draw polygon / Exclusion circle take clicks
// on the plan, the inputs set radius, ceiling, floor and PX4's breach action, Apply sends
// it (PUT /api/v1/geofence: answered once every autopilot holds it, or refused naming the
// field or the vehicles), Cancel drops the draft.

import * as api from './api.js';
import { FenceEditor } from './plan-fence.js';

const $ = (id) => document.getElementById(id);

const HINTS = {
  polygon: 'Click the plan at each vertex of the inclusion polygon; click the first vertex (or Finish) to close it.',
  circle: 'Click the centre of the exclusion circle, then a point on its rim.',
  move: 'Drag a vertex to move it. Apply sends the fence to every vehicle.',
};

export class FencePanel {
  constructor({ plan, toasts, log }) {
    this.plan = plan;
    this.toasts = toasts;
    this.log = log;
    this.fence = null;      // the fence in force
    this.version = null;    // its version, once an event or an answer said
    this.editor = new FenceEditor(plan, () => this.refresh());
    plan.setEditor(this.editor);
    $('fence-edit').addEventListener('click', () => this.edit());
    $('fence-draw-polygon').addEventListener('click', () => this.editor.drawPolygon());
    $('fence-add-circle').addEventListener('click', () => this.editor.addCircle());
    $('fence-finish').addEventListener('click', () => this.editor.finish());
    $('fence-no-polygon').addEventListener('click', () => {
      if (this.editor.draft) { this.editor.draft.polygon = []; this.editor.changed(); }
    });
    $('fence-no-exclusions').addEventListener('click', () => {
      if (this.editor.draft) { this.editor.draft.exclusions = []; this.editor.changed(); }
    });
    $('fence-cancel').addEventListener('click', () => this.editor.stop());
    $('fence-apply').addEventListener('click', () => this.apply());
    this.refresh();
  }

  /** The fence in force (GET /api/v1/geofence, a geofence_changed event). */
  setFence(fence, version) {
    this.fence = fence;
    if (version != null) this.version = version;
    this.plan.setGeofence(fence);
    this.refresh();
  }

  edit() {
    if (!this.fence) return;
    this.editor.start(this.fence);
    $('fence-radius').value = this.fence.radius_m;
    $('fence-ceiling').value = this.fence.max_altitude_m;
    $('fence-floor').value = this.fence.min_altitude_m || 0;
    $('fence-action').value = this.fence.breach_action || 'hold';
    // The plan may be scrolled away on a narrow screen.
    this.plan.canvas.parentElement.scrollIntoView({ block: 'nearest' });
  }

  refresh() {
    const f = this.fence;
    const parts = [];
    if (f) {
      if (this.version != null) parts.push(`v${this.version}`);
      parts.push(f.polygon && f.polygon.length >= 3 ? `polygon of ${f.polygon.length}` : `${f.radius_m} m circle`);
      if (f.exclusions && f.exclusions.length) parts.push(`${f.exclusions.length} excluded`);
      parts.push(`≤ ${f.max_altitude_m} m`, `breach: ${f.breach_action || 'hold'}`);
    }
    $('fence-summary').textContent = parts.join(' · ') || '–';
    const editing = this.editor.editing;
    $('fence-editor').hidden = !editing;
    $('fence-edit').disabled = editing || !f;
    $('fence-hint').textContent = editing ? HINTS[this.editor.mode] : '';
    // The crosshair while clicks go to the editor (a go-to pick owns it otherwise).
    if (editing) this.plan.canvas.classList.toggle('picking', this.editor.mode !== 'move');
    else if (!this.plan.picking) this.plan.canvas.classList.remove('picking');
  }

  /** The draft with the panel's inputs, as the PUT body. */
  body() {
    const d = this.editor.draft;
    const num = (id) => Number($(id).value);
    return {
      ...d,
      radius_m: num('fence-radius'),
      max_altitude_m: num('fence-ceiling'),
      min_altitude_m: num('fence-floor'),
      breach_action: $('fence-action').value,
    };
  }

  async apply() {
    if (!this.editor.draft) return;
    this.editor.finish();
    const body = this.body();
    const btn = $('fence-apply');
    btn.disabled = true;
    const res = await api.putGeofence(body);
    btn.disabled = false;
    if (res.ok) {
      const n = Object.keys(res.data.vehicles || {}).length;
      this.editor.stop();
      this.setFence(res.data.fence, res.data.version);
      this.toasts.show('ok', `Geofence v${res.data.version}`, `in force; held by ${n} vehicle${n === 1 ? '' : 's'}`);
      this.log.note('api', 'ok', 'geofence', `geofence version ${res.data.version} held by ${n} vehicles`);
    } else {
      const field = res.data.field ? ` (${res.data.field})` : '';
      this.toasts.show('error', `Geofence refused${field}`, res.data.error);
      this.log.note('api', 'error', 'geofence', `refused${field}: ${res.data.error}`);
      const input = { radius_m: 'fence-radius', max_altitude_m: 'fence-ceiling', min_altitude_m: 'fence-floor' }[res.data.field];
      if (input) $(input).setAttribute('aria-invalid', 'true');
    }
  }
}
