// HTTP API and WebSocket stream of skein v1 (see core/api/src/lib.rs).
// HTTP helpers never throw: they resolve to {ok, status, data}, where a network failure
// has status 0 and data {error}. The stream reconnects by itself with capped backoff.

const API = '/api/v1';

/** One JSON request. Resolves to {ok, status, data}. */
export async function request(method, path, body) {
  const init = { method, headers: { Accept: 'application/json' } };
  if (body !== undefined) {
    init.headers['Content-Type'] = 'application/json';
    init.body = JSON.stringify(body);
  }
  let res;
  try {
    res = await fetch(API + path, init);
  } catch (e) {
    return { ok: false, status: 0, data: { error: `network error: ${e.message || e}` } };
  }
  let data = null;
  const text = await res.text().catch(() => '');
  if (text) {
    try { data = JSON.parse(text); } catch { data = { error: text.slice(0, 200) }; }
  }
  if (!res.ok && (!data || typeof data.error !== 'string')) {
    data = { ...(data || {}), error: `HTTP ${res.status} ${res.statusText}`.trim() };
  }
  return { ok: res.ok, status: res.status, data };
}

export const swarmCommand = (body) => request('POST', '/swarm/commands', body);
export const vehicleCommand = (id, body) =>
  request('POST', `/vehicles/${encodeURIComponent(id)}/commands`, body);
export const getFormation = () => request('GET', '/formation');
export const putFormation = (spec) => request('PUT', '/formation', spec);
export const getShapes = () => request('GET', '/formation/shapes');
/** Leader motion: motion is `goto`, `waypoints`, `orbit` or `hold`. */
export const leaderMotion = (motion, body = {}) =>
  request('POST', `/formation/leader/${motion}`, body);

/** The stream URL, derived from the page's location (ws: or wss:). */
export function streamUrl(loc = window.location) {
  const scheme = loc.protocol === 'https:' ? 'wss:' : 'ws:';
  return `${scheme}//${loc.host}${API}/stream`;
}

/**
 * A self-reconnecting WebSocket.
 * handlers: onMessage(obj), onStatus(status, detail) with status one of
 * 'connecting' | 'connected' | 'reconnecting' (detail: delay ms).
 */
export class Stream {
  constructor(url, handlers) {
    this.url = url;
    this.h = handlers;
    this.ws = null;
    this.attempt = 0;
    this.timer = 0;
    this.lastMessage = 0;
    // A stream that sends nothing for this long is considered dead (frames come at 10 Hz).
    this.staleMs = 5000;
    this.watchdog = setInterval(() => this.checkStale(), 1000);
  }

  start() {
    clearTimeout(this.timer);
    this.h.onStatus('connecting');
    let ws;
    try {
      ws = new WebSocket(this.url);
    } catch (e) {
      this.scheduleReconnect();
      return;
    }
    this.ws = ws;
    ws.onopen = () => {
      this.attempt = 0;
      this.lastMessage = performance.now();
      this.h.onStatus('connected');
    };
    ws.onmessage = (ev) => {
      this.lastMessage = performance.now();
      let msg;
      try { msg = JSON.parse(ev.data); } catch { return; }
      if (msg && typeof msg === 'object') this.h.onMessage(msg);
    };
    ws.onclose = () => {
      if (this.ws !== ws) return;
      this.ws = null;
      this.scheduleReconnect();
    };
    // onerror is always followed by onclose; nothing to do here.
    ws.onerror = () => {};
  }

  scheduleReconnect() {
    // 0.5 s, 1 s, 2 s … capped at 8 s, with ±20 % jitter so many dashboards spread out.
    const base = Math.min(8000, 500 * 2 ** this.attempt);
    const delay = Math.round(base * (0.8 + 0.4 * Math.random()));
    this.attempt += 1;
    this.h.onStatus('reconnecting', delay);
    clearTimeout(this.timer);
    this.timer = setTimeout(() => this.start(), delay);
  }

  checkStale() {
    const ws = this.ws;
    if (ws && ws.readyState === WebSocket.OPEN && performance.now() - this.lastMessage > this.staleMs) {
      this.ws = null;
      ws.onclose = null;
      try { ws.close(); } catch { /* already closing */ }
      this.scheduleReconnect();
    }
  }
}
