// Pre-flight tab: the fleet's checks before a flight (GET /api/v1/preflight, polled once a
// second while shown): one row per vehicle, one cell per check (link, state, PX4's arming
// checks with what PX4 said, home, GNSS, battery, the autopilot's geofence, Remote ID),
// each ok / warn / fail with what was seen; below, the flight logs (flight_logs.js).
// Test hooks: [data-testid=preflight] with data-ready, tr[data-vehicle=…] with data-ready,
// td[data-check=…] with data-state.

import * as api from './api.js';
import { FlightLogsView } from './flight_logs.js';

const CHECKS = [
  ['link', 'link'], ['state', 'state'], ['px4_arming_checks', 'PX4 checks'], ['home', 'home'],
  ['gnss', 'GNSS'], ['battery', 'battery'], ['geofence', 'fence'], ['remote_id', 'Remote ID'],
];
const MARK = { ok: '✓', warn: '!', fail: '✗' };

export class PreflightView {
  /** deps: {controls, tabs}. */
  constructor(root, deps) {
    Object.assign(this, deps);
    this.root = root;
    root.innerHTML = `
      <div class="view-head"><span class="hint" data-field="summary">checking…</span></div>
      <table class="preflight" data-testid="preflight">
        <thead><tr><th>vehicle</th>${CHECKS.map(([, l]) => `<th>${l}</th>`).join('')}</tr></thead>
        <tbody></tbody>
      </table>
      <section class="flight-logs-section"></section>`;
    this.body = root.querySelector('tbody');
    this.logs = new FlightLogsView(root.querySelector('.flight-logs-section'), deps, 'preflight');
    this.poller = new api.Poller(() => this.refresh(), 1000, () => this.tabs.isOpen('preflight'));
    this.tabs.onOpen((name) => { if (name === 'preflight') this.poller.poke(); });
  }

  async refresh() {
    const res = await api.getPreflight();
    if (res.ok) this.render(res.data);
    return res;
  }

  render(p) {
    const table = this.root.querySelector('[data-testid="preflight"]');
    table.dataset.ready = String(p.ready);
    const failing = p.vehicles.filter((v) => !v.ready).map((v) => v.id);
    this.root.querySelector('[data-field="summary"]').textContent = p.vehicles.length === 0
      ? 'no vehicles'
      : failing.length === 0 ? `all ${p.vehicles.length} vehicles ready` : `not ready: ${failing.join(', ')}`;
    this.body.replaceChildren(...p.vehicles.map((v) => this.row(v)));
  }

  row(v) {
    const tr = document.createElement('tr');
    tr.dataset.vehicle = v.id;
    tr.dataset.ready = String(v.ready);
    const name = document.createElement('th');
    name.textContent = v.id;
    tr.append(name);
    for (const [key] of CHECKS) {
      const c = v.checks.find((x) => x.check === key);
      const td = document.createElement('td');
      td.dataset.check = key;
      if (c) {
        td.dataset.state = c.state;
        td.className = `pf-${c.state}`;
        td.textContent = `${MARK[c.state] || ''} ${c.detail}`;
        td.title = c.detail;
      } else {
        td.textContent = '–';
      }
      tr.append(td);
    }
    return tr;
  }
}
