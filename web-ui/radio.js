// Radio payload card: link quality (loss, latency, RSSI, margin, distance) now and over
// the last minutes (client-side history, see history.js), on two small canvas charts.
// Test hooks: [data-field=loss] / [data-field=latency].

import { drawChart } from './chart.js';
import { fmt } from './model.js';

export class RadioCard {
  constructor(el, { vehicleId, history }) {
    this.id = vehicleId;
    this.history = history;
    el.innerHTML = `
      <dl class="kv compact">
        <div><dt>loss</dt><dd data-field="loss">–</dd></div>
        <div><dt>latency</dt><dd data-field="latency">–</dd></div>
        <div><dt>rssi</dt><dd data-field="rssi">–</dd></div>
        <div><dt>margin</dt><dd data-field="margin">–</dd></div>
        <div><dt>distance</dt><dd data-field="distance">–</dd></div>
        <div><dt>backend</dt><dd data-field="backend">–</dd></div>
      </dl>
      <div class="chart-pair"><canvas class="chart small" data-chart="loss"></canvas><canvas class="chart small" data-chart="latency"></canvas></div>`;
    this.el = el;
    this.lastDraw = 0;
  }

  update(p) {
    const s = p.state || {};
    const put = (k, t) => { const e = this.el.querySelector(`[data-field="${k}"]`); if (e.textContent !== t) e.textContent = t; };
    put('loss', `${fmt(s.loss_percent, 1)} %${s.override ? ' (override)' : ''}`);
    put('latency', `${fmt(s.latency_ms, 1)} ms`);
    put('rssi', `${fmt(s.rssi_dbm, 1)} dBm`);
    put('margin', `${fmt(s.link_margin_db, 1)} dB`);
    put('distance', `${fmt(s.distance_m, 0)} m`);
    put('backend', String(s.backend ?? '–'));
    const now = Date.now();
    if (now - this.lastDraw < 1000) return;
    this.lastDraw = now;
    const h = this.history.of(this.id);
    drawChart(this.el.querySelector('[data-chart="loss"]'),
      [{ label: 'loss', colour: '#ff8a5b', points: h.loss.points }],
      { windowS: 120, now, title: 'loss', unit: '%', fixedMin: 0, min: 0, max: 5 });
    drawChart(this.el.querySelector('[data-chart="latency"]'),
      [{ label: 'latency', colour: '#5bd1e6', points: h.latency.points }],
      { windowS: 120, now, title: 'latency', unit: 'ms', fixedMin: 0, min: 0, max: 10 });
  }

  destroy() {}
}
