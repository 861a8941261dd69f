// Shared vocabulary of the dashboard: vehicle state classes and colours, formatting,
// natural ordering of ids.

/** State → CSS class suffix; the classes carry the colours (style.css `.s-*`). */
const STATE_CLASS = {
  Disconnected: 'offline',
  Landed: 'landed',
  Armed: 'armed',
  TakingOff: 'airborne',
  Hovering: 'airborne',
  InFormation: 'formation',
  GoTo: 'moving',
  Landing: 'moving',
  ReturnToLaunch: 'moving',
  Failsafe: 'alert',
  Lost: 'alert',
};

/** Canvas colours per class (kept in step with the CSS custom properties). */
export const CLASS_COLOUR = {
  offline: '#5b6574',
  connecting: '#7fb0c9',
  landed: '#8d97a8',
  armed: '#e6b84a',
  airborne: '#4c9bff',
  formation: '#3ecf8e',
  moving: '#c792ff',
  alert: '#ff5566',
};

/** The display class of a vehicle: a lost link trumps its last known state. */
export function stateClass(v) {
  if (v.link && v.link.connected === false) return 'alert';
  if (isConnecting(v)) return 'connecting';
  return STATE_CLASS[v.state] || 'offline';
}

/**
 * True while the link is up but the vehicle's state machine has not left `Disconnected`
 * (the first second after it is heard, before it accepts `arm`).
 */
export function isConnecting(v) {
  return v.state === 'Disconnected' && !!(v.link && v.link.connected);
}

/** The state as shown to the operator: `connecting` for a link that is up but not ready. */
export function displayState(v) {
  return isConnecting(v) ? 'connecting' : String(v.state);
}

/** A stable colour per vehicle (for chart lines), from its position in the sorted list. */
const PALETTE = ['#4c9bff', '#3ecf8e', '#e6b84a', '#c792ff', '#ff8a5b', '#5bd1e6', '#ff5fa2', '#a3d65c'];
export const vehicleColour = (index) => PALETTE[index % PALETTE.length];

export const AIRBORNE = new Set(['TakingOff', 'Hovering', 'InFormation', 'GoTo', 'Landing', 'ReturnToLaunch', 'Failsafe']);

/** "uav-2" sorts before "uav-10". */
const collator = new Intl.Collator(undefined, { numeric: true, sensitivity: 'base' });
export const compareIds = (a, b) => collator.compare(a, b);

/** Number with fixed decimals, or an en dash when missing. */
export function fmt(x, digits = 1) {
  return typeof x === 'number' && Number.isFinite(x) ? x.toFixed(digits) : '–';
}

/** Milliseconds as a short human duration ("12 ms", "3.4 s", "2 min"). */
export function fmtAge(ms) {
  if (typeof ms !== 'number' || !Number.isFinite(ms)) return '–';
  if (ms < 1000) return `${Math.round(ms)} ms`;
  if (ms < 60000) return `${(ms / 1000).toFixed(1)} s`;
  return `${Math.round(ms / 60000)} min`;
}

/** Local wall-clock time, "14:03:22" (with ms = true: "14:03:22.417"). */
export function fmtTime(d, ms = false) {
  const p = (n, w = 2) => String(n).padStart(w, '0');
  const s = `${p(d.getHours())}:${p(d.getMinutes())}:${p(d.getSeconds())}`;
  return ms ? `${s}.${p(d.getMilliseconds(), 3)}` : s;
}

/** Ground speed from a NED velocity, m/s. */
export function groundSpeed(vel) {
  if (!vel) return NaN;
  return Math.hypot(vel.north_m_s || 0, vel.east_m_s || 0);
}

/** MAVLink's GPS_FIX_TYPE in words (GPS_RAW_INT.fix_type). */
export const FIX_NAMES = ['no GPS', 'no fix', '2D fix', '3D fix', 'DGPS', 'RTK float', 'RTK fixed', 'static', 'PPP'];

/** A vehicle's GNSS in one line: fix, satellites, accuracy and RTK corrections' age. */
export function gnssText(g) {
  if (!g) return '–';
  const fix = FIX_NAMES[g.fix_type] || `fix ${g.fix_type}`;
  const acc = Number.isFinite(g.eph_m) ? ` · ±${fmt(g.eph_m, g.eph_m < 0.1 ? 3 : 2)} m` : '';
  const age = Number.isFinite(g.correction_age_s) ? ` · corrections ${fmt(g.correction_age_s, 1)} s` : '';
  return `${fix} · ${g.satellites} sats${acc}${age}`;
}
