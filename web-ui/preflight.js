// Pre-flight tab: the fleet's checks before a flight (GET /api/v1/preflight, polled once a
// second while shown): one row per vehicle, one cell per check (link, state, PX4's arming
// checks with what PX4 said, home, GNSS, battery, the autopilot's geofence, Remote ID),
// each ok / warn / fail with what was seen; below, the RTK corrections (rtk.js) and the
// flight logs (flight_logs.js).
// Where PX4 sends its events, the PX4 checks cell lists each of PX4's failing checks by
// name (the vehicle's px4_arming_checks: ✗ when it prevents arming in the current mode,
// its description as the tooltip).
// Test hooks: [data-testid=preflight] with data-ready, tr[data-vehicle=…] with data-ready,
// td[data-check=…] with data-state, li[data-arming-check] with data-prevents.

import * as api from './api.js';
import { FlightLogsView } from './flight_logs.js';
import { RtkView } from './rtk.js';

const CHECKS = [
  ['link', 'link'], ['state', 'state'], ['px4_arming_checks', 'PX4 checks'], ['home', 'home'],
  ['gnss', 'GNSS'], ['battery', 'battery'], ['geofence', 'fence'], ['remote_id', 'Remote ID'],
];
const MARK = { ok: '✓', warn: '!', fail: '✗' };

export class PreflightView {
  /** deps: {controls, tabs, vehicles: () => the stream's latest vehicle snapshots}. */
  constructor(root, deps) {
    Object.assign(this, deps);
    this.root = root;
    root.innerHTML = `
      <div class="view-head"><span class="hint" data-field="summary">checking…</span></div>
      <table class="preflight" data-testid="preflight">
        <thead><tr><th>vehicle</th>${CHECKS.map(([, l]) => `<th>${l}</th>`).join('')}</tr></thead>
        <tbody></tbody>
      </table>
      <section class="rtk-section"></section>
      <section class="flight-logs-section"></section>`;
    this.body = root.querySelector('tbody');
    this.rtk = new RtkView(root.querySelector('.rtk-section'), deps, 'preflight');
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
      const named = key === 'px4_arming_checks' ? this.armingChecks(v.id) : [];
      if (c && named.length > 0) {
        td.dataset.state = c.state;
        td.className = `pf-${c.state}`;
        const ul = document.createElement('ul');
        ul.className = 'pf-checks';
        ul.append(...named.map((a) => {
          const li = document.createElement('li');
          li.dataset.armingCheck = a.message;
          li.dataset.prevents = String(a.prevents_arming);
          li.className = a.prevents_arming ? 'pf-fail' : 'pf-warn';
          li.textContent = `${a.prevents_arming ? MARK.fail : MARK.warn} ${a.message} (${a.severity})`;
          li.title = a.description || a.message;
          return li;
        }));
        td.append(ul);
        td.title = named.map((a) => a.message).join('\n');
      } else if (c) {
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

  /** PX4's failing checks of vehicle `id` (its snapshot's px4_arming_checks). */
  armingChecks(id) {
    const v = (this.vehicles ? this.vehicles() : []).find((x) => x.id === id);
    return (v && v.px4_arming_checks) || [];
  }
}
