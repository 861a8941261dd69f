// Small time-series line charts drawn on a canvas (no library): a shared time axis over
// the last `windowS` seconds, an automatic value axis (optionally with fixed bounds), one
// line per series and a legend. The canvas is sized to its CSS box at the device pixel
// ratio on every draw, so charts stay sharp when panels resize.

const FONT = '10px system-ui, -apple-system, "Segoe UI", sans-serif';

/** A "nice" step (1, 2, 5 × 10^n) for about `n` ticks over `span`. */
function tickStep(span, n) {
  const raw = span / Math.max(1, n);
  const p = 10 ** Math.floor(Math.log10(raw));
  for (const m of [1, 2, 5, 10]) if (m * p >= raw) return m * p;
  return 10 * p;
}

/**
 * Draws `series` ([{label, colour, points: [[t_ms, v]]}]) on `canvas`.
 * opts: {windowS, now, min, max, unit, title, digits}.
 */
export function drawChart(canvas, series, opts = {}) {
  const dpr = window.devicePixelRatio || 1;
  const w = Math.max(1, canvas.clientWidth);
  const h = Math.max(1, canvas.clientHeight);
  if (canvas.width !== Math.round(w * dpr) || canvas.height !== Math.round(h * dpr)) {
    canvas.width = Math.round(w * dpr);
    canvas.height = Math.round(h * dpr);
  }
  const ctx = canvas.getContext('2d');
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  ctx.clearRect(0, 0, w, h);
  ctx.font = FONT;

  const now = opts.now ?? Date.now();
  const windowMs = (opts.windowS ?? 120) * 1000;
  const t0 = now - windowMs;
  let lo = Infinity, hi = -Infinity;
  for (const s of series) {
    for (const [t, v] of s.points) {
      if (t < t0) continue;
      lo = Math.min(lo, v); hi = Math.max(hi, v);
    }
  }
  if (opts.min !== undefined) lo = Math.min(opts.min, lo === Infinity ? opts.min : lo);
  if (opts.max !== undefined) hi = Math.max(opts.max, hi === -Infinity ? opts.max : hi);
  if (opts.fixedMin !== undefined) lo = opts.fixedMin;
  if (opts.fixedMax !== undefined) hi = opts.fixedMax;
  const empty = !(lo <= hi);
  if (empty) { lo = 0; hi = 1; }
  if (hi - lo < 1e-6) { hi += 0.5; lo -= 0.5; }
  const pad = (hi - lo) * 0.08;
  if (opts.fixedMax === undefined) hi += pad;
  if (opts.fixedMin === undefined && lo !== 0) lo -= pad;

  const L = 34, R = 6, T = opts.title ? 16 : 6, B = 14;
  const pw = w - L - R, ph = h - T - B;
  const X = (t) => L + ((t - t0) / windowMs) * pw;
  const Y = (v) => T + (1 - (v - lo) / (hi - lo)) * ph;

  // Frame, value ticks and time ticks.
  ctx.strokeStyle = 'rgba(140,160,190,0.12)';
  ctx.fillStyle = '#6f7a8c';
  ctx.lineWidth = 1;
  ctx.textAlign = 'right';
  ctx.textBaseline = 'middle';
  const step = tickStep(hi - lo, Math.max(2, Math.floor(ph / 22)));
  const digits = opts.digits ?? (step < 1 ? 1 : 0);
  ctx.beginPath();
  for (let v = Math.ceil(lo / step) * step; v <= hi + 1e-9; v += step) {
    const y = Math.round(Y(v)) + 0.5;
    ctx.moveTo(L, y); ctx.lineTo(w - R, y);
    ctx.fillText(v.toFixed(digits), L - 4, y);
  }
  ctx.stroke();
  ctx.textAlign = 'center';
  ctx.textBaseline = 'top';
  const tStep = windowMs > 180000 ? 60000 : windowMs > 60000 ? 30000 : 10000;
  for (let k = 0; k * tStep <= windowMs; k++) {
    const t = now - k * tStep;
    const x = X(t);
    if (x < L + 10) break;
    ctx.textAlign = k ? 'center' : 'right';
    ctx.fillText(k ? `-${Math.round((k * tStep) / 1000)}s` : 'now', k ? x : x + 2, h - B + 2);
  }
  if (opts.title) {
    ctx.textAlign = 'left';
    ctx.fillStyle = '#8893a5';
    ctx.fillText(opts.title + (opts.unit ? ` (${opts.unit})` : ''), L, 3);
  }

  // Lines.
  ctx.save();
  ctx.beginPath();
  ctx.rect(L, T, pw, ph);
  ctx.clip();
  ctx.lineWidth = 1.5;
  ctx.lineJoin = 'round';
  for (const s of series) {
    ctx.strokeStyle = s.colour;
    ctx.beginPath();
    let started = false;
    let prevT = 0;
    for (const [t, v] of s.points) {
      if (t < t0 - 2000) continue;
      const x = X(t), y = Y(v);
      // A gap of more than 3 s (stream down) breaks the line.
      if (!started || t - prevT > 3000) ctx.moveTo(x, y); else ctx.lineTo(x, y);
      started = true;
      prevT = t;
    }
    ctx.stroke();
  }
  ctx.restore();

  // Legend, top right.
  ctx.textAlign = 'right';
  ctx.textBaseline = 'top';
  let x = w - R;
  for (const s of [...series].reverse()) {
    if (!s.label) continue;
    const last = s.points.length ? s.points[s.points.length - 1][1] : NaN;
    const text = Number.isFinite(last) && opts.showLast ? `${s.label} ${last.toFixed(opts.lastDigits ?? 1)}` : s.label;
    ctx.fillStyle = s.colour;
    ctx.fillText(text, x, 3);
    x -= ctx.measureText(text).width + 10;
  }
  if (empty) {
    ctx.textAlign = 'center';
    ctx.textBaseline = 'middle';
    ctx.fillStyle = '#5f6a7b';
    ctx.fillText('no data yet', L + pw / 2, T + ph / 2);
  }
}
