// Camera payload card: the live MJPEG stream in an <img> (only while the card is shown;
// it reconnects with backoff when the stream ends, e.g. a skein restart) with what the
// camera reports seeing (`visible`: other aircraft in pixels) drawn over it, the pointing
// and optics, and zoom / capture controls.
// Test hooks: img[data-testid=camera-video], [data-field=frames] (data-frames), the
// widget's data-visible (ids of the aircraft in view), data-detections (boxes the
// vehicle's `detector` payload found in this camera's last processed frame), canvas.overlay,
// the widget's data-source-state (a real source's `source_status.state`: `streaming`,
// `stalled`, `connecting`, `failed`; the video is dimmed and marked while not streaming,
// so a stalled camera never passes for a frozen live image).

import * as api from './api.js';
import { fmt } from './model.js';

export class CameraCard {
  constructor(el, { vehicleId, slot, send }) {
    this.id = vehicleId;
    this.slot = slot;
    this.send = send;
    this.state = null;
    this.active = false;
    this.retry = 0;
    this.retryTimer = 0;
    el.innerHTML = `
      <div class="video"><img data-testid="camera-video" alt="live video of ${vehicleId} ${slot}">
        <canvas class="overlay" aria-hidden="true"></canvas><span class="video-status"></span></div>
      <div class="cam-info"><span data-field="frames">–</span><span data-field="pointing">–</span><span data-field="optics">–</span></div>
      <form class="payload-ctl" autocomplete="off">
        <label>Zoom <input type="range" min="1" max="12" step="0.5" value="1" data-field="zoom" aria-label="Zoom"></label>
        <button type="button" class="btn tiny" data-act="capture">Capture</button>
        <a class="btn tiny" target="_blank" rel="noopener" href="${api.payloadVideoUrl(vehicleId, slot, true)}">Snapshot</a>
      </form>`;
    this.el = el;
    this.img = el.querySelector('img');
    this.canvas = el.querySelector('canvas');
    this.status = el.querySelector('.video-status');
    this.img.addEventListener('load', () => { this.retry = 0; this.status.textContent = ''; });
    this.img.addEventListener('error', () => this.onError());
    // A broken stream does not always fire `error` (a multipart response cut short): a
    // watchdog reconnects an image that is complete but empty.
    this.watchdog = setInterval(() => {
      if (this.active && !this.retryTimer && this.img.getAttribute('src') && this.img.complete && !this.img.naturalWidth) {
        this.onError();
      }
    }, 2000);
    el.querySelector('[data-field="zoom"]').addEventListener('change', (ev) =>
      this.send('set_zoom', { command: 'set_zoom', zoom: Number(ev.target.value) }));
    el.querySelector('[data-act="capture"]').addEventListener('click', (ev) =>
      this.send('capture', { command: 'capture' }, ev.target));
    new ResizeObserver(() => this.drawOverlay()).observe(this.img);
  }

  /** Streams only while shown: an open MJPEG response costs the server a frame copy per client. */
  setActive(on) {
    if (on === this.active) return;
    this.active = on;
    clearTimeout(this.retryTimer);
    this.retryTimer = 0;
    if (on) this.connect();
    else this.img.removeAttribute('src');
  }

  /** Opens a new stream now (after the dashboard reconnected to a restarted skein). */
  reconnect() {
    if (!this.active) return;
    clearTimeout(this.retryTimer);
    this.retryTimer = 0;
    this.retry = 0;
    this.connect();
  }

  connect() {
    this.retryTimer = 0;
    if (!this.active) return;
    this.status.textContent = 'connecting…';
    // A fresh URL each time, so the browser opens a new stream instead of reusing a dead one.
    const url = api.payloadVideoUrl(this.id, this.slot);
    this.img.src = `${url}${url.includes('?') ? '&' : '?'}t=${Date.now()}`;
  }

  onError() {
    if (!this.active) return;
    this.img.removeAttribute('src');
    const delay = Math.min(10000, 500 * 2 ** this.retry++);
    this.status.textContent = `no video; retrying in ${(delay / 1000).toFixed(1)} s`;
    this.retryTimer = setTimeout(() => this.connect(), delay);
  }

