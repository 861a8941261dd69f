// The mission plan's step kinds as the Mission tab edits them (core/mission/src/plan.rs):
// each kind's fields with their units and defaults, a step's card (its inputs, its points
// drawn on the plan), and the plan's JSON as POST /api/v1/missions takes it.
//
// A step is kept as the API's JSON object (`{kind, group?, altitude_m, ...}`, nested
// `camera` and `formation`), edited in place by its card's inputs; what the API has two
// ways of saying (a survey's lanes spaced by `lane_spacing_m` or by a `camera`, a transit
// with or without a `formation`) is chosen by the card and settled in `planBody`.
// Test hooks: li[data-testid="mission-step"][data-step=i][data-kind], its inputs and
// selects [data-field="altitude_m" | "camera.hfov_deg" | "group" | ...], the points' row
// [data-field="polygon" | "route" | "waypoints" | "points"] with button[data-act="draw"]
// and [data-field="count"], and p[data-field="error"].

import { GEOMETRY } from './plan-mission.js';

export const KINDS = ['takeoff', 'transit', 'survey', 'patrol', 'station', 'return', 'land'];
/** Transit formations (the shapes skein flies without custom offsets). */
const SHAPES = ['line', 'column', 'wedge', 'echelon_left', 'echelon_right', 'diamond', 'circle', 'grid'];

const num = (field, label, unit, def, opts = {}) => ({ type: 'num', field, label, unit, def, ...opts });
const INTERVAL = num('interval_s', 'Interval', 's', 2, { min: 0, max: 60, step: 0.5 });

/** Each kind's fields, in the card's order; `def` fills a new step (`null`: left empty). */
const FIELDS = {
  takeoff: [num('altitude_m', 'Altitude', 'm', 10, { title: 'above each vehicle’s home' }), INTERVAL],
  transit: [
    { type: 'points', field: 'waypoints' },
    num('altitude_m', 'Altitude', 'm', 15), num('speed_m_s', 'Speed', 'm/s', 4, { step: 0.5 }),
    { type: 'choice', field: 'formation.shape', label: 'Formation', options: [['', 'none'], ...SHAPES.map((s) => [s, s.replace('_', ' ')])] },
    num('formation.spacing_m', 'Spacing', 'm', 8, { when: (s) => !!(s.formation && s.formation.shape) }),
  ],
  survey: [
    { type: 'points', field: 'polygon' },
    num('altitude_m', 'Altitude', 'm', 15),
    { type: 'choice', field: 'spacing', label: 'Lanes by', options: [['lanes', 'spacing'], ['camera', 'camera']] },
    num('lane_spacing_m', 'Spacing', 'm', 8, { when: (s, ui) => ui.spacing !== 'camera' }),
    num('camera.hfov_deg', 'FOV', '°', 60, { min: 1, max: 170, when: (s, ui) => ui.spacing === 'camera' }),
    num('camera.overlap', 'Overlap', '', 0.2, { min: 0, max: 0.9, step: 0.05, when: (s, ui) => ui.spacing === 'camera' }),
  ],
  patrol: [
    { type: 'points', field: 'route' },
    num('altitude_m', 'Altitude', 'm', 15),
    num('duration_s', 'Duration', 's', null, { placeholder: '∞', title: 'empty: until skipped' }),
  ],
  station: [{ type: 'points', field: 'points' }, num('altitude_m', 'Altitude', 'm', 12), num('duration_s', 'Hold', 's', 30)],
  return: [INTERVAL],
  land: [INTERVAL],
};

/** A field's value in a step (`camera.hfov_deg` reads step.camera.hfov_deg). */
export function getPath(obj, path) {
  return path.split('.').reduce((o, k) => (o == null ? undefined : o[k]), obj);
}

/** Sets (or, for undefined, deletes) a field of a step, making nested objects as needed. */
export function setPath(obj, path, value) {
  const keys = path.split('.');
  const last = keys.pop();
  let o = obj;
  for (const k of keys) {
    if (o[k] == null || typeof o[k] !== 'object') o[k] = {};
    o = o[k];
  }
  if (value === undefined) delete o[last]; else o[last] = value;
}

/** A new step of `kind` with its defaults (both ways of spacing a survey's lanes). */
export function newStep(kind) {
  const step = { kind };
  for (const f of FIELDS[kind]) {
    if (f.type === 'points') step[f.field] = [];
    else if (f.type === 'num' && f.def != null) setPath(step, f.field, f.def);
  }
  return step;
}

/** A stored plan's step as the editor keeps it: the API's nulls (options absent) left out. */
export function fromApi(step) {
  const out = {};
  for (const [k, v] of Object.entries(step)) {
    if (v == null) continue;
    out[k] = v && typeof v === 'object' && !Array.isArray(v) ? fromApi(v) : JSON.parse(JSON.stringify(v));
  }
  return out;
}

/** The card's choices of a step as the API has it (a stored plan opened again). */
export function uiOf(step) {
  return { spacing: step.kind === 'survey' && !Number.isFinite(step.lane_spacing_m) && step.camera ? 'camera' : 'lanes' };
}

