// skein ground station: wires the stream to the plan view (and the map under it), the
// vehicle table, the event log, the header summary and the side panel's views (swarm
// controls, the geofence, missions, vehicle detail, payloads, supervision, plugins,
// charts, tracks, pre-flight), and the controls to the HTTP API.

import * as api from './api.js';
import { initAuth } from './auth.js';
import { initRole } from './role.js';
import { PlanView } from './plan.js';
import { VehicleTable } from './table.js';
import { EventLog, describeFormation } from './log.js';
import { Toasts } from './toast.js';
import { Controls } from './controls.js';
import { AIRBORNE, fmt } from './model.js';
import { History } from './history.js';
import { Tabs } from './tabs.js';
import { VehicleDetail } from './detail.js';
import { PayloadsView } from './payloads.js';
import { SupervisionView } from './supervision.js';
import { PreflightView } from './preflight.js';
import { showLoad } from './load.js';
import { PluginsView } from './plugins.js';
import { ChartsView } from './charts.js';
import { TracksView } from './tracks.js';
import { installShortcuts } from './keys.js';
import { MapLayer } from './plan-map.js';
import { FencePanel } from './fence.js';
import { MissionView } from './mission.js';

const $ = (id) => document.getElementById(id);

initAuth();
initRole($('coordinator-role'), $('standby-banner'));

const toasts = new Toasts($('toasts'));
const log = new EventLog($('event-log'), $('log-filter'), $('log-clear'));
const controls = new Controls({ toasts, log });

const history = new History();
const tabs = new Tabs($('tabs'), $('views'));
// Vehicle id → its MAVLink connection (from vehicle_joined), to pick its link counters.
const connections = new Map();

let selected = null;
let lastVehicles = [];
const select = (id) => {
  selected = id;
  plan.setSelected(id);
  table.setSelected(id);
  detail.setVehicle(id);
  if (id) payloads.setVehicle(id);
  // A vehicle picked on the plan or in the table opens its detail (the payloads stay
  // open when they are what the operator is looking at).
  if (id && tabs.current !== 'payloads') tabs.open('vehicle');
  $('plan-follow').disabled = !id;
};
const plan = new PlanView($('plan'), $('plan-markers'), $('plan-empty'), { onSelect: select });
plan.setMapLayer(new MapLayer($('plan-map'), $('map-attribution'), () => plan.kick()));
const fencePanel = new FencePanel({ plan, toasts, log });
// The swarm origin (where the map and the cursor's latitude / longitude hang from): asked
// on (re)connection and, until the first vehicle anchors it, while vehicles report.
let originAsked = 0;
function askOrigin() {
  originAsked = performance.now();
  api.getHealth().then((res) => { if (res.ok && res.data.swarm_origin) plan.setOrigin(res.data.swarm_origin); });
}
const deps = { controls, toasts, log, history, plan, tabs };
const detail = new VehicleDetail($('view-vehicle'), {
  ...deps,
  connectionOf: (id) => {
    const v = lastVehicles.find((x) => x.id === id);
    return (v && v.connection) || connections.get(id) || null;
  },
});
const payloads = new PayloadsView($('view-payloads'), deps);
const supervision = new SupervisionView($('view-supervision'), deps);
new PluginsView($('view-plugins'), deps);
new ChartsView($('view-charts'), deps);
new TracksView($('view-tracks'), deps);
const missions = new MissionView($('view-mission'), deps);
new PreflightView($('view-preflight'), { ...deps, vehicles: () => lastVehicles });
const table = new VehicleTable($('vehicle-rows'), $('table-empty'), {
  onCommand: (id, command, button) => controls.vehicleCommand(id, command, button),
  onSelect: select,
});

let formation = null;
const setFormation = (f) => {
  formation = f;
  plan.setFormation(f);
  const lead = f && f.leader_id ? ` · leader ${f.leader_id}` : '';
  $('sum-formation-desc').textContent = f && f.shape ? (f.active ? `${f.shape} ${f.spacing_m} m${lead}` : `${f.shape} (inactive)`) : 'none';
  $('sum-formation-desc').title = describeFormation(f);
};
controls.onFormation = setFormation;