  update(p, v) {
    const s = p.state || {};
    this.state = s;
    // The detector that reads this camera (same vehicle): its boxes are drawn over the video.
    const det = ((v && v.payloads) || []).find((x) => x.kind === 'detector' && x.state && x.state.camera_slot === this.slot);
    this.detections = (det && det.state.last && det.state.last.detections) || [];
    const nDet = String(this.detections.length);
    if (this.el.dataset.detections !== nDet) this.el.dataset.detections = nDet;
    const put = (k, t) => { const e = this.el.querySelector(`[data-field="${k}"]`); if (e.textContent !== t) e.textContent = t; };
    const frames = s.frames ?? p.frames;
    put('frames', `frame ${frames ?? '–'} · ${fmt(s.frame_rate_hz, 0)} Hz · ${s.width_px ?? '?'}×${s.height_px ?? '?'}`);
    this.el.querySelector('[data-field="frames"]').dataset.frames = String(frames ?? '');
    const pt = s.pointing;
    put('pointing', pt ? `az ${fmt(pt.azimuth_deg, 0)}° el ${fmt(pt.elevation_deg, 0)}° (${pt.from || '?'})` : 'pointing –');
    const src = s.source_status;
    put('optics', `zoom ${fmt(s.zoom, 1)}× · fov ${fmt(s.horizontal_fov_deg, 0)}°` +
      (src ? ` · ${s.source} ${src.transport} · ${fmt(src.stream_rate_hz, 0)} fps · ${fmt(s.viewer_kbit_s, 0)} kbit/s per viewer` : ''));
    const srcState = src ? src.state : 'simulated';
    if (this.el.dataset.sourceState !== srcState) {
      this.el.dataset.sourceState = srcState;
      this.el.classList.toggle('source-down', srcState !== 'streaming' && srcState !== 'simulated');
    }
    const zoom = this.el.querySelector('[data-field="zoom"]');
    if (document.activeElement !== zoom && Number.isFinite(s.zoom)) zoom.value = String(s.zoom);
    if (src && src.state !== 'streaming') {
      this.status.textContent = `camera ${src.state.toUpperCase()}: ${src.detail || 'no frame yet'}`;
    } else if (s.last_error) this.status.textContent = `camera: ${s.last_error}`;
    else if (this.status.textContent.startsWith('camera')) this.status.textContent = '';
    const seen = (s.visible || []).map((o) => o.id).join(',');
    if (this.el.dataset.visible !== seen) this.el.dataset.visible = seen;
    this.drawOverlay();
  }

  /** What the camera reports it sees, scaled from its pixels to the shown image. */
  drawOverlay() {
    const s = this.state;
    const w = this.img.clientWidth, h = this.img.clientHeight;
    const dpr = window.devicePixelRatio || 1;
    if (this.canvas.width !== Math.round(w * dpr) || this.canvas.height !== Math.round(h * dpr)) {
      this.canvas.width = Math.round(w * dpr);
      this.canvas.height = Math.round(h * dpr);
    }
    const ctx = this.canvas.getContext('2d');
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.clearRect(0, 0, w, h);
    if (!s || !s.width_px || !s.height_px || !w) return;
    const kx = w / s.width_px, ky = h / s.height_px;
    ctx.font = '11px system-ui, sans-serif';
    ctx.lineWidth = 1.5;
    for (const o of s.visible || []) {
      const x = o.x_px * kx, y = o.y_px * ky;
      const r = Math.max(8, (o.radius_px || 0) * kx + 6);
      ctx.strokeStyle = '#3ecf8e';
      ctx.strokeRect(x - r, y - r, 2 * r, 2 * r);
      ctx.fillStyle = 'rgba(8,11,16,0.7)';
      const label = `${o.id} ${fmt(o.depth_m, 0)} m`;
      ctx.fillRect(x - r, y - r - 15, ctx.measureText(label).width + 6, 14);
      ctx.fillStyle = '#3ecf8e';
      ctx.fillText(label, x - r + 3, y - r - 4);
    }
    // The detector's boxes (camera pixels): what image processing found, not the truth.
    ctx.strokeStyle = '#ff8a5b';
    for (const d of this.detections || []) {
      const b = d.box_px;
      if (!b) continue;
      const pad = 3;
      ctx.strokeRect(b.x * kx - pad, b.y * ky - pad, b.width * kx + 2 * pad, b.height * ky + 2 * pad);
      ctx.fillStyle = '#ff8a5b';
      ctx.fillText(`${fmt((d.confidence ?? 0) * 100, 0)} % · az ${fmt(d.azimuth_deg, 0)}°`, b.x * kx - pad, (b.y + b.height) * ky + pad + 11);
    }
    // Centre reticle.
    ctx.strokeStyle = 'rgba(255,255,255,0.5)';
    ctx.beginPath();
    ctx.moveTo(w / 2 - 10, h / 2); ctx.lineTo(w / 2 + 10, h / 2);
    ctx.moveTo(w / 2, h / 2 - 10); ctx.lineTo(w / 2, h / 2 + 10);
    ctx.stroke();
  }

  destroy() {
    this.setActive(false);
    clearInterval(this.watchdog);
  }
}
