// The coordinator role (`skein coordinator`, see core/api/src/election.rs): when
// GET /api/v1/health names a `coordinator_role`, polls GET /api/v1/coordinator every
// second; in `skein up` (no role) nothing is shown and nothing polled. A
// candidate shows its role in the top bar; a standby also shows a banner naming the
// active coordinator, with a link to its dashboard, because its own API refuses every
// command (409) until it becomes active. The badge also says whether the swarm's DDS
// link is secured (DDS Security: `dds_security`), and its tooltip which enclave each
// remote vehicle's agent proved.

import * as api from './api.js';

const PERIOD_MS = 1000;

export function initRole(badge, banner) {
  const render = (s) => {
    const me = s.this || {};
    badge.hidden = false;
    badge.dataset.role = s.role;
    badge.dataset.epoch = String(me.epoch ?? '');
    const sec = s.dds_security;
    badge.dataset.dds = sec ? 'secured' : 'open';
    badge.textContent = (s.role === 'active'
      ? `coordinator ${me.coordinator_id} · active · epoch ${me.epoch}`
      : `coordinator ${me.coordinator_id} · standby`)
      + (sec ? ' · DDS secured' : ' · DDS open');
    badge.title = sec
      ? [`enclave ${sec.enclave}`].concat(Object.entries(sec.vehicles).map(([id, v]) =>
        `${id}: ${v.agent}, enclave ${v.enclave ?? `unknown (identity ${v.identity})`}`)).join('\n')
      : 'The swarm link is not secured: any host on its network can speak on it.';
    document.body.classList.toggle('standby', s.role !== 'active');
    if (s.role === 'active') {
      banner.hidden = true;
      return;
    }
    banner.hidden = false;
    banner.replaceChildren();
    const a = s.active;
    if (a) {
      banner.dataset.active = a.coordinator_id;
      banner.append(`Standby: commands go to coordinator ${a.coordinator_id} (priority ${a.priority}, epoch ${a.epoch}) at `);
      const link = document.createElement('a');
      link.href = `${a.api_url}/`;
      link.textContent = a.api_url;
      link.dataset.testid = 'coordinator-active-link';
      banner.append(link, '. This dashboard only watches.');
    } else {
      banner.dataset.active = '';
      banner.append('Standby: no coordinator is active yet (election in progress).');
    }
  };
  const poll = async () => {
    const r = await api.request('GET', '/coordinator');
    if (r.ok && r.data) render(r.data);
    setTimeout(poll, PERIOD_MS);
  };
  const start = async () => {
    const h = await api.getHealth();
    if (!h.ok) {
      setTimeout(start, PERIOD_MS); // not up yet, or a network error: ask again
      return;
    }
    if (h.data && h.data.coordinator_role) poll();
  };
  start();
}
