// Load indicator in the top bar: how late skein runs and what optional work it sheds
// (the `load` of every `vehicles` frame on the stream; see docs/architecture.md,
// "Running out of CPU"). Normal: a quiet "load ok". Shedding: the lag and what yields.

/** Shows `load` (the stream frame's `load` object, or null) in the element `el`. */
export function showLoad(el, load) {
  if (!el) return;
  if (!load) { el.hidden = true; return; }
  el.hidden = false;
  el.dataset.level = load.level;
  const lag = Math.round(load.lag_ms);
  el.textContent = load.level === 'shedding' ? `shedding · ${lag} ms late` : 'load ok';
  const shed = Object.entries(load.shed || {})
    .filter(([, n]) => n > 0)
    .map(([work, n]) => `${work} ${n}`)
    .join(', ');
  el.title = [
    `running ${lag} ms late (max ${Math.round(load.max_lag_ms)} ms in 30 s)`,
    `shed: ${shed || 'nothing'}`,
    `tick overruns: ${load.tick_overruns}`,
    `late watchdog answers forgiven: ${load.watchdog_late}`,
    `restarts held back: ${load.restarts_deferred}`,
  ].join('\n');
}
