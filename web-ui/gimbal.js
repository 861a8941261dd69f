// Gimbal payload card: its attitude drawn (pitch on a side view, yaw on a compass) and in
// numbers with the target, and the gimbal manager's commands: set pitch / yaw, point at a
// spot clicked on the plan (roi_location), track another vehicle (roi_vehicle), release
// the ROI, neutral. Test hooks: [data-field=pitch] / [data-field=yaw] (degrees, 1 decimal),
// [data-testid=gimbal-pitch], gimbal-set, gimbal-neutral, gimbal-point.

import { fmt } from './model.js';

export class GimbalCard {
  constructor(el, { vehicleId, send, plan, vehicleIds }) {
    this.id = vehicleId;
    this.send = send;
    this.plan = plan;
    this.vehicleIds = vehicleIds;
    el.innerHTML = `
      <div class="gimbal-view">
        <canvas class="gimbal-dial" width="180" height="84" aria-hidden="true"></canvas>
        <dl class="kv compact">
          <div><dt>pitch °</dt><dd data-field="pitch">–</dd></div>
          <div><dt>yaw ° (veh.)</dt><dd data-field="yaw">–</dd></div>
          <div><dt>yaw ° (north)</dt><dd data-field="yaw_abs">–</dd></div>
          <div><dt>target</dt><dd data-field="target">–</dd></div>
          <div><dt>mode</dt><dd data-field="mode">–</dd></div>
          <div><dt>roi</dt><dd data-field="roi">–</dd></div>
        </dl>
      </div>
      <form class="payload-ctl" autocomplete="off">
        <label>Pitch <input type="number" step="5" min="-90" max="30" value="-45" data-testid="gimbal-pitch"></label>
        <label>Yaw <input type="number" step="5" min="-180" max="180" value="0" data-testid="gimbal-yaw"></label>
        <button type="submit" class="btn tiny primary" data-testid="gimbal-set">Set</button>
        <button type="button" class="btn tiny" data-testid="gimbal-neutral" data-act="neutral">Neutral</button>
        <button type="button" class="btn tiny" data-testid="gimbal-point" data-act="point" title="Then click a spot on the plan">Point at…</button>
        <select data-testid="gimbal-track" aria-label="Track a vehicle"><option value="">track…</option></select>
        <button type="button" class="btn tiny" data-act="roi_none">ROI off</button>
      </form>`;
    this.el = el;
    this.dial = el.querySelector('canvas');
    this.track = el.querySelector('[data-testid="gimbal-track"]');
    const form = el.querySelector('form');
    form.addEventListener('submit', (ev) => {
      ev.preventDefault();
      const pitch = Number(el.querySelector('[data-testid="gimbal-pitch"]').value);
      const yaw = Number(el.querySelector('[data-testid="gimbal-yaw"]').value);
      this.send('set_angles', { command: 'set_angles', pitch_deg: pitch, yaw_deg: yaw, yaw_frame: 'vehicle' },
        ev.submitter);
    });
    form.addEventListener('click', async (ev) => {
      const b = ev.target.closest('button[data-act]');
      if (!b) return;
      if (b.dataset.act === 'point') {
        const p = await this.plan.pickPoint(`Point ${vehicleId}'s gimbal: click a spot on the plan (Esc cancels)`);
        if (!p) return;
        this.plan.setMark(`roi-${vehicleId}`, p.north_m, p.east_m, `${vehicleId} looks here`);
        this.send('roi_location', { command: 'roi_location', north_m: p.north_m, east_m: p.east_m, down_m: 0 }, b);
      } else {
        if (b.dataset.act === 'neutral' || b.dataset.act === 'roi_none') this.plan.clearMark(`roi-${vehicleId}`);
        this.send(b.dataset.act, { command: b.dataset.act }, b);
      }
    });
    this.track.addEventListener('change', () => {
      if (!this.track.value) return;
      this.plan.clearMark(`roi-${vehicleId}`);
      this.send('roi_vehicle', { command: 'roi_vehicle', vehicle: this.track.value });
      this.track.value = '';
    });
    this.trackKey = '';
  }

  update(p) {
    const s = p.state || {};
    const put = (k, t) => { const e = this.el.querySelector(`[data-field="${k}"]`); if (e.textContent !== t) e.textContent = t; };
    put('pitch', fmt(s.pitch_deg, 1));
    put('yaw', fmt(s.yaw_deg, 1));
    put('yaw_abs', fmt(s.yaw_absolute_deg, 1));
    put('target', s.target ? `${fmt(s.target.pitch_deg, 0)} / ${fmt(s.target.yaw_deg, 0)}` : '–');
    put('mode', String(s.mode ?? '–'));
    put('roi', s.roi ? (s.roi.vehicle ? `${s.roi.vehicle} ${fmt(s.roi.range_m, 0)} m` : `${fmt(s.roi.range_m, 0)} m`) : s.roi_error || '–');
    const others = this.vehicleIds().filter((x) => x !== this.id);
    const key = others.join(',');
    if (key !== this.trackKey) {
      this.trackKey = key;
      this.track.replaceChildren(new Option('track…', ''), ...others.map((x) => new Option(x, x)));
    }
    this.draw(s);
  }

  /** Side view (pitch, 0° = horizon, −90° = straight down) and top view (yaw in the vehicle frame). */
  draw(s) {
    const c = this.dial;
    const ctx = c.getContext('2d');
    ctx.clearRect(0, 0, c.width, c.height);
    const arm = 30;
    const dial = (cx, cy, angleRad, targetRad, label) => {
      ctx.strokeStyle = '#2c3847';
      ctx.lineWidth = 1;
      ctx.beginPath(); ctx.arc(cx, cy, arm, 0, Math.PI * 2); ctx.stroke();
      if (Number.isFinite(targetRad)) {
        ctx.strokeStyle = 'rgba(230,184,74,0.7)';
        ctx.setLineDash([3, 3]);
        ctx.beginPath(); ctx.moveTo(cx, cy); ctx.lineTo(cx + arm * Math.cos(targetRad), cy + arm * Math.sin(targetRad)); ctx.stroke();
        ctx.setLineDash([]);
      }
      if (Number.isFinite(angleRad)) {
        ctx.strokeStyle = '#4c9bff';
        ctx.lineWidth = 3;
        ctx.beginPath(); ctx.moveTo(cx, cy); ctx.lineTo(cx + arm * Math.cos(angleRad), cy + arm * Math.sin(angleRad)); ctx.stroke();
      }
      ctx.fillStyle = '#8893a5';
      ctx.font = '10px system-ui, sans-serif';
      ctx.textAlign = 'center';
      ctx.fillText(label, cx, cy + arm + 10);
    };
    const rad = (d) => (d * Math.PI) / 180;
    // Side view: forward is right, down is down (canvas y grows downwards).
    const t = s.target || {};
    dial(45, 38, Number.isFinite(s.pitch_deg) ? -rad(s.pitch_deg) : NaN,
      Number.isFinite(t.pitch_deg) ? -rad(t.pitch_deg) : NaN, 'pitch (side)');
    // Top view: the vehicle's nose is up.
    dial(135, 38, Number.isFinite(s.yaw_deg) ? rad(s.yaw_deg - 90) : NaN,
      Number.isFinite(t.yaw_deg) ? rad(t.yaw_deg - 90) : NaN, 'yaw (top)');
  }

  destroy() {}
}
