// Vehicle detail (the "Vehicle" tab): the selected vehicle's telemetry at 10 Hz, its FSM
// state history and PX4 status texts (kept client-side from the stream, see history.js),
// the link counters of its MAVLink endpoint (GET /api/v1/links, polled while shown), its
// parameters (params.js), and every individual command, with go-to by clicking the plan.
// Test hooks: [data-testid=detail] with data-vehicle-id, dd[data-field=…],
// button[data-detail-command=…], ol[data-testid=state-history] li, detail-goto.

import * as api from './api.js';
import { ParamsView } from './params.js';
import { confirmAction } from './confirm.js';
import { displayState, stateClass, fmt, fmtAge, fmtTime, groundSpeed, gnssText } from './model.js';

const COMMANDS = [
  ['arm', 'Arm'], ['disarm', 'Disarm'], ['takeoff', 'Take off'], ['hold', 'Hold'],
  ['land', 'Land'], ['rtl', 'RTL'], ['join_formation', 'Join form.'], ['leave_formation', 'Leave form.'],
];
const SEVERITY = ['EMERG', 'ALERT', 'CRIT', 'ERROR', 'WARN', 'NOTICE', 'INFO', 'DEBUG'];

const FIELDS = [
  ['state', 'state'], ['mode', 'PX4 mode'], ['armed', 'armed'], ['landed', 'landed state'],
  ['ned', 'N / E / D m'], ['alt', 'height m'], ['amsl', 'AMSL m'], ['latlon', 'lat / lon'],
  ['speed', 'ground m/s'], ['vz', 'climb m/s'], ['heading', 'heading °'], ['battery', 'battery'],
  ['gnss', 'GNSS'], ['link', 'link'], ['formation', 'formation'], ['model', 'model / sysid'], ['remote_id', 'Remote ID'],
];

const OPERATOR_AT = { live_gnss: 'live GNSS', fixed: 'fixed location', takeoff: 'takeoff point' };

/** Where the operator location last sent came from, and why not live GNSS when configured. */
function operatorAt(r) {
  const source = r.operator_location_source;
  if (!source) return '';
  const why = r.operator_location_fallback ? ` (not live GNSS: ${r.operator_location_fallback})` : '';
  return ` at ${OPERATOR_AT[source] ?? source}${why}`;
}

/** The vehicle's Remote ID: what skein sends, what its transmitter says (OPEN_DRONE_ID_ARM_STATUS). */
function remoteId(r) {
  if (!r) return 'off';
  const sent = r.operator_sent ? `operator sent${operatorAt(r)}` : 'operator not sent';
  const t = r.transmitter;
  if (!t) return `${sent} · no transmitter heard`;
  return `${sent} · ${t.good_to_arm ? 'transmitter ready' : `transmitter: ${t.error || 'not ready'}`}`;
}

export class VehicleDetail {
  /** deps: {controls, toasts, log, history, plan, tabs, connectionOf(id)}. */
  constructor(root, deps) {
    Object.assign(this, deps);
    this.root = root;
    this.id = null;
    this.v = null;
    root.innerHTML = `
      <p class="muted detail-empty" data-testid="detail-empty">Select a vehicle on the plan or in the table.</p>
      <div class="detail" data-testid="detail" hidden>
        <div class="detail-head"><h3 data-field="id"></h3><span class="badge" data-field="badge"></span>
          <span class="hint" data-field="age"></span></div>
        <dl class="kv">${FIELDS.map(([k, l]) => `<div><dt>${l}</dt><dd data-field="${k}">–</dd></div>`).join('')}</dl>
        <div class="detail-cmds" role="group" aria-label="Vehicle commands">
          ${COMMANDS.map(([c, l]) => `<button type="button" class="btn tiny" data-detail-command="${c}">${l}</button>`).join('')}
          <button type="button" class="btn tiny primary" data-testid="detail-goto" title="Then click a point on the plan (G)">Go to…</button>
          <button type="button" class="btn tiny danger" data-detail-command="force_disarm" title="Stops the motors, even in the air">Force disarm</button>
        </div>
        <h4>State history</h4>
        <ol class="mini-log" data-testid="state-history"></ol>
        <h4>Status texts</h4>
        <ol class="mini-log" data-testid="status-texts"></ol>
        <h4>Link counters <span class="hint" data-field="conn"></span></h4>
        <div class="links-box"><table class="links" data-testid="link-counters"><thead><tr><th>endpoint</th><th title="frames decoded">ok</th>
          <th title="bad CRC">crc</th><th title="unknown message ids">unkn.</th><th title="parse errors, truncated, bad flags, garbage bytes">malf.</th>
          <th title="rejected datagrams (other sources)">rej.</th><th title="frames sent">sent</th><th title="send errors, no route">s.err</th>
          <th title="MAVLink 2 signing: frames dropped unsigned, badly signed or replayed (– when the link does not sign)">sig.</th></tr></thead><tbody></tbody></table></div>
        <h4>Parameters</h4>
        <div data-testid="params"></div>
      </div>`;
    this.q = (sel) => root.querySelector(sel);
    this.params = new ParamsView(this.q('[data-testid="params"]'), deps);
    this.q('.detail-cmds').addEventListener('click', (ev) => {
      const b = ev.target.closest('button');
      if (!b || !this.id) return;
      if (b.dataset.testid === 'detail-goto') this.goto();
      else this.command(b.dataset.detailCommand, b);
    });
    this.links = new api.Poller(() => this.pollLinks(), 2000, () => this.id && this.tabs.isOpen('vehicle'));
    this.tabs.onOpen((name) => { if (name === 'vehicle') { this.links.poke(); this.renderLists(); } });
    this.listsKey = '';
  }

