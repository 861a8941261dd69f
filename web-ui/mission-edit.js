// The Mission tab's plan editor: the plan's name, what an abort does, its groups (listed
// vehicles or a model) and its steps (mission-steps.js cards: added by kind, moved up and
// down, removed); the selected step's points drawn on the plan by clicks (plan-mission.js,
// the `draft` layer). Store posts the plan (POST /api/v1/missions): a 201 hands the mission
// to the view, a 400 is shown where it names (`steps[2].polygon[1]`: the step's card
// highlighted with the reason, the field marked, the point ringed on the plan).
// Test hooks: [data-testid="mission-editor"], mission-name, mission-add-KIND,
// mission-store, mission-cancel, mission-plan-error; the cards' (mission-steps.js).

import * as api from './api.js';
import { GEOMETRY } from './plan-mission.js';
import { surveySpacing } from './lanes.js';
import { KINDS, fromApi, newStep, planBody, readInput, refreshCard, stepCard, uiOf } from './mission-steps.js';

const esc = (s) => String(s).replace(/[&<>"]/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;' })[c]);

export class PlanEditor {
  /** deps: {layer (the draft MissionLayer), toasts, log, onStored(mission), onClose()}. */
  constructor(root, deps) {
    Object.assign(this, deps);
    this.root = root;
    this.ui = new WeakMap(); // step → the card's choices ({spacing})
    this.draft = null;       // {name, abort, groups: [{name, by, value}], steps}
    this.selected = -1;
    root.innerHTML = `
      <div class="m-editor" data-testid="mission-editor">
        <div class="m-row">
          <label class="m-name"><span>Name</span><input data-pfield="name" data-testid="mission-name" maxlength="64"></label>
          <label><span>On abort</span><select data-pfield="abort"><option value="return">return</option><option value="land">land</option></select></label>
        </div>
        <details class="m-groups"><summary>Groups <span class="hint" data-field="group-count"></span></summary>
          <ul class="m-group-list" data-testid="mission-groups"></ul>
          <button type="button" class="btn tiny" data-act="add-group">Add group</button>
        </details>
        <ol class="m-steps" data-testid="mission-steps"></ol>
        <div class="m-add" role="group" aria-label="Add a step"><span class="hint">add</span>
          ${KINDS.map((k) => `<button type="button" class="btn tiny" data-add="${k}" data-testid="mission-add-${k}">${k}</button>`).join('')}
        </div>
        <p class="m-error" data-testid="mission-plan-error" role="alert" hidden></p>
        <div class="m-row">
          <button type="button" class="btn primary" data-act="store" data-testid="mission-store">Store</button>
          <button type="button" class="btn" data-act="cancel" data-testid="mission-cancel">Cancel</button>
          <span class="hint" data-field="hint"></span>
        </div>
      </div>`;
    this.list = root.querySelector('.m-steps');
    this.groupList = root.querySelector('.m-group-list');
    root.addEventListener('click', (ev) => this.onClick(ev));
    root.addEventListener('input', (ev) => this.onInput(ev));
    root.addEventListener('change', (ev) => this.onInput(ev));
  }

  get open() { return !!this.draft; }

  /** Starts a draft: a copy of `plan` (a stored mission's), or a new plan. */
  start(plan) {
    const p = plan ? JSON.parse(JSON.stringify(plan)) : null;
    this.draft = {
      name: p ? `${p.name} (copy)`.slice(0, 64) : 'sortie',
      abort: (p && p.abort) || 'return',
      groups: Object.entries((p && p.groups) || {}).map(([name, g]) => (g.model
        ? { name, by: 'model', value: g.model } : { name, by: 'vehicles', value: (g.vehicles || []).join(', ') })),
      steps: p ? p.steps.map(fromApi) : [],
    };
    for (const s of this.draft.steps) this.ui.set(s, uiOf(s));
    this.root.querySelector('[data-pfield="name"]').value = this.draft.name;
    this.root.querySelector('[data-pfield="abort"]').value = this.draft.abort;
    this.selected = -1;
    this.renderGroups();
    this.renderSteps();
    this.select(this.draft.steps.length ? 0 : -1);
    this.showError(null);
  }

  close() {
    this.draft = null;
    this.layer.setDrawing(false);
    this.layer.markError(null);
    this.layer.show(-1, null);
  }

  uiFor(step) {
    if (!this.ui.has(step)) this.ui.set(step, uiOf(step));
    return this.ui.get(step);
  }

  /** A survey's lane spacing as the card chose it (its spacing, or its camera's), metres. */
  spacingOf(step) {
    if (this.uiFor(step).spacing === 'camera') return surveySpacing({ altitude_m: step.altitude_m, camera: step.camera });
    return Number.isFinite(step.lane_spacing_m) ? step.lane_spacing_m : null;
  }

  groupNames() {
    return this.draft.groups.map((g) => g.name.trim()).filter(Boolean);
  }

  renderGroups() {
    const gs = this.draft.groups;
    this.groupList.replaceChildren(...gs.map((g, i) => {
      const li = document.createElement('li');
      li.dataset.group = String(i);
      li.innerHTML = `<input data-gfield="name" placeholder="name" value="${esc(g.name)}" aria-label="group name">
        <select data-gfield="by" aria-label="group by"><option value="vehicles">vehicles</option><option value="model">model</option></select>
        <input data-gfield="value" value="${esc(g.value)}" aria-label="vehicles or model">
        <button type="button" class="btn tiny" data-act="remove-group" title="remove">✕</button>`;
      li.querySelector('[data-gfield="by"]').value = g.by;
      li.querySelector('[data-gfield="value"]').placeholder = g.by === 'model' ? 'observation' : 'uav-1, uav-3';
      return li;
    }));
    this.root.querySelector('[data-field="group-count"]').textContent = gs.length ? String(gs.length) : 'none: steps fly every vehicle';
  }

  renderSteps() {
    const steps = this.draft.steps;
    const groups = this.groupNames();
    this.list.replaceChildren(...steps.map((s, i) => stepCard(s, i, steps.length, groups, this.uiFor(s))));
    this.markSelected();
  }

  card(i) {
    return this.list.querySelector(`li[data-step="${i}"]`);
  }

  /** Selects step i (−1: none): its card marked, its points on the plan. */
  select(i) {
    if (i !== this.selected) this.layer.setDrawing(false);
    this.selected = i;
    const step = this.draft.steps[i];
    this.layer.show(i, step || null, { editable: true, label: 'draft', spacing: (s) => this.spacingOf(s) });
    this.markSelected();
  }

  markSelected() {
    for (const li of this.list.children) {
      const on = Number(li.dataset.step) === this.selected;
      li.classList.toggle('selected', on);
      if (on) li.setAttribute('aria-current', 'step'); else li.removeAttribute('aria-current');
      const s = this.draft.steps[Number(li.dataset.step)];
      refreshCard(li, s, this.uiFor(s), on && this.layer.drawing);
    }
    const kind = this.selected >= 0 ? this.draft.steps[this.selected].kind : null;
    let hint = GEOMETRY[kind] ? 'Drag a point on the plan to move it.' : '';
    if (this.layer.drawing) {
      hint = kind === 'survey' || kind === 'patrol'
        ? 'Click the plan at each point; the first point again (or Finish) closes it.'
        : 'Click the plan at each point; Finish when done.';
    }
    this.root.querySelector('[data-field="hint"]').textContent = hint;
  }

  /** Clicks on the plan stop adding points (the tab was left). */
  stopDrawing() {
    if (!this.layer.drawing) return;
    this.layer.setDrawing(false);
    this.markSelected();
  }

  /** The layer's points changed (a click or a drag): the card follows. */
  pointsChanged() {
    if (!this.draft) return;
    this.clearStepError(this.selected);
    this.markSelected();
  }

  onClick(ev) {
    const add = ev.target.closest('button[data-add]');
    if (add) {
      const s = newStep(add.dataset.add);
      this.ui.set(s, uiOf(s));
      this.draft.steps.push(s);
      this.renderSteps();
      this.select(this.draft.steps.length - 1);
      this.card(this.selected).scrollIntoView({ block: 'nearest' });
      return;
    }
    const b = ev.target.closest('button[data-act]');
    const li = ev.target.closest('li[data-step]');
    if (b) { this.act(b.dataset.act, li ? Number(li.dataset.step) : -1, b); return; }
    if (li && !ev.target.closest('input, select') && Number(li.dataset.step) !== this.selected) this.select(Number(li.dataset.step));
  }

  act(what, i, button) {
    const steps = this.draft.steps;
    switch (what) {
      case 'up': case 'down': {
        const j = what === 'up' ? i - 1 : i + 1;
        [steps[i], steps[j]] = [steps[j], steps[i]];
        this.renderSteps();
        this.select(j);
        break;
      }
      case 'remove':
        steps.splice(i, 1);
        this.renderSteps();
        this.select(Math.min(i, steps.length - 1));
        break;
      case 'draw': {
        if (i !== this.selected) this.select(i);
        const pts = this.layer.pts();
        if (this.layer.drawing) this.layer.setDrawing(false);
        else { pts.length = 0; this.layer.setDrawing(true); }
        this.clearStepError(i);
        this.markSelected();
        break;
      }
      case 'clear':
        if (i !== this.selected) this.select(i);
        this.layer.pts().length = 0;
        this.layer.setDrawing(false);
        this.clearStepError(i);
        this.markSelected();
        this.layer.plan.kick();
        break;
      case 'add-group':
        this.draft.groups.push({ name: `group${this.draft.groups.length + 1}`, by: 'vehicles', value: '' });
        this.renderGroups();
        this.renderSteps();
        break;
      case 'remove-group':
        this.draft.groups.splice(Number(button.closest('li[data-group]').dataset.group), 1);
        this.renderGroups();
        this.renderSteps();
        break;
      case 'store': this.store(button); break;
      case 'cancel': this.close(); this.onClose(); break;
      default:
    }
  }

  onInput(ev) {
    const el = ev.target;
    if (!this.draft || !el.matches('input, select')) return;
    el.removeAttribute('aria-invalid');
    if (el.dataset.pfield) { this.draft[el.dataset.pfield] = el.value; return; }
    const gi = el.closest('li[data-group]');
    if (gi) {
      const g = this.draft.groups[Number(gi.dataset.group)];
      g[el.dataset.gfield] = el.value;
      // The steps' group choices follow a group's name once it is typed.
      if (el.dataset.gfield === 'by') this.renderGroups();
      if (ev.type === 'change') this.renderSteps();
      return;
    }
    const li = el.closest('li[data-step]');
    if (!li || !el.dataset.field) return;
    const i = Number(li.dataset.step);
    const step = this.draft.steps[i];
    readInput(el, step, this.uiFor(step));
    this.clearStepError(i);
    if (i !== this.selected) this.select(i);
    refreshCard(li, step, this.uiFor(step), this.layer.drawing);
    this.layer.plan.kick();
  }

  /** The groups as the plan has them: `{name: {vehicles: [...]} | {model}}`. */
  groupsBody() {
    const out = {};
    for (const g of this.draft.groups) {
      const name = g.name.trim();
      if (!name) continue;
      out[name] = g.by === 'model'
        ? { model: g.value.trim() }
        : { vehicles: g.value.split(/[\s,]+/).filter(Boolean) };
    }
    return out;
  }

  body() {
    return planBody({ ...this.draft, groups: this.groupsBody() }, (s) => this.uiFor(s));
  }

  async store(button) {
    this.layer.setDrawing(false);
    this.showError(null);
    button.disabled = true;
    const res = await api.request('POST', '/missions', this.body());
    button.disabled = false;
    if (!this.draft) return;
    if (res.ok) {
      const m = res.data;
      this.toasts.show('ok', `Mission ${m.id} stored`, `${m.name}: ${m.steps.length} steps, ready to start`);
      this.log.note('api', 'ok', 'mission', `${m.id} stored (${m.name})`);
      this.close();
      this.onStored(m);
      return;
    }
    const d = res.data || {};
    const where = d.field ? ` (${d.field})` : '';
    this.toasts.show('error', `Mission refused${where}`, d.error);
    this.log.note('api', 'error', 'mission', `refused${where}: ${d.error}`);
    this.showError(d.field || '', d.error || `HTTP ${res.status}`);
  }

  clearStepError(i) {
    const li = this.card(i);
    if (!li || !li.classList.contains('has-error')) return;
    li.classList.remove('has-error');
    delete li.dataset.error;
    li.querySelector('p.m-error').hidden = true;
    for (const el of li.querySelectorAll('[aria-invalid]')) el.removeAttribute('aria-invalid');
    this.layer.markError(null);
  }

  /** Shows a refusal at what `field` names (null: clears every error shown). */
  showError(field, error) {
    for (const li of this.list.children) this.clearStepError(Number(li.dataset.step));
    for (const el of this.root.querySelectorAll('[aria-invalid]')) el.removeAttribute('aria-invalid');
    this.layer.markError(null);
    const box = this.root.querySelector('[data-testid="mission-plan-error"]');
    box.hidden = field === null;
    if (field === null) return;
    box.textContent = field ? `${field}: ${error}` : error;
    box.dataset.field = field;
    const m = /^steps\[(\d+)\]\.?(.*)$/.exec(field);
    if (m && this.card(Number(m[1]))) { this.showStepError(Number(m[1]), m[2], error); return; }
    const g = /^groups\.(.+)$/.exec(field);
    const at = field === 'name' || field === 'abort'
      ? this.root.querySelector(`[data-pfield="${field}"]`)
      : g ? [...this.groupList.children].find((li, i) => this.draft.groups[i].name.trim() === g[1]) : null;
    if (g) this.root.querySelector('.m-groups').open = true;
    if (at) at.setAttribute('aria-invalid', 'true');
    if (field === 'steps') this.list.setAttribute('aria-invalid', 'true');
  }

  /** Step i's card highlighted with `error`, the field `rest` marked, a point ringed. */
  showStepError(i, rest, error) {
    this.select(i);
    const li = this.card(i);
    li.classList.add('has-error');
    li.dataset.error = rest || 'step';
    const p = li.querySelector('p.m-error');
    p.textContent = error;
    p.hidden = false;
    const base = rest.replace(/\[\d+\]$/, '');
    for (const el of li.querySelectorAll('[data-field]')) {
      const f = el.dataset.field;
      if (base && (f === base || f.startsWith(`${base}.`))) el.setAttribute('aria-invalid', 'true');
    }
    const pm = /^(\w+)\[(\d+)\]$/.exec(rest);
    const step = this.draft.steps[i];
    if (pm && GEOMETRY[step.kind] === pm[1] && step[pm[1]][Number(pm[2])]) {
      this.layer.markError(step[pm[1]][Number(pm[2])], `${pm[1]}[${pm[2]}]: ${error}`);
    }
    li.scrollIntoView({ block: 'nearest' });
  }
}
