// Swarm controls (take off, formation, hold / RTL / land) and per-vehicle commands, and
// how their HTTP outcome is shown: a toast plus a line in the event log for every answer
// (202 accepted / refused, 200 formation, 4xx {error, field}, network failure).

import * as api from './api.js';
import { describeFormation } from './log.js';
import { compareIds } from './model.js';
import { confirmAction } from './confirm.js';

// Button labels of the formation shapes; the list itself and how many vehicles each needs
// come from GET /api/v1/formation/shapes (`custom` needs offsets: API only).
const SHAPE_LABELS = {
  line: 'Line', column: 'Column', wedge: 'Wedge', echelon_left: 'Echelon L',
  echelon_right: 'Echelon R', diamond: 'Diamond', circle: 'Circle', grid: 'Grid',
};

export class Controls {
  constructor({ toasts, log }) {
    this.toasts = toasts;
    this.log = log;
    this.leaderIds = '';
    this.onFormation = () => {};

    const takeoffForm = document.getElementById('takeoff-form');
    this.altInput = document.getElementById('takeoff-alt');
    takeoffForm.addEventListener('submit', (ev) => {
      ev.preventDefault();
      const alt = this.takeoffAltitude();
      if (alt === null) return;
      this.run(ev.submitter || takeoffForm.querySelector('button'), 'takeoff',
        () => api.swarmCommand({ command: 'takeoff', altitude_m: alt }), { altitude_m: 'takeoff-alt' });
    });

    // Formation: one submit button per shape, as the server lists them.
    this.shapeButtons = document.getElementById('shape-buttons');
    this.vehicleCount = 0;
    this.loadShapes();
    this.leaderSelect = document.getElementById('form-leader');
    const formForm = document.getElementById('formation-form');
    formForm.addEventListener('submit', (ev) => {
      ev.preventDefault();
      const btn = ev.submitter || this.shapeButtons.querySelector('button');
      if (!btn) return;
      const spec = this.formationSpec(btn.dataset.shape);
      if (!spec) return;
      this.requestFormation(btn, spec);
    });

    // Leader motion (the virtual leader, or the leader vehicle).
    const leaderForm = document.getElementById('leader-form');
    leaderForm.addEventListener('submit', (ev) => {
      ev.preventDefault();
      const btn = ev.submitter || leaderForm.querySelector('button');
      const motion = btn.dataset.leaderMotion;
      const body = this.leaderMotionBody(motion);
      if (!body) return;
      this.run(btn, `leader ${motion}`, () => api.leaderMotion(motion, body), {
        north_m: 'lead-north', east_m: 'lead-east', speed_m_s: 'lead-speed', radius_m: 'lead-radius',
      });
    });

    // A field flagged by a 400 stays marked until it is edited.
    for (const el of document.querySelectorAll('.ctl-group input, .ctl-group select')) {
      el.addEventListener('input', () => el.removeAttribute('aria-invalid'));
    }

    for (const b of document.querySelectorAll('[data-swarm-command]')) {
      b.addEventListener('click', () => this.swarmCommand(b.dataset.swarmCommand, b));
    }
  }

  /** A swarm command; landing every vehicle asks first. */
  async swarmCommand(command, button) {
    if (command === 'land') {
      const ok = await confirmAction('Land every vehicle?', 'All vehicles descend where they are and the formation ends.', 'Land all');
      if (!ok) return;
    }
    if (command === 'takeoff') {
      const alt = this.takeoffAltitude();
      if (alt === null) return;
      this.run(button, 'takeoff', () => api.swarmCommand({ command, altitude_m: alt }), { altitude_m: 'takeoff-alt' });
      return;
    }
    this.run(button, command, () => api.swarmCommand({ command }));
  }

  /** The takeoff altitude input as a number, or null (and a toast) when invalid. */
  takeoffAltitude() {
    const alt = Number(this.altInput.value);
    if (!this.altInput.value || !Number.isFinite(alt) || alt <= 0) {
      this.toasts.show('error', 'Take off', 'altitude must be a number of metres above 0');
      this.altInput.focus();
      return null;
    }
    return alt;
  }

