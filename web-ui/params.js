// PX4 parameters of one vehicle: the ones skein has seen so far (GET …/params), read one
// by name (GET …/params/{name}) and write one (PUT …/params/{name}); every answer, good or
// bad, is shown (a 504 when the vehicle does not answer, a 409 when it refuses).
// Test hooks: [data-testid=param-name] / param-read, rows tr[data-param=NAME] with
// td[data-field=value], the value's edit input [data-testid=param-value] and param-write.

import * as api from './api.js';

// Common PX4 parameters offered while typing (any name can be read).
const COMMON = ['MIS_TAKEOFF_ALT', 'MPC_XY_CRUISE', 'MPC_XY_VEL_MAX', 'MPC_Z_VEL_MAX_UP', 'MPC_Z_VEL_MAX_DN',
  'MPC_ACC_HOR', 'MPC_LAND_SPEED', 'COM_DISARM_LAND', 'COM_DL_LOSS_T', 'COM_OF_LOSS_T', 'COM_RC_IN_MODE',
  'RTL_RETURN_ALT', 'NAV_ACC_RAD', 'BAT1_N_CELLS', 'BAT1_CAPACITY', 'MAV_SYS_ID', 'GF_MAX_HOR_DIST'];

export class ParamsView {
  constructor(root, { toasts, log }) {
    this.root = root;
    this.toasts = toasts;
    this.log = log;
    this.id = null;
    this.values = new Map(); // name → {value, type}
    root.innerHTML = `
      <form class="param-read" autocomplete="off">
        <input data-testid="param-name" list="param-names" placeholder="PARAM_NAME" maxlength="16" aria-label="Parameter name">
        <button class="btn tiny" data-testid="param-read" type="submit">Read</button>
        <button class="btn tiny" data-testid="param-list" type="button">List seen</button>
        <input class="param-filter" type="search" placeholder="filter" aria-label="Filter parameters">
      </form>
      <datalist id="param-names">${COMMON.map((n) => `<option value="${n}">`).join('')}</datalist>
      <div class="param-scroll"><table class="params"><tbody></tbody></table>
        <p class="muted param-empty">Read a parameter by name, or list the ones seen.</p></div>`;
    this.nameInput = root.querySelector('[data-testid="param-name"]');
    this.filter = root.querySelector('.param-filter');
    this.tbody = root.querySelector('tbody');
    this.empty = root.querySelector('.param-empty');
    root.querySelector('form').addEventListener('submit', (ev) => {
      ev.preventDefault();
      const name = this.nameInput.value.trim().toUpperCase();
      if (name) this.read(name);
    });
    root.querySelector('[data-testid="param-list"]').addEventListener('click', () => this.list());
    this.filter.addEventListener('input', () => this.render());
    this.tbody.addEventListener('submit', (ev) => {
      ev.preventDefault();
      const tr = ev.target.closest('tr[data-param]');
      const input = tr.querySelector('input');
      this.write(tr.dataset.param, input.value, tr.querySelector('button'));
    });
  }

  setVehicle(id) {
    if (id === this.id) return;
    this.id = id;
    this.values.clear();
    this.render();
  }

  fail(label, res) {
    const d = res.data || {};
    const status = res.status ? `HTTP ${res.status}` : 'no answer';
    this.toasts.show('error', `${label}: ${status}`, d.error + (d.field ? ` (field ${d.field})` : ''));
    this.log.note('api', 'error', 'api', `${label}: ${status}: ${d.error}`);
  }

  async list() {
    const id = this.id;
    const res = await api.getParams(id);
    if (id !== this.id) return;
    if (!res.ok) { this.fail(`${id} parameters`, res); return; }
    for (const p of res.data) {
      const old = this.values.get(p.name);
      this.values.set(p.name, { value: p.value, type: old ? old.type : '' });
    }
    if (!res.data.length) this.toasts.show('info', `${id} parameters`, 'none seen yet: read one by name');
    this.render();
  }

  async read(name) {
    const id = this.id;
    const res = await api.getParam(id, name);
    if (id !== this.id) return;
    if (!res.ok) { this.fail(`${id} read ${name}`, res); return; }
    this.values.set(res.data.name, { value: res.data.value, type: res.data.type });
    this.render();
    const tr = this.tbody.querySelector(`tr[data-param="${CSS.escape(res.data.name)}"]`);
    if (tr) tr.scrollIntoView({ block: 'nearest' });
  }

  async write(name, text, button) {
    const value = Number(text);
    if (text.trim() === '' || !Number.isFinite(value)) {
      this.toasts.show('error', `${name}`, 'the value must be a number');
      return;
    }
    const id = this.id;
    button.disabled = true;
    const res = await api.putParam(id, name, value);
    button.disabled = false;
    if (id !== this.id) return;
    if (!res.ok) { this.fail(`${id} set ${name}`, res); return; }
    this.values.set(res.data.name, { value: res.data.value, type: res.data.type });
    this.toasts.show('ok', `${id}: ${name} = ${res.data.value}`, res.data.type);
    this.log.note('api', 'ok', 'param', `${id}: ${name} set to ${res.data.value} (${res.data.type})`);
    this.render();
  }

  render() {
    const f = this.filter.value.trim().toUpperCase();
    const names = [...this.values.keys()].sort().filter((n) => !f || n.includes(f));
    const rows = [];
    for (const name of names) {
      const { value, type } = this.values.get(name);
      let tr = this.tbody.querySelector(`tr[data-param="${CSS.escape(name)}"]`);
      if (!tr) {
        tr = document.createElement('tr');
        tr.dataset.param = name;
        tr.dataset.testid = 'param-row';
        tr.innerHTML = `<th scope="row"></th><td data-field="value"></td><td data-field="type"></td>
          <td><form class="param-edit"><input data-testid="param-value" type="number" step="any" aria-label="New value">
          <button class="btn tiny" data-testid="param-write" type="submit">Set</button></form></td>`;
        tr.querySelector('th').textContent = name;
      }
      const shown = type === 'real32' ? String(+Number(value).toPrecision(7)) : String(value);
      const cell = tr.querySelector('[data-field="value"]');
      if (cell.textContent !== shown) cell.textContent = shown;
      tr.querySelector('[data-field="type"]').textContent = type || '';
      const input = tr.querySelector('input');
      if (document.activeElement !== input) input.placeholder = shown;
      rows.push(tr);
    }
    this.tbody.replaceChildren(...rows);
    this.empty.hidden = this.values.size > 0;
  }
}
