// Tracks tab: the hostile swarms (GET /api/v1/swarms) and the counter-UAS tracker's
// tracks (GET /api/v1/tracks), polled twice a second; the plan view draws them too. One
// row per swarm with its shape, members, speed, where it will be in 10 s and its
// observers' stations, and an Observe / Release button (POST / DELETE
// /api/v1/swarms/{id}/observe: the observers fly to the best stations); one row per track
// with its status, speed, position sigma, its swarm, the cameras that see it and the
// vehicles observing it, and an Observe / Release button (POST / DELETE
// /api/v1/tracks/{id}/observe; operators).
// Test hooks: li[data-swarm-id] with data-members, data-shape, data-observed-by,
// data-x / data-y (its centroid on the plan), data-hull (points of its drawn hull),
// data-cone ("1" when its forecast cone is drawn), data-stations; li[data-track-id] with
// data-status, data-swarm and data-observed-by; button[data-act=observe|release]; the
// tab's [data-field=count].

import * as api from './api.js';
import { fmt } from './model.js';

const enc = encodeURIComponent;

export class TracksView {
  /** deps: {toasts, log, plan, tabs}. */
  constructor(root, deps) {
    Object.assign(this, deps);
    this.root = root;
    root.innerHTML = `
      <div class="view-head"><span class="hint" data-field="swarm-summary">no hostile swarm</span></div>
      <ul class="track-list swarm-list" data-testid="swarm-list"></ul>
      <div class="view-head"><span class="hint" data-field="summary">no tracks</span></div>
      <ul class="track-list" data-testid="track-list"></ul>`;
    this.list = root.querySelector('[data-testid="track-list"]');
    this.swarmList = root.querySelector('[data-testid="swarm-list"]');
    this.list.addEventListener('click', (ev) => {
      const b = ev.target.closest('button[data-act]');
      if (b) this.observe('tracks', b.closest('li[data-track-id]').dataset.trackId, b.dataset.act === 'observe', b);
    });
    this.swarmList.addEventListener('click', (ev) => {
      const b = ev.target.closest('button[data-act]');
      if (b) this.observe('swarms', b.closest('li[data-swarm-id]').dataset.swarmId, b.dataset.act === 'observe', b);
    });
    this.countEl = document.querySelector('[data-tab="tracks"] [data-field="count"]');
    this.poller = new api.Poller(() => this.refresh(), 500);
  }

  async refresh() {
    const [res, sw] = await Promise.all([api.request('GET', '/tracks'), api.request('GET', '/swarms')]);
    if (!res.ok) return;
    const tracks = (res.data && res.data.tracks) || [];
    const swarms = (sw.ok && sw.data && sw.data.swarms) || [];
    this.plan.setTargets(tracks, swarms);
    this.render(tracks);
    this.renderSwarms(swarms);
  }