  /** Builds one button per shape from GET /api/v1/formation/shapes. */
  async loadShapes() {
    const res = await api.getShapes();
    if (!res.ok || !Array.isArray(res.data)) {
      this.toasts.show('error', 'Formation shapes', (res.data && res.data.error) || 'no answer');
      return;
    }
    const buttons = [];
    for (const { shape, min_vehicles: min } of res.data) {
      if (!(shape in SHAPE_LABELS)) continue;
      const b = document.createElement('button');
      b.type = 'submit';
      b.className = 'btn primary';
      b.dataset.shape = shape;
      b.dataset.testid = shape;
      b.dataset.minVehicles = String(min);
      b.textContent = SHAPE_LABELS[shape];
      buttons.push(b);
    }
    this.shapeButtons.replaceChildren(...buttons);
    this.updateShapeAvailability();
  }

  /** Marks the shapes that need more vehicles than the swarm has (the server refuses them). */
  updateShapeAvailability() {
    for (const b of this.shapeButtons.querySelectorAll('button')) {
      const min = Number(b.dataset.minVehicles);
      const short = this.vehicleCount < min;
      b.classList.toggle('short', short);
      b.title = short ? `needs at least ${min} vehicles` : `${b.textContent} formation`;
    }
  }

  /** The body of a leader motion request from the form, or null when a field is invalid. */
  leaderMotionBody(motion) {
    if (motion === 'hold') return {};
    const num = (id) => Number(document.getElementById(id).value);
    const [north, east, speed] = [num('lead-north'), num('lead-east'), num('lead-speed')];
    if (![north, east].every(Number.isFinite)) {
      this.toasts.show('error', 'Leader', 'north and east must be numbers of metres');
      return null;
    }
    if (!Number.isFinite(speed) || speed <= 0) {
      this.toasts.show('error', 'Leader', 'speed must be a number of m/s above 0');
      return null;
    }
    const body = { north_m: north, east_m: east, speed_m_s: speed };
    if (motion === 'orbit') {
      const radius = num('lead-radius');
      if (!Number.isFinite(radius) || radius <= 0) {
        this.toasts.show('error', 'Leader', 'radius must be a number of metres above 0');
        return null;
      }
      body.radius_m = radius;
    }
    return body;
  }

  /** The PUT /api/v1/formation body from the form, or null when a field is invalid. */
  formationSpec(shape) {
    const num = (id) => {
      const el = document.getElementById(id);
      return el.value.trim() === '' ? null : Number(el.value);
    };
    const spacing = num('form-spacing');
    if (spacing === null || !Number.isFinite(spacing) || spacing <= 0) {
      this.toasts.show('error', 'Formation', 'spacing must be a number of metres above 0');
      return null;
    }
    const spec = { shape, spacing_m: spacing };
    const heading = num('form-heading');
    if (heading !== null && Number.isFinite(heading) && heading !== 0) spec.heading_deg = heading;
    const alt = num('form-alt');
    if (alt !== null && Number.isFinite(alt)) spec.altitude_m = alt;
    if (this.leaderSelect.value) spec.leader = this.leaderSelect.value;
    spec.frame = document.getElementById('form-frame').value;
    return spec;
  }

  /** A per-vehicle command from the table. */
  vehicleCommand(id, command, button) {
    let body = { command };
    if (command === 'takeoff') {
      const alt = this.takeoffAltitude();
      if (alt === null) return;
      body = { command, altitude_m: alt };
    }
    this.run(button, `${id} ${command}`, () => api.vehicleCommand(id, body), { altitude_m: 'takeoff-alt' });
  }

