// Mission tab: the missions skein keeps (GET /api/v1/missions), the one picked with its
// state, the step it flies and each step's progress (a survey's lanes flown of all, the
// step's own words), and its commands: Start, Pause, Resume, Skip step, Abort (asked
// first, as landing every vehicle is) through POST /api/v1/missions/{id}/{action}. New
// plan and Edit a copy open the plan editor (mission-edit.js) in the tab's place.
// The list follows the stream's mission_* events and a poll (every second while the tab
// is shown or a mission flies). The plan draws the step the picked mission flies
// (plan-mission.js's `flight` layer: a survey with its lanes, each vehicle's block in its
// colour) and the editor's selected step (the `draft` layer). Rehearse flies the plan in
// virtual time first (mission-rehearsal.js shows how far it got, its figures and picture).
// Test hooks: [data-testid="mission-list"] li[data-mission-id][data-state];
// [data-testid="mission-status"] with data-mission-id, data-state, data-step;
// [data-testid="mission-progress"] li[data-step] with data-state, data-lanes-done,
// data-lanes-total, data-fraction; buttons mission-new, mission-start, mission-pause,
// mission-resume, mission-skip, mission-abort, mission-copy, mission-rehearse (the
// rehearsal's own hooks: mission-rehearsal.js).

import * as api from './api.js';
import { confirmAction } from './confirm.js';
import { compareIds, fmt, vehicleColour } from './model.js';
import { MissionLayer } from './plan-mission.js';
import { PlanEditor } from './mission-edit.js';
import { RehearsalPanel } from './mission-rehearsal.js';

const enc = encodeURIComponent;
/** The commands each state allows (the coordinator answers 409 to the others). */
const ALLOWED = {
  ready: ['start'], running: ['pause', 'skip', 'abort'], paused: ['resume', 'skip', 'abort'],
  done: ['start'], aborted: ['start'],
};
const FLYING = new Set(['running', 'paused']);
/** States a mission may be rehearsed in (not while it flies). */
const REHEARSABLE = new Set(['ready', 'done', 'aborted']);
const ABORT_TEXT = {
  return: 'Every airborne vehicle holds for a second, then returns to launch one after the other.',
  land: 'Every airborne vehicle holds for a second, then lands where it is one after the other.',
};

export class MissionView {
  /** deps: {toasts, log, plan, tabs}. */
  constructor(root, deps) {
    Object.assign(this, deps);
    this.root = root;
    this.missions = [];
    this.picked = null;     // id of the mission shown
    this.pinned = null;     // step index the operator picked to see on the plan
    root.innerHTML = `
      <div data-field="home">
        <div class="view-head">
          <span class="hint" data-field="summary">no missions</span>
          <button type="button" class="btn tiny op-only" data-act="new" data-testid="mission-new">New plan</button>
        </div>
        <ul class="mission-list" data-testid="mission-list"></ul>
        <section class="m-status" data-testid="mission-status" hidden>
          <div class="m-status-head"><strong data-field="title"></strong>
            <span class="m-state" data-field="state"></span><span class="hint" data-field="elapsed"></span></div>
          <div class="m-controls op-only" role="group" aria-label="Mission commands">
            <button type="button" class="btn primary" data-ctl="start" data-testid="mission-start">Start</button>
            <button type="button" class="btn" data-ctl="pause" data-testid="mission-pause">Pause</button>
            <button type="button" class="btn" data-ctl="resume" data-testid="mission-resume">Resume</button>
            <button type="button" class="btn" data-ctl="skip" data-testid="mission-skip">Skip step</button>
            <button type="button" class="btn danger" data-ctl="abort" data-testid="mission-abort">Abort</button>
            <button type="button" class="btn" data-act="rehearse" data-testid="mission-rehearse" title="fly it first in virtual time on simulated vehicles: nothing moves">Rehearse</button>
            <button type="button" class="btn tiny" data-act="copy" data-testid="mission-copy" title="a new plan from this one">Edit a copy</button>
          </div>
          <p class="m-error" data-field="error" role="alert" hidden></p>
          <ol class="m-progress" data-testid="mission-progress"></ol>
          <section class="m-rehearsal" data-testid="mission-rehearsal" hidden></section>
        </section>
      </div>
      <div data-field="editor" hidden></div>`;
    this.home = root.querySelector('[data-field="home"]');
    this.list = root.querySelector('[data-testid="mission-list"]');
    this.status = root.querySelector('[data-testid="mission-status"]');
    this.flight = new MissionLayer(this.plan, { name: 'flight', colour: '#a3d65c' });
    const draft = new MissionLayer(this.plan, { name: 'draft', colour: '#5bd1e6', onChange: () => this.editor.pointsChanged() });
    this.editorHost = root.querySelector('[data-field="editor"]');
    this.editor = new PlanEditor(this.editorHost, {
      layer: draft, toasts: this.toasts, log: this.log,
      onStored: (m) => { this.showEditor(false); this.pick(m.id); this.poller.poke(); },
      onClose: () => this.showEditor(false),
    });
    this.rehearsal = new RehearsalPanel(root.querySelector('[data-testid="mission-rehearsal"]'),
      { toasts: this.toasts, log: this.log });
    root.addEventListener('click', (ev) => this.onClick(ev));
    this.poller = new api.Poller(() => this.refresh(), 1000,
      () => this.tabs.isOpen('mission') || this.missions.some((m) => FLYING.has(m.state)));
    this.tabs.onOpen((name) => {
      if (name === 'mission') this.poller.poke();
      else if (this.editor.open) this.editor.stopDrawing(); // clicks go back to the plan
    });
    this.refresh();
  }

