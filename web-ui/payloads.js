// Payloads tab: one card per payload slot of the chosen vehicle (the selected one by
// default), from the `payloads` of the stream's vehicle objects. Known kinds get their own
// widget (camera, gimbal, radio); every kind, a third-party plugin's included, also shows
// its published state generically and accepts a raw JSON command, so a new plugin appears
// without dashboard changes. Test hooks: [data-testid=payload-card][data-slot][data-kind],
// [data-testid=payload-vehicle] (the vehicle choice).

import * as api from './api.js';
import { CameraCard } from './camera.js';
import { GimbalCard } from './gimbal.js';
import { RadioCard } from './radio.js';
import { compareIds } from './model.js';

const WIDGETS = { camera: CameraCard, gimbal: GimbalCard, radio: RadioCard };

export class PayloadsView {
  /** deps: {toasts, log, plan, history, tabs}. */
  constructor(root, deps) {
    Object.assign(this, deps);
    this.root = root;
    this.id = null;
    this.cards = new Map(); // slot → {el, widget, kind, stateEl}
    this.key = '';
    this.ids = [];
    root.innerHTML = `
      <div class="view-head"><label>Vehicle <select data-testid="payload-vehicle"></select></label>
        <span class="hint" data-field="summary"></span></div>
      <div class="payload-cards"></div>
      <p class="muted" data-field="empty">Select a vehicle: its payloads show here.</p>`;
    this.select = root.querySelector('select');
    this.list = root.querySelector('.payload-cards');
    this.select.addEventListener('change', () => this.setVehicle(this.select.value || null));
    this.tabs.onOpen(() => this.activate());
    document.addEventListener('visibilitychange', () => this.activate());
  }

  setVehicle(id) {
    if (id === this.id) return;
    this.id = id;
    this.clear();
    this.select.value = id || '';
  }

  clear() {
    for (const c of this.cards.values()) c.widget && c.widget.destroy();
    this.cards.clear();
    this.list.replaceChildren();
    this.key = '';
  }

  /** The stream came back (skein may have restarted): reopen the video streams. */
  reconnected() {
    for (const c of this.cards.values()) if (c.widget && c.widget.reconnect) c.widget.reconnect();
  }

  activate() {
    const on = this.tabs.isOpen('payloads');
    for (const c of this.cards.values()) if (c.widget && c.widget.setActive) c.widget.setActive(on);
  }

  /** Sends a payload command; errors (and their field) are toasted, answers logged. */
  async send(slot, label, body, button) {
    const id = this.id;
    if (button) button.disabled = true;
    const res = await api.payloadCommand(id, slot, body);
    if (button) button.disabled = false;
    if (!res.ok) {
      const d = res.data || {};
      const where = d.field ? ` (field ${d.field})` : '';
      this.toasts.show('error', `${id} ${slot} ${label}: ${res.status ? `HTTP ${res.status}` : 'no answer'}`, `${d.error}${where}`);
      this.log.note('api', 'error', 'payload', `${id} ${slot} ${label}: ${d.error}${where}`);
      return res;
    }
    this.log.note('api', 'ok', 'payload', `${id} ${slot} ${label}: ok`);
    return res;
  }

