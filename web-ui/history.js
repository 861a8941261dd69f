// Client-side history of the stream, for the charts and the vehicle detail: per vehicle
// altitude, speed and battery samples, FSM state transitions and PX4 status texts; for the
// swarm the formation RMS error and the smallest separation. Everything is kept for the
// last WINDOW_S seconds (transitions and texts: the last CAP_EVENTS of each vehicle).

import { AIRBORNE, groundSpeed } from './model.js';

export const WINDOW_S = 300;
const SAMPLE_MS = 500; // at most two samples a second per series
const CAP_EVENTS = 60;
const MISMATCH_MS = 1200;

/** A time series of [t_ms, value] trimmed to the window. */
export class Series {
  constructor() { this.points = []; }

  push(t, v) {
    if (!Number.isFinite(v)) return;
    this.points.push([t, v]);
    const cutoff = t - WINDOW_S * 1000;
    let drop = 0;
    while (drop < this.points.length && this.points[drop][0] < cutoff) drop++;
    if (drop) this.points.splice(0, drop);
  }

  last() { return this.points.length ? this.points[this.points.length - 1][1] : NaN; }
}

class VehicleHistory {
  constructor() {
    this.altitude = new Series();
    this.speed = new Series();
    this.battery = new Series();
    this.loss = new Series();     // radio payload: loss %
    this.latency = new Series();  // radio payload: latency ms
    this.states = [];             // [{t, from, to}] newest last
    this.texts = [];              // [{t, severity, text}]
    this.lastState = null;
    this.mismatchSince = 0;
    this.lastSample = 0;
  }
}

export class History {
  constructor() {
    this.vehicles = new Map();
    this.rms = new Series();
    this.minSep = new Series();
    this.lastSwarmSample = 0;
  }

  of(id) {
    let h = this.vehicles.get(id);
    if (!h) { h = new VehicleHistory(); this.vehicles.set(id, h); }
    return h;
  }

  /**
   * A `vehicles` frame of the stream, with its formation summary `form` (whose
   * `rms_error_m` counts absent members too: see `GET /api/v1/formation`).
   */
  onVehicles(list, form = null, now = Date.now()) {
    const airborne = [];
    let sq = 0, nErr = 0;
    for (const v of list) {
      const h = this.of(v.id);
      // The history comes from the state_changed events. Frames and events travel on
      // separate channels, so a frame may lag an event: a frame only adds the first state
      // seen, or a state it has shown for over a second without an event (one dropped).
      if (h.lastState === null) {
        this.addState(h, now, null, v.state);
      } else if (h.lastState !== v.state) {
        if (!h.mismatchSince) h.mismatchSince = now;
        else if (now - h.mismatchSince > MISMATCH_MS) this.addState(h, now, h.lastState, v.state);
      } else {
        h.mismatchSince = 0;
      }
      if (now - h.lastSample >= SAMPLE_MS) {
        h.lastSample = now;
        if (v.position) h.altitude.push(now, v.position.relative_alt_m);
        h.speed.push(now, groundSpeed(v.velocity));
        if (v.battery) h.battery.push(now, v.battery.percent);
        for (const p of v.payloads || []) {
          if (p.kind === 'radio' && p.state) {
            h.loss.push(now, p.state.loss_percent);
            h.latency.push(now, p.state.latency_ms);
          }
        }
      }
      if (AIRBORNE.has(v.state) && v.position) airborne.push(v.position);
      if (v.formation && Number.isFinite(v.formation.error_m)) { sq += v.formation.error_m ** 2; nErr++; }
    }
    for (const id of this.vehicles.keys()) {
      if (!list.some((v) => v.id === id)) this.vehicles.delete(id);
    }
    let minSep = Infinity;
    for (let i = 0; i < airborne.length; i++) {
      for (let j = i + 1; j < airborne.length; j++) {
        const a = airborne[i], b = airborne[j];
        minSep = Math.min(minSep, Math.hypot(a.north_m - b.north_m, a.east_m - b.east_m, a.down_m - b.down_m));
      }
    }
    let rms = nErr ? Math.sqrt(sq / nErr) : NaN;
    if (form && form.active) rms = Number.isFinite(form.rms_error_m) ? form.rms_error_m : NaN;
    const swarm = { rms, minSep };
    if (now - this.lastSwarmSample >= SAMPLE_MS) {
      this.lastSwarmSample = now;
      this.rms.push(now, swarm.rms);
      this.minSep.push(now, minSep);
    }
    return swarm;
  }

  addState(h, t, from, to) {
    h.lastState = to;
    h.mismatchSince = 0;
    h.states.push({ t, from, to });
    if (h.states.length > CAP_EVENTS) h.states.shift();
  }

  /** A stream event. */
  onEvent(ev, now = Date.now()) {
    if (ev.type === 'state_changed' && ev.id) {
      const h = this.of(ev.id);
      if (h.lastState !== ev.to) this.addState(h, now, ev.from, ev.to);
    } else if (ev.type === 'status_text' && ev.id) {
      const h = this.of(ev.id);
      h.texts.push({ t: now, severity: ev.severity, text: ev.text });
      if (h.texts.length > CAP_EVENTS) h.texts.shift();
    }
  }
}