  /** A stream event: mission_* ones refresh the list at once. */
  onEvent(ev) {
    if (ev.type === 'mission_started') this.picked = ev.id;
    if (String(ev.type).startsWith('mission_')) this.poller.poke();
  }

  async refresh() {
    const res = await api.request('GET', '/missions');
    if (!res.ok) return res;
    // Newest first (m-10 after m-9).
    this.missions = (Array.isArray(res.data) ? res.data : []).sort((a, b) => compareIds(b.id, a.id));
    if (!this.missions.some((m) => m.id === this.picked)) {
      const flying = this.missions.find((m) => FLYING.has(m.state));
      this.picked = (flying || this.missions[0] || {}).id || null;
    }
    this.render();
    return res;
  }

  pick(id) {
    if (id !== this.picked) this.pinned = null;
    this.picked = id;
    this.render();
  }

  current() {
    return this.missions.find((m) => m.id === this.picked) || null;
  }

  showEditor(on, plan) {
    if (on) this.editor.start(plan); else if (this.editor.open) this.editor.close();
    this.editorHost.hidden = !on;
    this.home.hidden = on;
    this.render();
  }

  onClick(ev) {
    const act = ev.target.closest('button[data-act]');
    if (act && act.dataset.act === 'new') { this.showEditor(true); return; }
    if (act && act.dataset.act === 'copy') { const m = this.current(); if (m) this.showEditor(true, m.plan); return; }
    if (act && act.dataset.act === 'rehearse') { this.rehearsal.start(act); return; }
    const ctl = ev.target.closest('button[data-ctl]');
    if (ctl) { this.control(ctl.dataset.ctl, ctl); return; }
    const li = ev.target.closest('li[data-mission-id]');
    if (li) { this.pick(li.dataset.missionId); return; }
    const step = ev.target.closest('[data-testid="mission-progress"] li[data-step]');
    if (step) {
      const i = Number(step.dataset.step);
      this.pinned = this.pinned === i ? null : i;
      this.render();
    }
  }

  /** Start, pause, resume, skip or abort the mission shown (abort asks first). */
  async control(action, button) {
    const m = this.current();
    if (!m) return;
    if (action === 'abort') {
      const ok = await confirmAction(`Abort ${m.id} (${m.name})?`, ABORT_TEXT[m.plan.abort] || ABORT_TEXT.return, 'Abort mission');
      if (!ok) return;
    }
    button.disabled = true;
    const res = await api.request('POST', `/missions/${enc(m.id)}/${action}`, {});
    button.disabled = false;
    if (res.ok) {
      this.log.note('api', 'ok', 'mission', `${m.id} ${action}: ${res.data.state}`);
      const i = this.missions.findIndex((x) => x.id === m.id);
      if (i >= 0) this.missions[i] = res.data;
    } else {
      const d = res.data || {};
      const where = d.field ? ` (${d.field})` : '';
      this.toasts.show('error', `${m.id} ${action}: ${res.status ? `HTTP ${res.status}` : 'no answer'}`, `${d.error}${where}`);
      this.log.note('api', 'error', 'mission', `${m.id} ${action}${where}: ${d.error}`);
    }
    this.render();
    this.poller.poke();
  }

  render() {
    const n = this.missions.length;
    const flying = this.missions.find((m) => FLYING.has(m.state));
    const summary = n ? `${n} mission${n > 1 ? 's' : ''}${flying ? ` · ${flying.id} ${flying.state}` : ''}` : 'no missions yet: New plan';
    const s = this.root.querySelector('[data-field="summary"]');
    if (s.textContent !== summary) s.textContent = summary;
    this.renderList();
    this.renderStatus(this.current());
    this.showOnPlan(this.current());
  }

  renderList() {
    const seen = new Set();
    let prev = null;
    for (const m of this.missions) {
      seen.add(m.id);
      let li = this.list.querySelector(`li[data-mission-id="${CSS.escape(m.id)}"]`);
      if (!li) {
        li = document.createElement('li');
        li.dataset.missionId = m.id;
        li.innerHTML = '<strong></strong> <span data-field="name"></span> <span class="m-state" data-field="state"></span>';
        li.querySelector('strong').textContent = m.id;
      }
      const want = prev ? prev.nextSibling : this.list.firstChild;
      if (want !== li) this.list.insertBefore(li, want);
      prev = li;
      li.dataset.state = m.state;
      li.classList.toggle('selected', m.id === this.picked);
      li.querySelector('[data-field="name"]').textContent = m.name;
      const st = li.querySelector('[data-field="state"]');
      st.textContent = m.state;
      st.dataset.state = m.state;
    }
    for (const li of [...this.list.children]) if (!seen.has(li.dataset.missionId)) li.remove();
  }

