// Vehicle table: one row per vehicle, keyed by id, created once and then patched in
// place (only cells whose text changed are touched), so rows never flicker or lose focus.
// Test hooks: <tr data-vehicle-id="uav-1"> with cells <td data-field="state|mode|armed|
// altitude|speed|battery|link|fence|slot"> (fence: `synced v2`, `failed`, `BREACH` …, with
// data-fence-state and data-breached).

import { stateClass, displayState, isConnecting, compareIds, fmt, fmtAge, groundSpeed } from './model.js';

const PER_VEHICLE = [
  ['takeoff', 'Take off'],
  ['hold', 'Hold'],
  ['land', 'Land'],
  ['rtl', 'RTL'],
];

export class VehicleTable {
  /**
   * tbody: the <tbody>; empty: element shown while there are no rows;
   * onCommand(id, command): a per-vehicle button was pressed; onSelect(id|null).
   */
  constructor(tbody, empty, { onCommand, onSelect }) {
    this.tbody = tbody;
    this.empty = empty;
    this.rows = new Map(); // id → {tr, cells, last}
    this.selected = null;
    tbody.addEventListener('click', (ev) => {
      const tr = ev.target.closest('tr[data-vehicle-id]');
      if (!tr) return;
      const btn = ev.target.closest('button[data-command]');
      if (btn) {
        onCommand(tr.dataset.vehicleId, btn.dataset.command, btn);
        return;
      }
      onSelect(this.selected === tr.dataset.vehicleId ? null : tr.dataset.vehicleId);
    });
  }

  /** Replaces the table's contents with this list of vehicle snapshots. */
  update(vehicles) {
    const seen = new Set();
    let inserted = false;
    for (const v of vehicles) {
      seen.add(v.id);
      let row = this.rows.get(v.id);
      if (!row) {
        row = this.createRow(v.id);
        this.rows.set(v.id, row);
        inserted = true;
      }
      this.patch(row, v);
    }
    for (const [id, row] of this.rows) {
      if (!seen.has(id)) {
        row.tr.remove();
        this.rows.delete(id);
      }
    }
    if (inserted) this.reorder();
    this.empty.hidden = this.rows.size > 0;
  }

  /** Keeps rows in natural id order; moves only rows that are out of place. */
  reorder() {
    const ids = [...this.rows.keys()].sort(compareIds);
    let prev = null;
    for (const id of ids) {
      const tr = this.rows.get(id).tr;
      const want = prev ? prev.nextSibling : this.tbody.firstChild;
      if (want !== tr) this.tbody.insertBefore(tr, want);
      prev = tr;
    }
  }

  setSelected(id) {
    this.selected = id;
    for (const [rid, row] of this.rows) {
      const on = rid === id;
      row.tr.classList.toggle('selected', on);
      row.tr.setAttribute('aria-selected', on ? 'true' : 'false');
    }
  }

  createRow(id) {
    const tr = document.createElement('tr');
    tr.dataset.vehicleId = id;
    tr.dataset.testid = 'vehicle-row';
    tr.setAttribute('aria-selected', 'false');
    const cells = {};
    const th = document.createElement('th');
    th.scope = 'row';
    th.dataset.field = 'id';
    th.textContent = id;
    tr.append(th);
    for (const f of ['state', 'mode', 'armed', 'altitude', 'speed', 'battery', 'link', 'fence', 'slot']) {
      const td = document.createElement('td');
      td.dataset.field = f;
      if (f === 'altitude' || f === 'speed') td.className = 'num';
      cells[f] = td;
      tr.append(td);
    }
    // Battery: a small bar and the percentage.
    const bar = document.createElement('span');
    bar.className = 'batt-bar';
    bar.setAttribute('aria-hidden', 'true');
    const fill = document.createElement('span');
    bar.append(fill);
    const pct = document.createElement('span');
    pct.className = 'batt-pct';
    cells.battery.append(bar, pct);
    cells.battFill = fill;
    cells.battText = pct;
    // State: a coloured badge whose text is exactly the state name.
    const badge = document.createElement('span');
    badge.className = 'badge';
    cells.state.append(badge);
    cells.stateBadge = badge;
    // Per-vehicle commands.
    const act = document.createElement('td');
    act.dataset.field = 'actions';
    act.className = 'actions';
    for (const [cmd, label] of PER_VEHICLE) {
      const b = document.createElement('button');
      b.type = 'button';
      b.className = 'btn tiny';
      b.dataset.command = cmd;
      b.dataset.testid = `vehicle-${cmd}`;
      b.textContent = label;
      b.setAttribute('aria-label', `${label} ${id}`);
      act.append(b);
    }
    tr.append(act);
    tr.classList.toggle('selected', this.selected === id);
    return { tr, cells, last: {} };
  }

