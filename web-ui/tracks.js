// Tracks tab: the counter-UAS tracker's tracks (GET /api/v1/tracks, polled twice a
// second; the plan view draws them too), one row per track with its status, speed,
// position sigma, the cameras that see it and the vehicles observing it, and an Observe /
// Release button (POST / DELETE /api/v1/tracks/{id}/observe; operators).
// Test hooks: li[data-track-id] with data-status and data-observed-by,
// button[data-act=observe|release], the tab's [data-field=count].

import * as api from './api.js';
import { fmt } from './model.js';

const enc = encodeURIComponent;

export class TracksView {
  /** deps: {toasts, log, plan, tabs}. */
  constructor(root, deps) {
    Object.assign(this, deps);
    this.root = root;
    root.innerHTML = `
      <div class="view-head"><span class="hint" data-field="summary">no tracks</span></div>
      <ul class="track-list" data-testid="track-list"></ul>`;
    this.list = root.querySelector('.track-list');
    this.list.addEventListener('click', (ev) => {
      const b = ev.target.closest('button[data-act]');
      if (b) this.observe(b.closest('li[data-track-id]').dataset.trackId, b.dataset.act === 'observe', b);
    });
    this.countEl = document.querySelector('[data-tab="tracks"] [data-field="count"]');
    this.poller = new api.Poller(() => this.refresh(), 500);
  }

  async refresh() {
    const res = await api.request('GET', '/tracks');
    if (!res.ok) return;
    const tracks = (res.data && res.data.tracks) || [];
    this.plan.setTargets(tracks);
    this.render(tracks);
  }

  render(tracks) {
    const confirmed = tracks.filter((t) => t.status === 'confirmed').length;
    const summary = tracks.length ? `${tracks.length} tracks, ${confirmed} confirmed` : 'no tracks';
    const s = this.root.querySelector('[data-field="summary"]');
    if (s.textContent !== summary) s.textContent = summary;
    if (this.countEl) this.countEl.textContent = confirmed ? String(confirmed) : '';
    const seen = new Set();
    for (const t of tracks) {
      seen.add(t.id);
      let li = this.list.querySelector(`li[data-track-id="${CSS.escape(t.id)}"]`);
      if (!li) {
        li = document.createElement('li');
        li.dataset.trackId = t.id;
        li.innerHTML = `<strong></strong> <span class="pl-status" data-field="status"></span>
          <span class="hint" data-field="motion"></span> <span class="hint" data-field="seen"></span>
          <button type="button" class="btn tiny op-only" data-act="observe">Observe</button>`;
        li.querySelector('strong').textContent = t.id;
        this.list.append(li);
      }
      const by = (t.observed_by || []).join(',');
      li.dataset.status = t.status;
      const px = this.plan.targetPx.get(t.id);
      li.dataset.x = px ? px[0].toFixed(1) : '';
      li.dataset.y = px ? px[1].toFixed(1) : '';
      li.dataset.observedBy = by;
      const put = (f, text) => { const e = li.querySelector(`[data-field="${f}"]`); if (e.textContent !== text) e.textContent = text; };
      put('status', t.status);
      li.querySelector('[data-field="status"]').className = `pl-status st-${t.status === 'confirmed' ? 'running' : t.status === 'lost' ? 'failed' : 'waiting'}`;
      const v = t.velocity || {};
      const speed = Math.hypot(v.north_m_s || 0, v.east_m_s || 0);
      const p = t.position || {};
      put('motion', `N ${fmt(p.north_m, 0)} E ${fmt(p.east_m, 0)} alt ${fmt(-(p.down_m ?? NaN), 0)} m · ${fmt(speed, 1)} m/s · σ ${fmt(t.position_sigma_m, 1)} m`);
      put('seen', `seen by ${(t.observers || []).join(', ') || '–'}${by ? ` · observed by ${by}` : ''}`);
      const b = li.querySelector('button[data-act]');
      const act = by ? 'release' : 'observe';
      if (b.dataset.act !== act) { b.dataset.act = act; b.textContent = by ? 'Release' : 'Observe'; }
      b.disabled = t.status === 'lost' && !by;
    }
    for (const li of [...this.list.children]) if (!seen.has(li.dataset.trackId)) li.remove();
  }

  async observe(id, on, button) {
    if (button) button.disabled = true;
    const res = on
      ? await api.request('POST', `/tracks/${enc(id)}/observe`, {})
      : await api.request('DELETE', `/tracks/${enc(id)}/observe`);
    if (button) button.disabled = false;
    const what = on ? 'observe' : 'release';
    if (!res.ok) {
      const d = res.data || {};
      this.toasts.show('error', `${id} ${what}: ${res.status ? `HTTP ${res.status}` : 'no answer'}`, d.error || '');
      this.log.note('api', 'error', 'track', `${id} ${what}: ${d.error || res.status}`);
    } else {
      const who = on ? res.data.vehicles : res.data.released;
      this.log.note('api', 'ok', 'track', `${id} ${what}: ${(who || []).join(', ') || 'nobody'}`);
    }
    this.poller.poke();
  }
}
