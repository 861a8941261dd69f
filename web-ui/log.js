// Event log: every stream event plus the dashboard's own notes (HTTP outcomes, link to
// the server), newest first, capped. Entries are batched into one DOM update per frame.
// Test hook: <li data-type="state_changed"> etc.

import { fmtTime } from './model.js';

const CAP = 500;
const SEVERITY = ['emergency', 'alert', 'critical', 'error', 'warning', 'notice', 'info', 'debug'];

/** Turns a stream event into {level, label, text}; level is info | ok | warn | error. */
export function describe(ev) {
  switch (ev.type) {
    case 'vehicle_joined':
      return { level: 'ok', label: 'joined', text: `${ev.id} joined (sysid ${ev.sysid}, ${ev.connection})` };
    case 'state_changed':
      return {
        level: ev.to === 'Failsafe' || ev.to === 'Lost' ? 'error' : 'info',
        label: 'state',
        text: `${ev.id}: ${ev.from} → ${ev.to}`,
      };
    case 'command_result':
      return ev.ok
        ? { level: 'ok', label: 'command', text: `${ev.id}: ${ev.command} done (#${ev.command_id})` }
        : { level: 'error', label: 'command', text: `${ev.id}: ${ev.command} failed (#${ev.command_id}): ${ev.error || 'no reason given'}` };
    case 'status_text': {
      const sev = SEVERITY[ev.severity] || `severity ${ev.severity}`;
      const level = ev.severity <= 3 ? 'error' : ev.severity === 4 ? 'warn' : 'info';
      return { level, label: 'px4', text: `${ev.id} [${sev}] ${ev.text}` };
    }
    case 'link_lost':
      return { level: 'error', label: 'link', text: `${ev.id}: link lost` };
    case 'link_restored':
      return { level: 'ok', label: 'link', text: `${ev.id}: link restored` };
    case 'rebooted':
      return { level: 'warn', label: 'reboot', text: `${ev.id}: autopilot rebooted` };
    case 'formation_changed':
      return { level: 'info', label: 'formation', text: describeFormation(ev.formation) };
    case 'geofence_clamp':
      return { level: 'warn', label: 'geofence', text: `${ev.id}: setpoint clamped (${ev.violation})` };
    case 'geofence_changed':
      return { level: 'ok', label: 'geofence', text: `geofence version ${ev.version} in force on every vehicle` };
    case 'geofence_breach':
      return ev.breached
        ? { level: 'error', label: 'geofence', text: `${ev.id} is outside the geofence at N ${ev.position[0].toFixed(1)} E ${ev.position[1].toFixed(1)}, ${ev.position[2].toFixed(1)} m up` }
        : { level: 'ok', label: 'geofence', text: `${ev.id} is back inside the geofence` };
    case 'fence_sync':
      return {
        level: ev.state === 'synced' ? 'ok' : ev.state === 'pending' ? 'info' : 'error',
        label: 'fence',
        text: `${ev.id}: autopilot fence ${ev.state} (version ${ev.version})${ev.reason ? `: ${ev.reason}` : ''}`,
      };
    case 'actor_restarted':
      return { level: 'warn', label: 'restart', text: `${ev.path} restarted (${ev.restarts}×, in ${(ev.latency_us / 1000).toFixed(1)} ms): ${ev.reason}` };
    case 'actor_failed':
      return {
        level: ev.escalated ? 'error' : 'warn',
        label: 'failure',
        text: `${ev.path} (${ev.kind}) failed: ${ev.reason}; ${ev.escalated ? 'restart budget spent: escalating' : ev.next_backoff_ms != null ? `restart in ${ev.next_backoff_ms} ms` : 'not restarted'}`,
      };
    case 'actor_escalated':
      return { level: 'error', label: 'escalation', text: `${ev.path}: ${ev.action}` };
    case 'coordinator_role_changed':
      return ev.role === 'active'
        ? { level: 'ok', label: 'coordinator', text: `${ev.coordinator_id} is the active coordinator (epoch ${ev.epoch})` }
        : { level: 'warn', label: 'coordinator', text: `${ev.coordinator_id} stands by: ${ev.reason || ''}` };
    case 'leader_changed':
      return { level: 'warn', label: 'leader', text: `leader ${ev.from || 'none'} → ${ev.to}: ${ev.reason}` };
    case 'hazard_added':
      return { level: 'error', label: 'hazard', text: `${ev.id} is a hazard (${ev.reason}) at N ${ev.position.north_m.toFixed(1)} E ${ev.position.east_m.toFixed(1)}: the formation plans around it` };
    case 'hazard_cleared':
      return { level: 'ok', label: 'hazard', text: `${ev.id} no longer a hazard: ${ev.reason}` };
    case 'formation_replanned':
      return { level: 'warn', label: 'formation', text: `planned again: ${ev.reason}` };
    case 'formation_blocked':
      return ev.reason
        ? { level: 'error', label: 'formation', text: `blocked: ${ev.reason}` }
        : { level: 'ok', label: 'formation', text: 'no longer blocked by hazards' };
    case 'payload_event':
      return { level: 'info', label: 'payload', text: `${ev.id}/${ev.slot} ${ev.kind}: ${JSON.stringify(ev.data)}` };
    case 'swarm_detected':
      return { level: 'warn', label: 'swarm', text: `hostile ${ev.swarm.id}: ${ev.swarm.shape} of ${ev.swarm.members.length} (${ev.swarm.members.join(', ')}) at ${ev.swarm.speed_m_s.toFixed(1)} m/s → ${ev.swarm.course_deg.toFixed(0)}°` };
    case 'swarm_changed': {
      const who = [...ev.joined.map((t) => `+${t}`), ...ev.left.map((t) => `−${t}`)].join(' ');
      return { level: 'info', label: 'swarm', text: `${ev.swarm.id}: ${ev.swarm.shape} of ${ev.swarm.members.length}${who ? ` (${who})` : ''}` };
    }
    case 'swarm_lost':
      return { level: 'info', label: 'swarm', text: `${ev.swarm.id} lost` };
    case 'mission_started':
      return { level: 'ok', label: 'mission', text: `${ev.id} started` };
    case 'mission_step':
      return {
        level: ev.state === 'aborted' ? 'warn' : ev.state === 'done' ? 'ok' : 'info',
        label: 'mission',
        text: ev.state === 'running' ? `${ev.id}: step ${ev.step + 1}` : `${ev.id} ${ev.state} (step ${ev.step + 1})`,
      };
    case 'mission_controlled':
      return { level: ev.action === 'abort' ? 'warn' : 'info', label: 'mission', text: `${ev.id}: ${ev.action}` };
    case 'events_dropped':
      return { level: 'warn', label: 'stream', text: `${ev.count} events dropped (dashboard too slow)` };
    default: {
      const { type, ...rest } = ev;
      return { level: 'info', label: String(type || 'event'), text: JSON.stringify(rest) };
    }
  }
}