  setVehicle(id) {
    if (this.id === id) return;
    this.id = id;
    this.v = null;
    this.listsKey = '';
    this.q('[data-testid="detail-empty"]').hidden = !!id;
    this.q('[data-testid="detail"]').hidden = !id;
    this.q('[data-testid="detail"]').dataset.vehicleId = id || '';
    this.params.setVehicle(id);
    if (id) { this.q('[data-field="id"]').textContent = id; this.links.poke(); }
  }

  async command(command, button) {
    const id = this.id;
    let body = { command };
    if (command === 'takeoff') {
      const alt = this.controls.takeoffAltitude();
      if (alt === null) return;
      body.altitude_m = alt;
    }
    if (command === 'force_disarm') {
      const ok = await confirmAction(`Force disarm ${id}?`,
        'The motors stop at once, even in the air: the vehicle falls.', 'Force disarm');
      if (!ok) return;
      body = { command, confirm: true };
    }
    this.controls.run(button, `${id} ${command}`, () => api.vehicleCommand(id, body));
  }

  /** Go-to: the next click on the plan is the target (at the vehicle's current height). */
  async goto() {
    const id = this.id;
    const p = await this.plan.pickPoint(`Go to for ${id}: click the target on the plan (Esc cancels)`);
    if (!p || !this.v || this.v.id !== id) return;
    const down = this.v.position && Number.isFinite(this.v.position.down_m) ? this.v.position.down_m : -10;
    this.plan.setMark(`goto-${id}`, p.north_m, p.east_m, `${id} go-to`);
    this.gotoAt = { id, t: Date.now() };
    const body = { command: 'goto', north_m: round1(p.north_m), east_m: round1(p.east_m), down_m: round1(down) };
    this.controls.run(this.q('[data-testid="detail-goto"]'), `${id} goto N ${body.north_m} E ${body.east_m}`,
      () => api.vehicleCommand(id, body));
  }