// Header summary from a vehicles frame: `swarm` is the history's `{rms, minSep}` of that
// frame, `form` the frame's formation summary (its rms error counts the members that
// dropped out unasked, which the vehicles' own slot errors cannot show).
function summarise(vehicles, swarm, form) {
  let connected = 0, airborne = 0, inForm = 0;
  for (const v of vehicles) {
    if (v.link && v.link.connected) connected++;
    if (AIRBORNE.has(v.state)) airborne++;
    if (v.state === 'InFormation') inForm++;
  }
  const put = (id, text) => { const el = $(id); if (el.textContent !== text) el.textContent = text; };
  put('sum-total', String(vehicles.length));
  put('sum-connected', String(connected));
  put('sum-airborne', String(airborne));
  put('sum-formation', String(inForm));
  const absent = form && form.active && Array.isArray(form.absent) ? form.absent : [];
  let rms = Number.isFinite(swarm.rms) ? `${fmt(swarm.rms, 2)} m` : '–';
  if (absent.length) rms += ` · ${absent.length} absent`;
  put('sum-rms', rms);
  const rmsEl = $('sum-rms');
  const why = absent.map((a) => `${a.id} ${a.absence}${Number.isFinite(a.error_m) ? ` ${fmt(a.error_m, 1)} m off slot ${a.slot}` : ''}`).join('\n');
  if (rmsEl.title !== why) rmsEl.title = why;
  const ids = absent.map((a) => a.id).join(',');
  if (rmsEl.dataset.absent !== ids) rmsEl.dataset.absent = ids;
  put('sum-sep', Number.isFinite(swarm.minSep) ? `${fmt(swarm.minSep, 1)} m` : '–');
}

function onVehicles(vehicles, form) {
  if (!Array.isArray(vehicles)) return;
  lastVehicles = vehicles;
  const swarm = history.onVehicles(vehicles, form);
  detail.update(vehicles);
  payloads.update(vehicles);
  table.update(vehicles);
  plan.setVehicles(vehicles);
  controls.setVehicleIds(vehicles.map((v) => v.id));
  controls.setVehicles(vehicles);
  summarise(vehicles, swarm, form);
  if (selected && !vehicles.some((v) => v.id === selected)) select(null);
  if (!plan.origin && vehicles.some((v) => v.position) && performance.now() - originAsked > 2000) askOrigin();
}

function onEvent(ev) {
  log.event(ev);
  history.onEvent(ev);
  missions.onEvent(ev);
  switch (ev.type) {
    case 'vehicle_joined':
      if (ev.id && ev.connection) connections.set(ev.id, ev.connection);
      break;
    case 'actor_failed':
      toasts.show(ev.escalated ? 'error' : 'warn', `${ev.path} failed`,
        `${ev.reason}${ev.escalated ? ' · escalating' : ev.next_backoff_ms != null ? ` · restart in ${ev.next_backoff_ms} ms` : ''}`);
      supervision.onActorEvent();
      break;
    case 'actor_escalated':
      toasts.show('error', `${ev.path} escalated`, ev.action);
      supervision.onActorEvent();
      break;
    case 'leader_changed':
      toasts.show('warn', `leader ${ev.from || 'none'} → ${ev.to}`, ev.reason);
      break;
    case 'hazard_added':
      toasts.show('error', `${ev.id} is a hazard`, `${ev.reason}: the formation plans around where it was last seen`);
      break;
    case 'formation_blocked':
      if (ev.reason) toasts.show('error', 'formation blocked', ev.reason);
      break;
    case 'formation_changed':
      setFormation(ev.formation);
      break;
    case 'geofence_changed':
      fencePanel.setFence(ev.fence, ev.version);
      break;
    case 'geofence_breach':
      if (ev.breached) toasts.show('error', `${ev.id} left the geofence`, 'its autopilot takes the breach action (GF_ACTION)');
      break;
    case 'fence_sync':
      if (ev.state === 'failed' || ev.state === 'differs') toasts.show('error', `${ev.id}: autopilot fence ${ev.state}`, ev.reason || '');
      break;
    case 'command_result':
      if (!ev.ok) toasts.show('error', `${ev.id}: ${ev.command} failed`, ev.error || '');
      break;
    case 'link_lost':
      toasts.show('warn', `${ev.id}: link lost`);
      break;
    case 'actor_restarted':
      toasts.show('ok', `${ev.path} restarted`, `${ev.restarts}× · ${(ev.latency_us / 1000).toFixed(1)} ms · ${ev.reason}`);
      supervision.onActorEvent();
      break;
    default:
  }
}