  renderSwarms(swarms) {
    const summary = swarms.length
      ? `${swarms.length} hostile swarm${swarms.length > 1 ? 's' : ''}: ${swarms.map((s) => `${s.id} (${s.members.length})`).join(', ')}`
      : 'no hostile swarm';
    const h = this.root.querySelector('[data-field="swarm-summary"]');
    if (h.textContent !== summary) h.textContent = summary;
    const seen = new Set();
    for (const s of swarms) {
      seen.add(s.id);
      let li = this.swarmList.querySelector(`li[data-swarm-id="${CSS.escape(s.id)}"]`);
      if (!li) {
        li = document.createElement('li');
        li.dataset.swarmId = s.id;
        li.innerHTML = `<strong></strong> <span class="pl-status st-failed" data-field="shape"></span>
          <span class="hint" data-field="motion"></span> <span class="hint" data-field="seen"></span>
          <button type="button" class="btn tiny op-only" data-act="observe">Observe</button>`;
        li.querySelector('strong').textContent = s.id;
        this.swarmList.append(li);
      }
      const by = (s.observed_by || []).join(',');
      const px = this.plan.swarmPx.get(s.id);
      const st = (s.stations && s.stations.stations) || [];
      Object.assign(li.dataset, {
        members: s.members.join(','), shape: s.shape, observedBy: by,
        x: px ? px.x.toFixed(1) : '', y: px ? px.y.toFixed(1) : '',
        hull: px ? String(px.hull) : '0', cone: px && px.cone ? '1' : '', stations: String(st.length),
      });
      const put = (f, text) => { const e = li.querySelector(`[data-field="${f}"]`); if (e.textContent !== text) e.textContent = text; };
      put('shape', `${s.shape} → ${fmt(s.shape_heading_deg, 0)}°`);
      const f10 = (s.forecast || []).find((f) => f.horizon_s === 10);
      const where = f10 ? ` · in 10 s: N ${fmt(f10.position.north_m, 0)} E ${fmt(f10.position.east_m, 0)} ±${fmt(f10.sigma_m, 0)} m (${f10.model.replace(/_/g, ' ')})` : '';
      put('motion', `${s.members.length} tracks (${s.members.join(', ')}) · ${fmt(s.speed_m_s, 1)} m/s → ${fmt(s.course_deg, 0)}° · ${fmt(s.extent.length_m, 0)}×${fmt(s.extent.width_m, 0)} m${where}`);
      const stations = s.stations ? ` · stations ${st.map((o) => o.vehicle).join(', ')}: ±${fmt(s.stations.predicted_sigma_m, 1)} m at ${fmt(s.stations.triangulation_angle_deg, 0)}°` : '';
      put('seen', by ? `observed by ${by}${stations}` : '');
      const b = li.querySelector('button[data-act]');
      const act = by ? 'release' : 'observe';
      if (b.dataset.act !== act) { b.dataset.act = act; b.textContent = by ? 'Release' : 'Observe'; }
    }
    for (const li of [...this.swarmList.children]) if (!seen.has(li.dataset.swarmId)) li.remove();
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
      li.dataset.swarm = t.swarm || '';
      const put = (f, text) => { const e = li.querySelector(`[data-field="${f}"]`); if (e.textContent !== text) e.textContent = text; };
      put('status', t.status);
      li.querySelector('[data-field="status"]').className = `pl-status st-${t.status === 'confirmed' ? 'running' : t.status === 'lost' ? 'failed' : 'waiting'}`;
      const v = t.velocity || {};
      const speed = Math.hypot(v.north_m_s || 0, v.east_m_s || 0);
      const p = t.position || {};
      put('motion', `N ${fmt(p.north_m, 0)} E ${fmt(p.east_m, 0)} alt ${fmt(-(p.down_m ?? NaN), 0)} m · ${fmt(speed, 1)} m/s · σ ${fmt(t.position_sigma_m, 1)} m`);
      put('seen', `${t.swarm ? `in ${t.swarm} · ` : ''}seen by ${(t.observers || []).join(', ') || '–'}${by ? ` · observed by ${by}` : ''}`);
      const b = li.querySelector('button[data-act]');
      const act = by ? 'release' : 'observe';
      if (b.dataset.act !== act) { b.dataset.act = act; b.textContent = by ? 'Release' : 'Observe'; }
      b.disabled = t.status === 'lost' && !by;
    }
    for (const li of [...this.list.children]) if (!seen.has(li.dataset.trackId)) li.remove();
  }

  /** Observe (or release) track or swarm `id`; `what` is `tracks` or `swarms`. */
  async observe(what, id, on, button) {
    if (button) button.disabled = true;
    const res = on
      ? await api.request('POST', `/${what}/${enc(id)}/observe`, {})
      : await api.request('DELETE', `/${what}/${enc(id)}/observe`);
    if (button) button.disabled = false;
    const verb = on ? 'observe' : 'release';
    if (!res.ok) {
      const d = res.data || {};
      this.toasts.show('error', `${id} ${verb}: ${res.status ? `HTTP ${res.status}` : 'no answer'}`, d.error || '');
      this.log.note('api', 'error', 'track', `${id} ${verb}: ${d.error || res.status}`);
    } else {
      const who = on ? res.data.vehicles : res.data.released;
      this.log.note('api', 'ok', 'track', `${id} ${verb}: ${(who || []).join(', ') || 'nobody'}`);
    }
    this.poller.poke();
  }
}