  renderStatus(m) {
    const box = this.status;
    box.hidden = !m;
    if (!m) return;
    Object.assign(box.dataset, { missionId: m.id, state: m.state, step: String(m.step) });
    const put = (f, text) => { const e = box.querySelector(`[data-field="${f}"]`); if (e.textContent !== text) e.textContent = text; };
    put('title', `${m.id} · ${m.name}`);
    put('state', m.state);
    box.querySelector('[data-field="state"]').dataset.state = m.state;
    const at = FLYING.has(m.state) ? ` · step ${m.step + 1} of ${m.steps.length}, ${m.steps[m.step].kind}` : ` · ${m.steps.length} steps`;
    put('elapsed', `${fmt(m.elapsed_s, 0)} s flown${at}`);
    const allowed = ALLOWED[m.state] || [];
    for (const b of box.querySelectorAll('button[data-ctl]')) b.hidden = !allowed.includes(b.dataset.ctl);
    box.querySelector('[data-act="rehearse"]').hidden = !REHEARSABLE.has(m.state);
    this.rehearsal.show(m.id);
    const err = box.querySelector('[data-field="error"]');
    err.hidden = !m.error;
    put('error', m.error || '');
    this.renderProgress(m);
  }

  renderProgress(m) {
    const ol = this.status.querySelector('[data-testid="mission-progress"]');
    if (ol.dataset.missionId !== m.id || ol.children.length !== m.steps.length) {
      ol.dataset.missionId = m.id;
      ol.replaceChildren(...m.steps.map((_, i) => {
        const li = document.createElement('li');
        li.dataset.step = String(i);
        li.innerHTML = `<span class="m-step-n">${i + 1}</span><strong data-field="kind"></strong>
          <span class="m-state" data-field="state"></span><span class="m-bar"><span></span></span>
          <span class="m-detail" data-field="detail"></span>`;
        return li;
      }));
    }
    m.steps.forEach((s, i) => {
      const li = ol.children[i];
      const p = s.progress;
      const who = m.plan.steps[i] && m.plan.steps[i].group;
      Object.assign(li.dataset, {
        state: s.state,
        fraction: p ? String(p.fraction) : '',
        lanesDone: p && p.lanes_done != null ? String(p.lanes_done) : '',
        lanesTotal: p && p.lanes_total != null ? String(p.lanes_total) : '',
      });
      li.classList.toggle('current', FLYING.has(m.state) && i === m.step);
      li.classList.toggle('pinned', i === this.pinned);
      li.querySelector('[data-field="kind"]').textContent = `${s.kind}${who ? ` · ${who}` : ''}`;
      li.querySelector('[data-field="state"]').textContent = s.state;
      li.querySelector('[data-field="state"]').dataset.state = s.state;
      li.querySelector('.m-bar > span').style.width = `${Math.round((p ? p.fraction : s.state === 'done' ? 1 : 0) * 100)}%`;
      const lanes = p && p.lanes_total != null ? `${p.lanes_done} / ${p.lanes_total} lanes` : '';
      this.renderDetail(li.querySelector('[data-field="detail"]'), [lanes, p && !lanes ? p.detail : ''].filter(Boolean).join(' · '),
        s.vehicles, m.plan.steps[i] && m.plan.steps[i].kind === 'survey');
    });
  }

  /** A step's words and its vehicles (a survey's each with its lanes' colour on the plan). */
  renderDetail(el, words, vehicles, swatches) {
    const key = JSON.stringify([words, vehicles, swatches]);
    if (el.dataset.key === key) return;
    el.dataset.key = key;
    const parts = vehicles.map((id, b) => {
      const span = document.createElement('span');
      span.className = swatches ? 'm-swatch' : '';
      if (swatches) span.style.setProperty('--sw', vehicleColour(b));
      span.textContent = id;
      return span;
    });
    el.replaceChildren(words, words && parts.length ? ' · ' : '', ...parts.flatMap((s, k) => (k ? [', ', s] : [s])));
  }

  /** The flight layer: the step the operator pinned, else the step flown now. */
  showOnPlan(m) {
    const i = m ? (this.pinned ?? (FLYING.has(m.state) ? m.step : null)) : null;
    if (i == null || !m.plan.steps[i]) { this.flight.show(-1, null); return; }
    const s = m.steps[i];
    const p = s.progress;
    this.flight.show(i, m.plan.steps[i], {
      vehicles: s.vehicles,
      lanesDone: p && p.lanes_done != null ? p.lanes_done : null,
      label: `${m.id} ${s.state}`,
    });
  }
}