// Connection indicator and stream.
const conn = $('connection');
let wasConnected = false;
let countdown = 0;
function onStatus(status, delay) {
  conn.dataset.state = status;
  clearInterval(countdown);
  if (status === 'reconnecting') {
    // Live countdown to the next attempt.
    const due = performance.now() + delay;
    const tick = () => {
      conn.textContent = `reconnecting in ${Math.max(0, (due - performance.now()) / 1000).toFixed(1)} s`;
    };
    tick();
    countdown = setInterval(tick, 100);
  } else {
    conn.textContent = status;
  }
  document.body.classList.toggle('offline', status !== 'connected');
  if (status === 'connected') {
    if (wasConnected) {
      log.note('stream', 'ok', 'stream', 'reconnected to skein');
      payloads.reconnected();
    }
    else log.note('stream', 'ok', 'stream', 'connected to skein');
    wasConnected = true;
    // The formation is not repeated on the stream: fetch it on every (re)connection.
    api.getFormation().then((res) => { if (res.ok) setFormation(res.data); });
    api.getGeofence().then((res) => {
      if (res.ok) fencePanel.setFence(res.data);
      else if (res.status !== 404) toasts.show('error', 'Geofence', res.data.error);
    });
    api.getMap().then((res) => { if (res.ok) plan.mapLayer.setInfo(res.data); });
    askOrigin();
  } else if (status === 'reconnecting' && conn.dataset.logged !== 'down') {
    log.note('stream', 'warn', 'stream', 'stream closed; reconnecting');
  }
  conn.dataset.logged = status === 'connected' ? 'up' : status === 'reconnecting' ? 'down' : conn.dataset.logged || '';
}

const stream = new api.Stream(api.streamUrl(), {
  onStatus,
  onMessage: (msg) => {
    if (msg.type !== 'vehicles') { onEvent(msg); return; }
    onVehicles(msg.vehicles, msg.formation);
    showLoad($('load'), msg.load);
  },
});
stream.start();

// Plan tools and keyboard shortcuts.
$('plan-fit').addEventListener('click', () => plan.fit());
$('plan-follow').addEventListener('click', () => follow());
$('plan-follow').disabled = true;
function follow() {
  if (!selected) { toasts.show('info', 'Follow', 'select a vehicle first'); return; }
  plan.setFollow(plan.follow === selected ? null : selected);
  $('plan-follow').classList.toggle('active', !!plan.follow);
}
const needSelected = (f) => () => (selected ? f(selected) : toasts.show('info', 'No vehicle selected', 'click one on the plan or in the table'));
installShortcuts({
  t: () => controls.swarmCommand('takeoff', null),
  h: () => controls.swarmCommand('hold', null),
  r: () => controls.swarmCommand('rtl', null),
  l: () => controls.swarmCommand('land', null),
  g: needSelected(() => { tabs.open('vehicle'); detail.goto(); }),
  x: needSelected(() => { tabs.open('vehicle'); detail.command('force_disarm', null); }),
  f: () => { plan.fit(); $('plan-follow').classList.remove('active'); },
  v: () => follow(),
  tab: (i) => { const n = tabs.names()[i]; if (n) tabs.open(n); },
  escape: () => { if (!plan.cancelPick() && selected) select(null); },
}, $('shortcuts'));
