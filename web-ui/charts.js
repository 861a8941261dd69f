// Charts tab: altitude, ground speed and battery of every vehicle, and the formation's
// RMS error and smallest separation, over the last minutes (history.js), redrawn once a
// second while shown. One colour per vehicle, the same on every chart.

import { drawChart } from './chart.js';
import { WINDOW_S } from './history.js';
import { compareIds, vehicleColour } from './model.js';

const WINDOWS = [60, 180, WINDOW_S];

export class ChartsView {
  /** deps: {history, tabs}. */
  constructor(root, deps) {
    Object.assign(this, deps);
    this.root = root;
    this.windowS = 180;
    root.innerHTML = `
      <div class="view-head"><span class="hint">last</span>
        ${WINDOWS.map((w) => `<button type="button" class="btn tiny" data-window="${w}">${w / 60} min</button>`).join('')}</div>
      <canvas class="chart" data-chart="altitude"></canvas>
      <canvas class="chart" data-chart="speed"></canvas>
      <canvas class="chart" data-chart="battery"></canvas>
      <canvas class="chart" data-chart="formation"></canvas>`;
    root.querySelector('.view-head').addEventListener('click', (ev) => {
      const b = ev.target.closest('button[data-window]');
      if (!b) return;
      this.windowS = Number(b.dataset.window);
      this.markWindow();
      this.draw();
    });
    this.markWindow();
    setInterval(() => { if (this.tabs.isOpen('charts')) this.draw(); }, 1000);
    this.tabs.onOpen((n) => { if (n === 'charts') requestAnimationFrame(() => this.draw()); });
  }

  markWindow() {
    for (const b of this.root.querySelectorAll('[data-window]')) b.classList.toggle('active', Number(b.dataset.window) === this.windowS);
  }

  draw() {
    const now = Date.now();
    const ids = [...this.history.vehicles.keys()].sort(compareIds);
    const per = (key) => ids.map((id, i) => ({ label: id, colour: vehicleColour(i), points: this.history.of(id)[key].points }));
    const c = (name) => this.root.querySelector(`[data-chart="${name}"]`);
    const o = { windowS: this.windowS, now };
    drawChart(c('altitude'), per('altitude'), { ...o, title: 'height above home', unit: 'm', min: 0 });
    drawChart(c('speed'), per('speed'), { ...o, title: 'ground speed', unit: 'm/s', fixedMin: 0, max: 1 });
    drawChart(c('battery'), per('battery'), { ...o, title: 'battery', unit: '%', fixedMin: 0, fixedMax: 100 });
    drawChart(c('formation'), [
      { label: 'rms error m', colour: '#e6b84a', points: this.history.rms.points },
      { label: 'min separation m', colour: '#4c9bff', points: this.history.minSep.points.filter((p) => Number.isFinite(p[1])) },
    ], { ...o, title: 'formation', unit: 'm', fixedMin: 0, max: 1, showLast: true, lastDigits: 2 });
  }
}
