// Plugins tab: the payload plugin libraries (GET /api/v1/plugins, polled every 2 s while
// shown) with version, kinds, generation, status and their instances (vehicle, slot,
// isolation, pid, generation, status); the providers; the files refused with the reason;
// load (a file of the plugin directory), reload and unload.
// Test hooks: tr[data-plugin=NAME] with td[data-field=generation|version|status],
// button[data-plugin-op=reload|unload], [data-testid=plugin-file] / plugin-load.

import * as api from './api.js';
import { confirmAction } from './confirm.js';

export class PluginsView {
  /** deps: {toasts, log, tabs}. */
  constructor(root, deps) {
    Object.assign(this, deps);
    this.root = root;
    root.innerHTML = `
      <div class="view-head"><span class="hint" data-field="dir">plugin directory: …</span></div>
      <form class="plugin-load" autocomplete="off">
        <input data-testid="plugin-file" list="plugin-files" placeholder="libskein_plugin_x.so" aria-label="Plugin file to load">
        <datalist id="plugin-files"></datalist>
        <button class="btn tiny primary" type="submit" data-testid="plugin-load">Load</button>
      </form>
      <table class="plugins" data-testid="plugin-table">
        <thead><tr><th>library</th><th>version</th><th>gen.</th><th>status</th><th>kinds</th><th></th></tr></thead>
        <tbody></tbody></table>
      <h4>Providers</h4><p class="muted" data-field="providers">–</p>
      <h4>Refused files</h4><ul class="refused" data-testid="plugin-refused"></ul>`;
    this.tbody = root.querySelector('tbody');
    root.querySelector('form').addEventListener('submit', (ev) => {
      ev.preventDefault();
      const file = root.querySelector('[data-testid="plugin-file"]').value.trim();
      if (!file) { this.toasts.show('error', 'Load plugin', 'name a file of the plugin directory'); return; }
      this.op('load', { file }, ev.submitter);
    });
    this.tbody.addEventListener('click', async (ev) => {
      const b = ev.target.closest('button[data-plugin-op]');
      if (!b) return;
      const name = b.closest('tr[data-plugin]').dataset.plugin;
      if (b.dataset.pluginOp === 'unload') {
        const ok = await confirmAction(`Unload ${name}?`, 'Refused while instances live: stop their payloads first, or use reload.', 'Unload');
        if (!ok) return;
      }
      this.op(b.dataset.pluginOp, { name }, b);
    });
    this.poller = new api.Poller(() => this.refresh(), 2000, () => this.tabs.isOpen('plugins'));
    this.tabs.onOpen((n) => { if (n === 'plugins') this.poller.poke(); });
  }

  async op(op, body, button) {
    if (button) button.disabled = true;
    const res = await api.pluginOp(op, body);
    if (button) button.disabled = false;
    const what = body.name || body.file;
    if (!res.ok) {
      const d = res.data || {};
      const where = d.field ? ` (field ${d.field})` : '';
      this.toasts.show('error', `${op} ${what}: ${res.status ? `HTTP ${res.status}` : 'no answer'}`, `${d.error}${where}`);
      this.log.note('api', 'error', 'plugin', `${op} ${what}: ${d.error}${where}`);
    } else {
      const d = res.data || {};
      const text = op === 'reload'
        ? `generation ${d.previous_generation} → ${d.library ? d.library.generation : '?'}; ${staleCount(d.stale_instances)} instance(s) moved to the new build`
        : `${d.name || what} ${d.version || ''}`;
      this.toasts.show('ok', `${op} ${what}`, text);
      this.log.note('api', 'ok', 'plugin', `${op} ${what}: ${text}`);
    }
    this.poller.poke();
  }

  async refresh() {
    const res = await api.getPlugins();
    if (!res.ok) return res;
    const d = res.data || {};
    // Re-rendered only when something changed, so a button is never replaced under the pointer.
    const key = JSON.stringify(d);
    if (key === this.lastKey) return res;
    this.lastKey = key;
    this.root.querySelector('[data-field="dir"]').textContent = `plugin directory: ${d.plugin_dir || '(none)'}`;
    const rows = [];
    for (const lib of d.libraries || []) {
      const tr = document.createElement('tr');
      tr.dataset.plugin = lib.name;
      tr.dataset.status = lib.status;
      tr.title = `${lib.file}\n${lib.build_stamp || ''}\nABI ${lib.abi_version ?? '?'}`;
      const cells = [['name', lib.name], ['version', lib.version], ['generation', String(lib.generation)],
        ['status', lib.status], ['kinds', (lib.kinds || []).join(', ')]];
      for (const [k, v] of cells) {
        const td = document.createElement(k === 'name' ? 'th' : 'td');
        td.dataset.field = k;
        td.textContent = v ?? '–';
        tr.append(td);
      }
      const act = document.createElement('td');
      act.className = 'actions';
      if (lib.status !== 'superseded') {
        act.innerHTML = `<button type="button" class="btn tiny" data-plugin-op="reload">Reload</button>
          <button type="button" class="btn tiny" data-plugin-op="unload">Unload</button>`;
      }
      tr.append(act);
      rows.push(tr);
      const sub = document.createElement('tr');
      sub.className = 'instances';
      const td = document.createElement('td');
      td.colSpan = 6;
      const insts = lib.instances || [];
      td.textContent = insts.length
        ? insts.map((i) => `${i.vehicle_id}/${i.slot} · ${i.isolation}${i.pid ? ` pid ${i.pid}` : ''} · gen ${i.generation} · ${i.status}`).join('\n')
        : 'no instances';
      sub.append(td);
      rows.push(sub);
    }
    this.tbody.replaceChildren(...rows);
    this.root.querySelector('[data-field="providers"]').textContent =
      (d.providers || []).map((p) => `${p.name} ${p.version} (${p.source}): ${(p.kinds || []).join(', ')}`).join(' · ') || 'none';
    const refused = (d.refused || []).map((r) => {
      const li = document.createElement('li');
      const b = document.createElement('strong');
      b.textContent = r.file;
      const s = document.createElement('span');
      s.textContent = r.reason;
      li.append(b, s);
      return li;
    });
    if (!refused.length) {
      const li = document.createElement('li');
      li.className = 'muted';
      li.textContent = 'none';
      refused.push(li);
    }
    this.root.querySelector('[data-testid="plugin-refused"]').replaceChildren(...refused);
    const files = [...(d.libraries || []).map((l) => l.file), ...(d.refused || []).map((r) => r.file)]
      .map((f) => String(f).split('/').pop());
    this.root.querySelector('#plugin-files').replaceChildren(...[...new Set(files)].map((f) => new Option(f, f)));
    return res;
  }
}

const staleCount = (x) => (Array.isArray(x) ? x.length : Number.isFinite(x) ? x : 0);