  patch(row, v) {
    const { tr, cells, last } = row;
    const set = (key, el, text) => {
      if (last[key] !== text) {
        el.textContent = text;
        last[key] = text;
      }
    };
    const cls = `s-${stateClass(v)}`;
    if (last.cls !== cls) {
      if (last.cls) tr.classList.remove(last.cls);
      tr.classList.add(cls);
      last.cls = cls;
    }
    if (last.state !== undefined && last.state !== v.state) {
      // Brief highlight of the state cell on a transition.
      cells.state.classList.remove('flash');
      void cells.state.offsetWidth; // restart the CSS animation
      cells.state.classList.add('flash');
    }
    set('state', cells.stateBadge, displayState(v));
    cells.stateBadge.title = isConnecting(v) ? 'link up; waiting for the vehicle to be ready (state Disconnected)' : '';
    set('mode', cells.mode, v.px4_mode || '–');
    set('armed', cells.armed, v.armed ? 'armed' : 'safe');
    cells.armed.classList.toggle('is-armed', !!v.armed);
    set('altitude', cells.altitude, v.position ? fmt(v.position.relative_alt_m, 1) : '–');
    set('speed', cells.speed, fmt(groundSpeed(v.velocity), 1));

    const pct = v.battery && Number.isFinite(v.battery.percent) ? v.battery.percent : null;
    const battText = pct === null ? '–' : `${Math.round(pct)} %`;
    if (last.batt !== battText) {
      cells.battText.textContent = battText;
      cells.battFill.style.width = `${pct === null ? 0 : Math.max(0, Math.min(100, pct))}%`;
      cells.battFill.className = pct === null ? '' : pct > 50 ? 'ok' : pct > 25 ? 'low' : 'crit';
      cells.battery.title = v.battery ? `${fmt(v.battery.voltage_v, 2)} V` : '';
      last.batt = battText;
    }

    const link = v.link || {};
    set('link', cells.link, link.connected ? `up ${fmtAge(link.last_seen_ms)}` : `lost ${fmtAge(link.last_seen_ms)}`);
    cells.link.dataset.connected = link.connected ? 'true' : 'false';

    // The geofence on the autopilot, and skein's breach check.
    const fence = v.fence;
    const fenceText = !fence ? '–' : fence.breached ? 'BREACH' : `${fence.state} v${fence.version}`;
    set('fence', cells.fence, fenceText);
    cells.fence.dataset.fenceState = fence ? fence.state : '';
    cells.fence.dataset.breached = fence && fence.breached ? 'true' : 'false';
    cells.fence.title = fence ? [fence.reason, `${fence.fence_items} fence items, ${fence.rally_items} rally points`].filter(Boolean).join(' · ') : '';

    const f = v.formation;
    const slot = f ? (f.leader ? `${f.slot} leader` : `${f.slot} · ${fmt(f.error_m, 1)} m`) : '–';
    set('slot', cells.slot, slot);
    cells.slot.classList.toggle('is-leader', !!(f && f.leader));
    tr.dataset.state = v.state;
  }
}