  /**
   * PUT /api/v1/formation. Refused while vehicles are still climbing (the server counts
   * only those at altitude), it is asked again once none is taking off, for up to a minute.
   */
  async requestFormation(button, spec, retry = false) {
    const label = `formation ${spec.shape}${retry ? ' (retried)' : ''}`;
    const res = await this.run(button, label, () => api.putFormation(spec), {
      spacing_m: 'form-spacing', heading_deg: 'form-heading', altitude_m: 'form-alt', leader: 'form-leader',
      frame: 'form-frame',
    });
    const climbing = this.takingOff();
    if (!retry && res && res.status === 400 && climbing.length) {
      this.pendingFormation = { spec, until: Date.now() + 60000 };
      const text = `asked again when ${climbing.join(', ')} reach${climbing.length === 1 ? 'es' : ''} their altitude`;
      this.toasts.show('info', `formation ${spec.shape} waits for the takeoff`, text);
      this.log.note('api', 'info', 'formation', `formation ${spec.shape}: ${text}`);
    }
  }

  takingOff() {
    return (this.vehicles || []).filter((v) => v.state === 'TakingOff').map((v) => v.id);
  }

  /** The stream's vehicles: states for a formation waiting on a takeoff. */
  setVehicles(vehicles) {
    this.vehicles = vehicles;
    const p = this.pendingFormation;
    if (!p) return;
    if (Date.now() > p.until) {
      this.pendingFormation = null;
      this.toasts.show('warn', `formation ${p.spec.shape} not retried`, 'the takeoff did not end within a minute');
      return;
    }
    if (!this.takingOff().length) {
      this.pendingFormation = null;
      this.requestFormation(null, p.spec, true);
    }
  }

  /** Keeps the leader choices in step with the swarm (and the current choice). */
  setVehicleIds(ids) {
    const sorted = [...ids].sort(compareIds);
    const key = sorted.join('\n');
    if (key === this.leaderIds) return;
    this.leaderIds = key;
    this.vehicleCount = sorted.length;
    this.updateShapeAvailability();
    const keep = this.leaderSelect.value;
    const opts = [new Option('auto', ''), new Option('virtual', 'virtual')];
    for (const id of sorted) opts.push(new Option(id, id));
    this.leaderSelect.replaceChildren(...opts);
    this.leaderSelect.value = keep === 'virtual' || sorted.includes(keep) ? keep : '';
  }

  /**
   * Sends one request with its button disabled, then reports the outcome. fields maps the
   * API's field names to the ids of the inputs that fill them (marked when named by a 400).
   */
  async run(button, label, send, fields = {}) {
    if (button) button.disabled = true;
    try {
      const res = await send();
      this.report(label, res);
      const bad = res.data && res.data.field && fields[res.data.field];
      if (!res.ok && bad) document.getElementById(bad).setAttribute('aria-invalid', 'true');
      return res;
    } finally {
      if (button) button.disabled = false;
    }
  }

  report(label, res) {
    const d = res.data || {};
    if (!res.ok) {
      const where = d.field ? ` (field ${d.field})` : '';
      const status = res.status ? `HTTP ${res.status}` : 'no answer';
      this.toasts.show('error', `${label}: ${status}`, `${d.error}${where}`);
      this.log.note('api', 'error', 'api', `${label}: ${status}: ${d.error}${where}`);
      return;
    }
    if (res.status === 202) {
      const acc = d.accepted || [];
      const ref = d.refused || [];
      const accText = acc.length ? `accepted by ${acc.join(', ')}` : 'accepted by none';
      this.toasts.show(ref.length ? 'warn' : 'ok', `${label} #${d.command_id}`, accText);
      this.log.note('api', 'ok', 'api', `${label} #${d.command_id}: ${accText}`);
      for (const r of ref) {
        this.toasts.show('warn', `${label}: ${r.id} refused`, r.reason);
        this.log.note('api', 'warn', 'api', `${label}: ${r.id} refused: ${r.reason}`);
      }
      return;
    }
    if (d && 'active' in d) { // a FormationStatus (PUT /formation)
      this.onFormation(d);
      this.toasts.show('ok', label, describeFormation(d));
      this.log.note('api', 'ok', 'api', `${label}: ${describeFormation(d)}`);
      return;
    }
    this.toasts.show('ok', label, `HTTP ${res.status}`);
  }
}