/** One line for a FormationStatus. */
export function describeFormation(f) {
  if (!f || !f.shape) return 'no formation';
  const parts = [`${f.shape} ${f.spacing_m} m`];
  if (f.heading_deg) parts.push(`heading ${f.heading_deg}°`);
  if (f.altitude_m != null) parts.push(`alt ${f.altitude_m} m`);
  if (f.leader_id) parts.push(`leader ${f.leader_id}`);
  parts.push(f.active ? `active, ${(f.members || []).length} members` : 'inactive');
  return parts.join(', ');
}

export class EventLog {
  constructor(list, filterInput, clearButton) {
    this.list = list;
    this.pending = [];
    this.raf = 0;
    this.filter = '';
    filterInput.addEventListener('input', () => {
      this.filter = filterInput.value.trim().toLowerCase();
      for (const li of this.list.children) this.applyFilter(li);
    });
    clearButton.addEventListener('click', () => this.list.replaceChildren());
  }

  /** A stream event. */
  event(ev) {
    const d = describe(ev);
    this.push(ev.type || 'event', d.level, d.label, d.text);
  }

  /** A note of the dashboard itself (type: "api", "stream" …). */
  note(type, level, label, text) {
    this.push(type, level, label, text);
  }

  push(type, level, label, text) {
    this.pending.push({ when: new Date(), type, level, label, text });
    if (this.pending.length > CAP) this.pending.splice(0, this.pending.length - CAP);
    if (!this.raf) this.raf = requestAnimationFrame(() => this.flush());
  }

  flush() {
    this.raf = 0;
    const frag = document.createDocumentFragment();
    // Newest first: the last pending entry goes on top.
    for (let i = this.pending.length - 1; i >= 0; i--) {
      const e = this.pending[i];
      const li = document.createElement('li');
      li.className = `lvl-${e.level}`;
      li.dataset.type = e.type;
      const time = document.createElement('time');
      time.dateTime = e.when.toISOString();
      time.textContent = fmtTime(e.when);
      time.title = fmtTime(e.when, true);
      const tag = document.createElement('span');
      tag.className = 'tag';
      tag.textContent = e.label;
      const msg = document.createElement('span');
      msg.className = 'msg';
      msg.textContent = e.text;
      li.append(time, tag, msg);
      this.applyFilter(li);
      frag.append(li);
    }
    this.pending = [];
    this.list.prepend(frag);
    while (this.list.childElementCount > CAP) this.list.lastElementChild.remove();
  }

  applyFilter(li) {
    li.hidden = !!this.filter && !li.textContent.toLowerCase().includes(this.filter);
  }
}
