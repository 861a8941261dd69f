// The side panel's tabs (Swarm, Mission, Vehicle, Payloads, Supervision, ...): one
// visible at a time; views ask `isOpen(name)` before polling or drawing, and get
// `onOpen(name)` callbacks. Test hooks: button[data-tab=NAME], section[data-view=NAME].

export class Tabs {
  constructor(bar, panes) {
    this.bar = bar;
    this.panes = panes;
    this.current = null;
    this.listeners = [];
    bar.addEventListener('click', (ev) => {
      const b = ev.target.closest('button[data-tab]');
      if (b) this.open(b.dataset.tab);
    });
    this.open(bar.querySelector('button[data-tab]').dataset.tab);
  }

  names() {
    return [...this.bar.querySelectorAll('button[data-tab]')].map((b) => b.dataset.tab);
  }

  open(name) {
    if (!this.names().includes(name)) return;
    this.current = name;
    for (const b of this.bar.querySelectorAll('button[data-tab]')) {
      const on = b.dataset.tab === name;
      b.classList.toggle('active', on);
      b.setAttribute('aria-selected', on ? 'true' : 'false');
    }
    for (const p of this.panes.querySelectorAll('[data-view]')) p.hidden = p.dataset.view !== name;
    for (const f of this.listeners) f(name);
  }

  isOpen(name) {
    return this.current === name && !document.hidden;
  }

  onOpen(f) {
    this.listeners.push(f);
  }
}
