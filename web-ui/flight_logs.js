// Flight logs (in the Pre-flight tab): every vehicle's ULog brought home after landing.
// "Fetch newest logs" asks skein for the newest log of every vehicle
// (POST /api/v1/logs/fetch_latest); the downloads (GET /api/v1/logs, polled once a second
// while shown) show their progress, and a complete one links to its file.
// Test hooks: button[data-testid=fetch-logs], tr[data-log="<vehicle>/<id>"] with
// data-state, a[data-testid=log-file].

import * as api from './api.js';

export class FlightLogsView {
  /** deps: {controls, tabs}; `tab` is the tab it lives in. */
  constructor(root, deps, tab) {
    Object.assign(this, deps);
    this.root = root;
    root.innerHTML = `
      <div class="view-head"><h4>Flight logs</h4>
        <button type="button" class="btn" data-testid="fetch-logs">Fetch newest logs</button></div>
      <p class="hint" data-field="logs-empty">No log fetched yet: after landing, fetch every vehicle's newest log.</p>
      <table class="flight-logs"><tbody></tbody></table>`;
    this.body = root.querySelector('tbody');
    const button = root.querySelector('[data-testid="fetch-logs"]');
    button.addEventListener('click', () => this.controls.run(button, 'fetch newest logs', async () => {
      const res = await api.fetchLatestLogs();
      this.poller.poke();
      return res;
    }));
    this.poller = new api.Poller(() => this.refresh(), 1000, () => this.tabs.isOpen(tab));
  }

  async refresh() {
    const res = await api.getLogDownloads();
    if (res.ok) this.render(res.data);
    return res;
  }

  render(downloads) {
    this.root.querySelector('[data-field="logs-empty"]').hidden = downloads.length > 0;
    this.body.replaceChildren(...downloads.map((d) => {
      const tr = document.createElement('tr');
      tr.dataset.log = `${d.vehicle}/${d.log_id}`;
      tr.dataset.state = d.state;
      const pct = d.size_bytes ? Math.floor((100 * d.received_bytes) / d.size_bytes) : 100;
      const cells = [d.vehicle, `log ${d.log_id}`, new Date(d.time_utc * 1000).toISOString().slice(0, 19).replace('T', ' '),
        `${(d.size_bytes / 1024).toFixed(0)} KiB`, d.state === 'failed' ? `failed: ${d.error}` : `${d.state} ${pct} %`];
      for (const text of cells) {
        const td = document.createElement('td');
        td.textContent = text;
        tr.append(td);
      }
      const td = document.createElement('td');
      if (d.state === 'complete') {
        const a = document.createElement('a');
        a.href = api.withToken(`/api/v1/vehicles/${encodeURIComponent(d.vehicle)}/logs/${d.log_id}/file`);
        a.download = `${d.vehicle}-log-${d.log_id}.ulg`;
        a.dataset.testid = 'log-file';
        a.textContent = '.ulg';
        td.append(a);
      }
      tr.append(td);
      return tr;
    }));
  }
}
