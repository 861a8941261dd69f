// HTTP API and WebSocket stream of skein v1 (see core/api/src/lib.rs).
// HTTP helpers never throw: they resolve to {ok, status, data}, where a network failure
// has status 0 and data {error}. The stream reconnects by itself with capped backoff.

const API = '/api/v1';

// The API token of this tab (see auth.js): sent as `Authorization: Bearer` on requests
// and as `?token=` where a browser cannot set headers (the WebSocket, <img> video).
const TOKEN_KEY = 'skein.token';
export const getToken = () => { try { return sessionStorage.getItem(TOKEN_KEY); } catch { return null; } };
export const setToken = (t) => sessionStorage.setItem(TOKEN_KEY, t);
export const clearToken = () => sessionStorage.removeItem(TOKEN_KEY);
/** `url` with `?token=` (or `&token=`) when logged in. */
export function withToken(url) {
  const t = getToken();
  return t ? `${url}${url.includes('?') ? '&' : '?'}token=${encodeURIComponent(t)}` : url;
}
/** Called with the error body when the API answers 401 (auth.js shows the login). */
export const auth = { onUnauthorized: null };

/** One JSON request. Resolves to {ok, status, data}. */
export async function request(method, path, body) {
  const init = { method, headers: { Accept: 'application/json' } };
  const token = getToken();
  if (token) init.headers.Authorization = `Bearer ${token}`;
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
  if (res.status === 401 && auth.onUnauthorized) auth.onUnauthorized(data);
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
  return withToken(`${scheme}//${loc.host}${API}/stream`);
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

// Per-vehicle detail, payloads, supervision and plugins.
const enc = encodeURIComponent;
export const getHealth = () => request('GET', '/health');
export const getLinks = () => request('GET', '/links');
export const getGeofence = () => request('GET', '/geofence');
export const putGeofence = (fence) => request('PUT', '/geofence', fence);
export const getMap = () => request('GET', '/map');
export const getParams = (id) => request('GET', `/vehicles/${enc(id)}/params`);
export const getParam = (id, name) => request('GET', `/vehicles/${enc(id)}/params/${enc(name)}`);
export const putParam = (id, name, value) =>
  request('PUT', `/vehicles/${enc(id)}/params/${enc(name)}`, { value });
export const payloadCommand = (id, slot, body) =>
  request('POST', `/vehicles/${enc(id)}/payloads/${enc(slot)}`, body);
/** URL of a payload's MJPEG stream (or its last frame with snapshot = true). */
export const payloadVideoUrl = (id, slot, snapshot = false) =>
  withToken(`${API}/vehicles/${enc(id)}/payloads/${enc(slot)}/${snapshot ? 'snapshot' : 'stream'}`);
export const getSupervision = () => request('GET', '/supervision');
export const getPreflight = () => request('GET', '/preflight');
export const getLogDownloads = () => request('GET', '/logs');
export const getRtk = () => request('GET', '/rtk');
/** config: {source, max_bytes_s?, stall_timeout_s?, send_gga?}. */
export const putRtk = (config) => request('PUT', '/rtk', config);
export const stopRtk = () => request('DELETE', '/rtk');
export const fetchLatestLogs = () => request('POST', '/logs/fetch_latest');
export const injectFault = (target, kind) => request('POST', '/faults', { target, kind });
export const getPlugins = () => request('GET', '/plugins');
/** op: load ({file}) | unload ({name}) | reload ({name}). */
export const pluginOp = (op, body) => request('POST', `/plugins/${op}`, body);

/**
 * Calls `task` (async, resolves to a {ok} result) every `periodMs` while `active()` is
 * true. Failures back off (doubling, up to 10 s) and recover by themselves, so a skein
 * restart does not flood it. `poke()` runs it at once.
 */
export class Poller {
  constructor(task, periodMs, active = () => true) {
    this.task = task;
    this.period = periodMs;
    this.active = active;
    this.failures = 0;
    this.timer = 0;
    this.running = false;
    this.schedule(0);
  }

  schedule(ms) {
    clearTimeout(this.timer);
    this.timer = setTimeout(() => this.run(), ms);
  }

  poke() {
    this.schedule(0);
  }

  async run() {
    if (this.running) return;
    if (!this.active()) {
      this.schedule(this.period);
      return;
    }
    this.running = true;
    let ok = false;
    try {
      const res = await this.task();
      ok = !res || res.ok !== false;
    } catch (e) {
      console.warn('poll task failed', e); // eslint-disable-line no-console
    } finally {
      this.running = false;
    }
    this.failures = ok ? 0 : this.failures + 1;
    const delay = ok ? this.period : Math.min(10000, this.period * 2 ** this.failures);
    this.schedule(delay);
  }
}