  update(vehicles) {
    const withPayloads = vehicles.filter((v) => (v.payloads || []).length).map((v) => v.id).sort(compareIds);
    this.ids = vehicles.map((v) => v.id).sort(compareIds);
    const optKey = withPayloads.join(',');
    if (optKey !== this.optKey) {
      this.optKey = optKey;
      const opts = [new Option('–', ''), ...this.ids.map((x) => new Option(withPayloads.includes(x) ? x : `${x} (none)`, x))];
      this.select.replaceChildren(...opts);
      this.select.value = this.id || '';
    }
    const v = this.id && vehicles.find((x) => x.id === this.id);
    const payloads = v ? v.payloads || [] : [];
    this.root.querySelector('[data-field="empty"]').hidden = payloads.length > 0;
    this.root.querySelector('[data-field="empty"]').textContent = this.id ? `${this.id} carries no payload.` : 'Select a vehicle: its payloads show here.';
    this.root.querySelector('[data-field="summary"]').textContent = payloads.length ? payloads.map((p) => `${p.slot}: ${p.status}`).join(' · ') : '';
    const key = payloads.map((p) => `${p.slot}:${p.kind}`).join(',');
    if (key !== this.key) {
      this.clear();
      this.key = key;
      for (const p of payloads) this.cards.set(p.slot, this.createCard(p));
      this.activate();
    }
    if (!this.tabs.isOpen('payloads')) return;
    for (const p of payloads) {
      const c = this.cards.get(p.slot);
      if (!c) continue;
      c.el.dataset.status = String(p.status);
      const st = c.el.querySelector('[data-field="status"]');
      const status = String(p.status);
      // A slot whose kind no loaded plugin provides says which kind it waits for.
      const text = status === 'waiting_for_plugin' && p.waiting_for ? `waiting for a ${p.waiting_for} plugin` : status;
      if (st.textContent !== text) { st.textContent = text; st.className = `pl-status st-${status.split(/[^a-z]/)[0]}`; }
      const served = pluginLabel(p);
      const pl = c.el.querySelector('[data-field="plugin"]');
      if (pl.textContent !== served) pl.textContent = served;
      if (c.widget) c.widget.update(p, v);
      if (c.details.open) {
        const text = JSON.stringify(p.state, null, 1);
        if (c.stateEl.textContent !== text) c.stateEl.textContent = text;
      }
    }
  }

  createCard(p) {
    const el = document.createElement('article');
    el.className = 'payload-card';
    el.dataset.testid = 'payload-card';
    el.dataset.slot = p.slot;
    el.dataset.kind = p.kind;
    el.innerHTML = `
      <header><strong></strong><span class="hint" data-field="plugin"></span><span class="pl-status" data-field="status"></span></header>
      <div class="widget"></div>
      <details><summary>state and raw command</summary><pre class="state-json"></pre>
        <form class="raw-cmd" autocomplete="off"><input placeholder='{"command": "status"}' aria-label="Payload command (JSON)">
        <button class="btn tiny" type="submit">Send</button></form><pre class="state-json reply" data-field="reply" hidden></pre></details>`;
    el.querySelector('strong').textContent = `${p.slot} · ${p.kind}`;
    el.querySelector('[data-field="plugin"]').textContent = pluginLabel(p);
    const details = el.querySelector('details');
    const send = (label, body, button) => this.send(p.slot, label, body, button);
    el.querySelector('.raw-cmd').addEventListener('submit', (ev) => {
      ev.preventDefault();
      const input = ev.target.querySelector('input');
      let body;
      try { body = JSON.parse(input.value || '{"command":"status"}'); } catch (e) {
        this.toasts.show('error', `${p.slot}: not JSON`, String(e.message || e));
        return;
      }
      send(body.command || 'command', body, ev.submitter).then((res) => {
        // The payload's answer, under the command (errors are toasted by send).
        const reply = el.querySelector('[data-field="reply"]');
        reply.hidden = !(res && res.ok);
        if (res && res.ok) reply.textContent = `→ ${JSON.stringify(res.data, null, 1)}`;
      });
    });
    const W = WIDGETS[p.kind];
    const widget = W ? new W(el.querySelector('.widget'), {
      vehicleId: this.id, slot: p.slot, send, plan: this.plan, history: this.history, vehicleIds: () => this.ids,
    }) : null;
    if (!W) details.open = true; // an unknown kind: its state is all there is to show
    this.list.append(el);
    return { el, widget, details, stateEl: el.querySelector('.state-json') };
  }
}

/** Which library and build serve a payload: "plugin gimbal 0.1.0 · gen 2". */
function pluginLabel(p) {
  if (!p.plugin) return '';
  const version = p.plugin_version ? ` ${p.plugin_version}` : '';
  const generation = p.generation != null ? ` · gen ${p.generation}` : '';
  return `plugin ${p.plugin}${version}${generation}`;
}