  /** A vehicles frame: patches the telemetry of the selected vehicle. */
  update(vehicles) {
    if (!this.id) return;
    const v = vehicles.find((x) => x.id === this.id);
    if (!v) return;
    this.v = v;
    // The go-to cross goes once the vehicle has left GoTo (arrived, or was commanded otherwise).
    const g = this.gotoAt;
    if (g && g.id === v.id && v.state !== 'GoTo' && Date.now() - g.t > 3000) {
      this.plan.clearMark(`goto-${v.id}`);
      this.gotoAt = null;
    }
    if (!this.tabs.isOpen('vehicle')) return;
    const p = v.position || {};
    const vel = v.velocity || {};
    const b = v.battery || {};
    const link = v.link || {};
    const f = v.formation;
    const put = (k, text) => {
      const el = this.q(`[data-field="${k}"]`);
      if (el.textContent !== text) el.textContent = text;
    };
    const badge = this.q('[data-field="badge"]');
    badge.className = `badge s-${stateClass(v)}`;
    put('badge', displayState(v));
    put('state', displayState(v));
    put('mode', v.px4_mode || '–');
    put('armed', v.armed ? 'armed' : 'safe');
    put('landed', v.landed_state || '–');
    put('ned', `${fmt(p.north_m)} / ${fmt(p.east_m)} / ${fmt(p.down_m)}`);
    put('alt', fmt(p.relative_alt_m));
    put('amsl', fmt(p.alt_amsl_m));
    put('latlon', `${fmt(p.lat_deg, 6)} / ${fmt(p.lon_deg, 6)}`);
    put('speed', fmt(groundSpeed(vel)));
    put('vz', fmt(Number.isFinite(vel.down_m_s) ? -vel.down_m_s : NaN));
    put('heading', fmt(v.heading_deg, 0));
    put('battery', `${fmt(b.percent, 0)} % · ${fmt(b.voltage_v, 2)} V`);
    put('gnss', gnssText(v.gps));
    put('link', `${link.connected ? 'up' : 'LOST'} · seen ${fmtAge(link.last_seen_ms)} ago`);
    put('formation', f ? `slot ${f.slot}${f.leader ? ' (leader)' : ''} · error ${fmt(f.error_m, 2)} m` : '–');
    put('model', `${v.model || '–'} / ${v.sysid ?? '–'}`);
    put('remote_id', remoteId(v.remote_id));
    this.renderLists();
  }

  renderLists() {
    if (!this.id) return;
    const h = this.history.of(this.id);
    const key = `${h.states.length}:${h.states.at(-1)?.t}:${h.texts.length}:${h.texts.at(-1)?.t}`;
    if (key === this.listsKey) return;
    this.listsKey = key;
    const li = (t, cls, text) => {
      const e = document.createElement('li');
      if (cls) e.className = cls;
      const time = document.createElement('time');
      time.textContent = fmtTime(new Date(t));
      const s = document.createElement('span');
      s.textContent = text;
      e.append(time, s);
      return e;
    };
    this.q('[data-testid="state-history"]').replaceChildren(
      ...[...h.states].reverse().map((s) => {
        const e = li(s.t, '', s.from ? `${s.from} → ${s.to}` : s.to);
        e.dataset.to = s.to;
        return e;
      }));
    const texts = [...h.texts].reverse().map((s) =>
      li(s.t, s.severity <= 3 ? 'lvl-error' : s.severity === 4 ? 'lvl-warn' : '', `[${SEVERITY[s.severity] || s.severity}] ${s.text}`));
    if (!texts.length) {
      const e = document.createElement('li');
      e.className = 'muted';
      e.textContent = 'none received since the page opened';
      texts.push(e);
    }
    this.q('[data-testid="status-texts"]').replaceChildren(...texts);
  }

  /**
   * One row per MAVLink endpoint; the selected vehicle's own endpoint (known from its
   * vehicle_joined event) is highlighted. Counters of malformed input are shown in red
   * when not zero.
   */
  async pollLinks() {
    const res = await api.getLinks();
    if (!res.ok) return res;
    const conn = this.connectionOf(this.id);
    const list = Array.isArray(res.data) ? res.data : [];
    const known = list.some((e) => e.connection === conn);
    this.q('[data-field="conn"]').textContent = known ? conn : 'every endpoint (this vehicle\'s joined before the page opened)';
    const rows = list.map((e) => {
      const d = e.decode || {}, sd = e.send || {};
      const malformed = (d.parse_errors || 0) + (d.truncated || 0) + (d.bad_flags || 0) + (d.garbage_bytes || 0);
      const cells = [e.connection, d.frames_ok, d.bad_crc, d.unknown_message, malformed, d.rejected_datagrams,
        sd.frames_sent, (sd.send_errors || 0) + (sd.no_route || 0),
        e.signing ? e.signing.unsigned + e.signing.bad_signature + e.signing.replayed + e.signing.too_old : null];
      const tr = document.createElement('tr');
      tr.classList.toggle('mine', known && e.connection === conn);
      cells.forEach((c, i) => {
        const td = document.createElement('td');
        td.textContent = c ?? '–';
        if (i >= 2 && i !== 1 && i !== 6 && Number(c) > 0) td.className = 'bad';
        tr.append(td);
      });
      tr.title = `${e.connection} (local ${e.local_addr || '–'})`;
      return tr;
    });
    this.q('[data-testid="link-counters"] tbody').replaceChildren(...rows);
    return res;
  }
}

const round1 = (x) => Math.round(x * 10) / 10;
