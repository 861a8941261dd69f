// The Mission tab's rehearsal: Rehearse (POST /api/v1/missions/{id}/rehearse: the plan
// flown in virtual time on simulated vehicles, the swarm as it is; nothing moves) and its
// outcome, followed through GET /api/v1/missions/{id}/rehearsal (every second while it
// runs): the mission seconds flown so far, then the figures (how it ended, duration,
// smallest separation and geofence margin with who, survey coverage, energy left per
// vehicle, reactions, refusals, speed) and the picture (the paths over the plan, SVG).
// Test hooks: [data-testid="mission-rehearse"] (button);
// [data-testid="mission-rehearsal"] with data-mission-id, data-state (running, done,
// failed), data-outcome (the mission's state in the rehearsal), data-duration-s,
// data-coverage, data-min-separation-m, data-reactions; img[data-field="picture"].

import * as api from './api.js';
import { fmt } from './model.js';

const enc = encodeURIComponent;

export class RehearsalPanel {
  /** box: the panel's element; deps: {toasts, log}. */
  constructor(box, deps) {
    Object.assign(this, deps);
    this.box = box;
    this.mission = null;    // id shown
    this.latest = null;     // its latest rehearsal status, or null
    box.innerHTML = `
      <div class="m-rh-head"><strong>Rehearsal</strong> <span class="m-state" data-field="state"></span>
        <span class="hint" data-field="progress"></span></div>
      <p class="m-error" data-field="error" role="alert" hidden></p>
      <dl class="m-rh-figures" data-field="figures"></dl>
      <img class="m-rh-picture" data-field="picture" alt="the rehearsed paths over the plan" hidden>`;
    this.poller = new api.Poller(() => this.refresh(), 1000,
      () => this.latest && this.latest.state === 'running');
  }

  /** Shows mission `id`'s latest rehearsal (fetched when the mission changes). */
  show(id) {
    if (id === this.mission) return;
    this.mission = id;
    this.latest = null;
    this.render();
    if (id) this.refresh();
  }

  /** Starts a rehearsal of the mission shown. */
  async start(button) {
    const id = this.mission;
    if (!id) return;
    button.disabled = true;
    const res = await api.request('POST', `/missions/${enc(id)}/rehearse`, {});
    button.disabled = false;
    if (!res.ok) {
      const d = res.data || {};
      const where = d.field ? ` (${d.field})` : '';
      this.toasts.show('error', `${id} rehearse: ${res.status ? `HTTP ${res.status}` : 'no answer'}`, `${d.error}${where}`);
      this.log.note('api', 'error', 'mission', `${id} rehearse${where}: ${d.error}`);
      return;
    }
    this.log.note('api', 'ok', 'mission', `${id} rehearsal started`);
    if (id === this.mission) { this.latest = res.data; this.render(); }
    this.poller.poke();
  }

  async refresh() {
    const id = this.mission;
    if (!id) return { ok: true };
    const res = await api.request('GET', `/missions/${enc(id)}/rehearsal`);
    if (id !== this.mission) return { ok: true };
    if (res.ok || res.status === 404) {
      const was = this.latest && this.latest.state;
      this.latest = res.ok && res.data.state !== 'none' ? res.data : null;
      if (was === 'running' && this.latest && this.latest.state !== 'running') {
        this.log.note('api', this.latest.state === 'done' ? 'ok' : 'error', 'mission', `${id} rehearsed: ${this.outcome()}`);
      }
      this.render();
      return { ok: true };
    }
    return res;
  }

  outcome() {
    const r = this.latest;
    if (!r) return '';
    if (r.state !== 'done') return r.state === 'failed' ? `failed: ${r.error}` : 'running';
    return `${r.report.state} after ${fmt(r.report.duration_s, 0)} s`;
  }

  render() {
    const r = this.latest;
    const box = this.box;
    box.hidden = !r;
    if (!r) { delete box.dataset.state; return; }
    const rep = r.report;
    Object.assign(box.dataset, {
      missionId: r.mission,
      state: r.state,
      outcome: rep ? rep.state : '',
      durationS: rep ? String(rep.duration_s) : '',
      coverage: rep && rep.coverage != null ? String(rep.coverage) : '',
      minSeparationM: rep && rep.min_separation_m != null ? String(rep.min_separation_m) : '',
      reactions: rep ? String(rep.reactions.length) : '',
    });
    const put = (f, text) => { const e = box.querySelector(`[data-field="${f}"]`); if (e.textContent !== text) e.textContent = text; };
    put('state', rep ? rep.state : r.state);
    box.querySelector('[data-field="state"]').dataset.state = rep ? rep.state : r.state;
    put('progress', r.state === 'running'
      ? `${fmt(r.mission_s, 0)} s of mission flown in ${fmt(r.wall_s, 0)} s`
      : `${fmt(r.mission_s, 0)} s of mission in ${fmt(r.wall_s, 1)} s`);
    const err = box.querySelector('[data-field="error"]');
    const why = r.error || (rep && rep.error) || '';
    err.hidden = !why;
    put('error', why);
    this.renderFigures(rep);
    const img = box.querySelector('[data-field="picture"]');
    img.hidden = !rep;
    const src = rep ? `data:image/svg+xml;charset=utf-8,${encodeURIComponent(rep.picture_svg)}` : '';
    if (img.dataset.src !== src) { img.dataset.src = src; img.src = src || ''; }
  }

  /** The report's figures as term/value rows. */
  renderFigures(rep) {
    const dl = this.box.querySelector('[data-field="figures"]');
    const key = rep ? `${rep.duration_s}/${rep.wall_s}` : '';
    if (dl.dataset.key === key) return;
    dl.dataset.key = key;
    if (!rep) { dl.replaceChildren(); return; }
    const sep = rep.min_separation;
    const fence = rep.min_fence_margin;
    const energy = Object.entries(rep.energy_left).map(([id, p]) => `${id} ${fmt(p, 0)} %`).join(', ');
    const rows = [
      ['duration', `${fmt(rep.duration_s, 0)} s (${rep.steps.filter((s) => s.state === 'done').length} of ${rep.steps.length} steps done)`],
      ['closest', sep ? `${fmt(sep.distance_m, 2)} m, ${sep.vehicles.join(' / ')} at ${fmt(sep.at_s, 0)} s` : '–'],
      ['fence margin', fence ? `${fmt(fence.margin_m, 1)} m, ${fence.vehicle} at ${fmt(fence.at_s, 0)} s` : '–'],
      ['coverage', rep.coverage != null ? `${fmt(rep.coverage * 100, 0)} %` : 'no survey'],
      ['energy left', energy || '–'],
      ['reactions', rep.reactions.length ? rep.reactions.map((x) => x.detail || x.kind).join('; ') : 'none'],
      ['refusals', rep.refusals.length ? rep.refusals.join('; ') : 'none'],
      ['speed', `${fmt(rep.speed_factor, 0)}× real time`],
    ];
    dl.replaceChildren(...rows.flatMap(([t, v]) => {
      const dt = document.createElement('dt');
      dt.textContent = t;
      const dd = document.createElement('dd');
      dd.textContent = v;
      return [dt, dd];
    }));
  }
}
