// RTK corrections (in the Pre-flight tab): the corrections source of the fleet
// (PUT /api/v1/rtk: an NTRIP caster, a TCP or UDP RTCM3 stream, a serial base station;
// DELETE stops it) and what it does (GET /api/v1/rtk, polled once a second while shown):
// the source's state, throughput, message types, bad CRCs, the base station and its age,
// and per vehicle its fix, the corrections' age, messages sent and dropped to the cap.
// Test hooks: form[data-testid=rtk-form] with input[data-testid=rtk-source],
// [data-testid=rtk-state] with data-state, tr[data-rtk-vehicle=…] with data-fix.

import * as api from './api.js';
import { FIX_NAMES, fmt } from './model.js';

export class RtkView {
  /** deps: {controls, tabs}; `tab` is the tab it lives in. */
  constructor(root, deps, tab) {
    Object.assign(this, deps);
    this.root = root;
    root.innerHTML = `
      <div class="view-head"><h4>RTK corrections</h4>
        <span class="badge" data-testid="rtk-state" data-state="idle">idle</span>
        <span class="hint" data-field="rtk-summary"></span></div>
      <form class="rtk-form" data-testid="rtk-form">
        <input data-testid="rtk-source" id="rtk-source" type="text" required spellcheck="false"
          placeholder="ntrip://user:password@caster:2101/MOUNT, tcp://host:port, udp://:port, serial:/dev/ttyUSB0:115200"
          aria-label="Corrections source">
        <button type="submit" class="btn primary">Use source</button>
        <button type="button" class="btn" data-testid="rtk-stop">Stop</button>
      </form>
      <p class="hint" data-field="rtk-base"></p>
      <table class="rtk"><thead><tr><th>vehicle</th><th>fix</th><th>corrections</th><th>sent</th>
        <th title="messages dropped whole to keep the rate cap">dropped</th></tr></thead><tbody></tbody></table>`;
    this.body = root.querySelector('tbody');
    const form = root.querySelector('[data-testid="rtk-form"]');
    form.addEventListener('submit', (ev) => {
      ev.preventDefault();
      const source = form.querySelector('input').value.trim();
      this.controls.run(ev.submitter, 'RTK source', async () => {
        const res = await api.putRtk({ source });
        this.poller.poke();
        return res;
      }, { source: 'rtk-source' });
    });
    const stop = root.querySelector('[data-testid="rtk-stop"]');
    stop.addEventListener('click', () => this.controls.run(stop, 'stop RTK', async () => {
      const res = await api.stopRtk();
      this.poller.poke();
      return res;
    }));
    this.poller = new api.Poller(() => this.refresh(), 1000, () => this.tabs.isOpen(tab));
  }

  async refresh() {
    const res = await api.getRtk();
    if (res.ok) this.render(res.data);
    return res;
  }

  render(r) {
    const state = this.root.querySelector('[data-testid="rtk-state"]');
    state.dataset.state = r.state;
    state.className = `badge rtk-${r.state}`;
    state.textContent = r.state;
    const types = Object.keys(r.message_types).join(' ');
    const summary = r.source
      ? `${r.source} · ${fmt(r.bytes_per_s / 1000, 2)} kB/s · ${r.frames} msgs${types ? ` (${types})` : ''}`
        + `${r.crc_failures ? ` · ${r.crc_failures} bad CRC` : ''}${r.error ? ` · ${r.error}` : ''}`
      : 'no source: corrections are not sent';
    this.root.querySelector('[data-field="rtk-summary"]').textContent = summary;
    const b = r.base;
    this.root.querySelector('[data-field="rtk-base"]').textContent = b
      ? `base station ${b.station_id} at ${fmt(b.position.lat_deg, 6)} / ${fmt(b.position.lon_deg, 6)}, `
        + `${fmt(b.position.alt_amsl_m, 1)} m, ${fmt(b.age_s, 0)} s ago`
      : '';
    this.body.replaceChildren(...r.vehicles.map((v) => {
      const tr = document.createElement('tr');
      tr.dataset.rtkVehicle = v.id;
      tr.dataset.fix = String(v.fix_type ?? '');
      const cells = [v.id, FIX_NAMES[v.fix_type] || '–',
        Number.isFinite(v.correction_age_s) ? `${fmt(v.correction_age_s, 1)} s old` : 'none yet',
        `${v.messages} · ${fmt(v.bytes / 1024, 1)} KiB`, String(v.dropped_over_cap + v.dropped_send)];
      for (const text of cells) {
        const td = document.createElement('td');
        td.textContent = text;
        tr.append(td);
      }
      return tr;
    }));
  }
}