/** The plan as POST /api/v1/missions takes it: each step as its card chose it. */
export function planBody(draft, uiFor) {
  const steps = draft.steps.map((s) => {
    const out = JSON.parse(JSON.stringify(s));
    if (!out.group) delete out.group;
    if (out.kind === 'survey') {
      if (uiFor(s).spacing === 'camera') delete out.lane_spacing_m; else delete out.camera;
    }
    if (out.kind === 'transit' && !(out.formation && out.formation.shape)) delete out.formation;
    return out;
  });
  return { name: draft.name, groups: draft.groups, steps, abort: draft.abort };
}

const esc = (s) => String(s).replace(/[&<>"]/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;' })[c]);

function inputHtml(f, step, ui) {
  if (f.type === 'points') {
    return `<div class="m-points" data-field="${f.field}"><span class="m-points-label">${f.field}</span>
      <span data-field="count"></span>
      <button type="button" class="btn tiny" data-act="draw" data-testid="mission-draw">Draw</button>
      <button type="button" class="btn tiny" data-act="clear">Clear</button></div>`;
  }
  const hidden = f.when && !f.when(step, ui) ? ' hidden' : '';
  if (f.type === 'choice') {
    const v = f.field === 'spacing' ? ui.spacing : getPath(step, f.field) || '';
    const opts = f.options.map(([val, text]) => `<option value="${val}"${val === v ? ' selected' : ''}>${esc(text)}</option>`).join('');
    return `<label${hidden}><span>${f.label}</span><select data-field="${f.field}">${opts}</select></label>`;
  }
  const v = getPath(step, f.field);
  const attrs = [`data-field="${f.field}"`, 'type="number"', `step="${f.step ?? 1}"`,
    f.min != null ? `min="${f.min}"` : '', f.max != null ? `max="${f.max}"` : '',
    f.placeholder ? `placeholder="${f.placeholder}"` : '', `value="${Number.isFinite(v) ? v : ''}"`].join(' ');
  const unit = f.unit ? ` <span class="unit">${f.unit}</span>` : '';
  return `<label${hidden}${f.title ? ` title="${esc(f.title)}"` : ''}><span>${f.label}${unit}</span><input ${attrs}></label>`;
}

/** The card of step `step` (index i of n) in a plan whose groups are `groups`. */
export function stepCard(step, i, n, groups, ui) {
  const li = document.createElement('li');
  li.className = 'm-step';
  li.dataset.testid = 'mission-step';
  li.dataset.step = String(i);
  li.dataset.kind = step.kind;
  const groupOpts = ['<option value="">every vehicle</option>',
    ...groups.map((g) => `<option value="${esc(g)}"${g === step.group ? ' selected' : ''}>${esc(g)}</option>`)].join('');
  li.innerHTML = `<header class="m-step-head">
      <span class="m-step-n">${i + 1}</span><strong>${step.kind}</strong>
      <select data-field="group" title="who flies it" aria-label="group">${groupOpts}</select>
      <button type="button" class="btn tiny" data-act="up" title="earlier"${i === 0 ? ' disabled' : ''}>↑</button>
      <button type="button" class="btn tiny" data-act="down" title="later"${i === n - 1 ? ' disabled' : ''}>↓</button>
      <button type="button" class="btn tiny" data-act="remove" title="remove" data-testid="mission-remove">✕</button>
    </header>
    <div class="m-fields">${FIELDS[step.kind].map((f) => inputHtml(f, step, ui)).join('')}</div>
    <p class="m-error" data-field="error" role="alert" hidden></p>`;
  if (step.group && !groups.includes(step.group)) {
    li.querySelector('select[data-field="group"]').append(new Option(step.group, step.group, true, true));
  }
  refreshCard(li, step, ui, false);
  return li;
}

/** Updates what a card shows from its step: points count, Draw / Finish, hidden fields. */
export function refreshCard(li, step, ui, drawing) {
  const f = GEOMETRY[step.kind];
  if (f) {
    const n = (step[f] || []).length;
    li.querySelector('[data-field="count"]').textContent = `${n} point${n === 1 ? '' : 's'}`;
    const b = li.querySelector('[data-act="draw"]');
    b.textContent = drawing ? 'Finish' : n ? 'Redraw' : 'Draw';
    b.classList.toggle('active', drawing);
  }
  for (const spec of FIELDS[step.kind]) {
    if (!spec.when) continue;
    const el = li.querySelector(`[data-field="${spec.field}"]`);
    if (el) el.closest('label').hidden = !spec.when(step, ui);
  }
}

/** Reads input `el` of a card into its step (`ui` takes the card's own choices). */
export function readInput(el, step, ui) {
  const field = el.dataset.field;
  if (field === 'spacing') { ui.spacing = el.value; return; }
  if (field === 'group') { setPath(step, 'group', el.value || undefined); return; }
  if (el.tagName === 'SELECT') { setPath(step, field, el.value || undefined); return; }
  const v = el.value.trim() === '' ? undefined : Number(el.value);
  setPath(step, field, v);
}
