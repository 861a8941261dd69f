// Supervision tab: the actor tree (GET /api/v1/supervision, polled once a second while
// shown and at once after an actor event) with each actor's status, restarts, failures,
// last failure, last restart latency and backoff. When skein runs with
// --enable-fault-injection (GET /api/v1/health: `fault_injection`), every actor gets
// panic / hang / stop / error buttons (POST /api/v1/faults).
// Test hooks: li[data-path=…] with data-status / data-restarts, and
// button[data-fault=panic|hang|stop|error] inside the actor's own row.

import * as api from './api.js';
import { confirmAction } from './confirm.js';
import { fmtTime } from './model.js';

const FAULTS = ['panic', 'hang', 'stop', 'error'];

export class SupervisionView {
  /** deps: {toasts, log, tabs}. */
  constructor(root, deps) {
    Object.assign(this, deps);
    this.root = root;
    this.faults = null; // unknown until /health answers
    this.rows = new Map(); // path → li
    root.innerHTML = `
      <div class="view-head"><span class="hint" data-field="faults">fault injection: checking…</span>
        <input type="search" class="sup-filter" placeholder="filter actors" aria-label="Filter actors"></div>
      <ul class="sup-tree" data-testid="supervision-tree"></ul>`;
    this.tree = root.querySelector('.sup-tree');
    this.filter = root.querySelector('.sup-filter');
    this.filter.addEventListener('input', () => this.applyFilter());
    this.tree.addEventListener('click', (ev) => {
      const b = ev.target.closest('button[data-fault]');
      if (b) this.inject(b.closest('li[data-path]').dataset.path, b.dataset.fault, b);
    });
    this.poller = new api.Poller(() => this.refresh(), 1000, () => this.tabs.isOpen('supervision'));
    this.health = new api.Poller(() => this.checkHealth(), 15000, () => this.faults === null || this.tabs.isOpen('supervision'));
    this.tabs.onOpen((name) => { if (name === 'supervision') this.poller.poke(); });
  }

  async checkHealth() {
    const res = await api.getHealth();
    if (res.ok) {
      const on = !!res.data.fault_injection;
      if (on !== this.faults) {
        this.faults = on;
        this.root.querySelector('[data-field="faults"]').textContent = on
          ? 'fault injection enabled: break an actor and watch it come back'
          : 'fault injection disabled (start skein with --enable-fault-injection)';
        this.root.classList.toggle('faults-on', on);
      }
    }
    return res;
  }

  /** An actor event arrived: refresh soon. */
  onActorEvent() {
    this.poller.poke();
  }

  async inject(path, kind, button) {
    if (kind === 'stop' || kind === 'hang') {
      const ok = await confirmAction(`${kind} ${path}?`, `The actor will ${kind === 'stop' ? 'stop' : 'stop answering'}; its supervisor decides what happens next.`, `Inject ${kind}`);
      if (!ok) return;
    }
    button.disabled = true;
    const res = await api.injectFault(path, kind);
    button.disabled = false;
    if (!res.ok) {
      const d = res.data || {};
      this.toasts.show('error', `fault ${kind} → ${path}: ${res.status ? `HTTP ${res.status}` : 'no answer'}`, d.error + (d.field ? ` (field ${d.field})` : ''));
      this.log.note('api', 'error', 'fault', `${kind} → ${path}: ${d.error}`);
      if (res.status === 403) { this.faults = null; this.health.poke(); }
      return;
    }
    this.toasts.show('info', `fault injected: ${kind}`, path);
    this.log.note('api', 'warn', 'fault', `${kind} injected into ${path}`);
    this.poller.poke();
  }

  async refresh() {
    const res = await api.getSupervision();
    if (!res.ok) return res;
    const seen = new Set();
    const build = (node, parentUl) => {
      seen.add(node.path);
      const li = this.row(node);
      if (li.parentElement !== parentUl) parentUl.append(li);
      const ul = li.querySelector(':scope > ul');
      for (const c of node.children || []) build(c, ul);
    };
    build(res.data, this.tree);
    for (const [path, li] of this.rows) {
      if (!seen.has(path)) { li.remove(); this.rows.delete(path); }
    }
    this.applyFilter();
    return res;
  }

  row(n) {
    let li = this.rows.get(n.path);
    if (!li) {
      li = document.createElement('li');
      li.dataset.path = n.path;
      li.dataset.testid = 'actor';
      li.innerHTML = `<div class="actor-row"><span class="actor-name"></span><span class="actor-kind"></span>
          <span class="actor-status" data-field="status"></span><span class="actor-num" data-field="restarts" title="restarts"></span>
          <span class="actor-faults">${FAULTS.map((f) => `<button type="button" class="btn tiny fault" data-fault="${f}" title="inject ${f}">${f}</button>`).join('')}</span></div>
          <div class="actor-detail" data-field="detail"></div><ul></ul>`;
      li.querySelector('.actor-name').textContent = n.name;
      this.rows.set(n.path, li);
    }
    const status = String(n.status);
    li.dataset.status = status;
    li.dataset.restarts = String(n.restarts ?? 0);
    // The kind only where the name does not already say it (payload/camera is a payload).
    const kind = typeof n.kind === 'string' ? n.kind : JSON.stringify(n.kind);
    const norm = (x) => String(x).toLowerCase().replace(/[^a-z0-9]/g, '');
    li.querySelector(':scope > .actor-row .actor-kind').textContent = norm(n.name).startsWith(norm(kind)) ? '' : kind;
    li.querySelector(':scope > .actor-row .actor-name').title = `${n.path} (${kind})`;
    const st = li.querySelector(':scope > .actor-row [data-field="status"]');
    st.textContent = status;
    st.className = `actor-status st-${status.split(/[^a-z]/)[0]}`;
    li.querySelector(':scope > .actor-row [data-field="restarts"]').textContent = `↻ ${n.restarts ?? 0}`;
    const parts = [];
    if (n.failures) parts.push(`${n.failures} failure${n.failures === 1 ? '' : 's'}`);
    if (n.last_restart_latency_us != null) parts.push(`restart ${(n.last_restart_latency_us / 1000).toFixed(1)} ms`);
    if (n.backoff_ms) parts.push(`backoff ${n.backoff_ms} ms`);
    if (n.last_failure) {
      const f = n.last_failure;
      parts.push(`last: ${f.at_unix_ms ? fmtTime(new Date(f.at_unix_ms)) : ''} ${f.reason}`);
    }
    const detail = li.querySelector(':scope > [data-field="detail"]');
    const text = parts.join(' · ');
    if (detail.textContent !== text) detail.textContent = text;
    detail.hidden = !text;
    return li;
  }

  applyFilter() {
    const f = this.filter.value.trim().toLowerCase();
    const paths = [...this.rows.keys()].map((p) => p.toLowerCase());
    for (const [path, li] of this.rows) {
      const p = path.toLowerCase();
      // Shown when it matches or has a matching descendant (the way down stays visible).
      const hit = !f || paths.some((q) => (q === p || q.startsWith(`${p}/`)) && q.includes(f));
      li.classList.toggle('filtered-out', !hit);
    }
  }
}
