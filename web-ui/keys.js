// Keyboard shortcuts of the main commands, with a visible legend (the bar under the plan
// lists them; `?` opens the full list). Keys typed into a form field are left alone.
// Dangerous ones (land all, RTL all, force disarm) ask for confirmation first.

export const SHORTCUTS = [
  ['t', 'take off all'], ['h', 'hold all'], ['r', 'RTL all'], ['l', 'land all'],
  ['g', 'go-to (selected)'], ['f', 'fit swarm'], ['v', 'follow selected'], ['x', 'force disarm (selected)'],
  ['1–9', 'tabs'], ['Esc', 'cancel / deselect'], ['?', 'shortcuts'],
];

/** actions: {t, h, r, l, g, f, v, x, tab(i), escape} (functions). */
export function installShortcuts(actions, legend) {
  legend.innerHTML = SHORTCUTS.map(([k, what]) => `<span><kbd>${k}</kbd> ${what}</span>`).join('');
  document.addEventListener('keydown', (ev) => {
    if (ev.ctrlKey || ev.metaKey || ev.altKey) return;
    const t = ev.target;
    if (t && (t.isContentEditable || ['INPUT', 'SELECT', 'TEXTAREA'].includes(t.tagName))) {
      if (ev.key === 'Escape') t.blur();
      return;
    }
    if (document.querySelector('dialog[open]')) return;
    const k = ev.key;
    if (k === 'Escape') { actions.escape(); return; }
    if (k === '?') { legend.classList.toggle('expanded'); return; }
    if (/^[1-9]$/.test(k)) { actions.tab(Number(k) - 1); ev.preventDefault(); return; }
    const f = actions[k.toLowerCase()];
    if (f && k.length === 1) { ev.preventDefault(); f(); }
  });
}
