//! Payload actors: one per payload slot of a vehicle, supervised by its Vehicle actor.
//!
//! The actor owns a [`PayloadDriver`] created by the configured [`PayloadFactory`]
//! (plugins, or the built-in fault fixture), ticks it at the rate it asks for, forwards
//! operator commands and MAVLink from the vehicle's components to it, and answers the
//! watchdog. A driver error during a tick fails the actor (a crashed process-isolated
//! plugin shows up that way), and the supervisor restarts it, which creates a new driver.
//! The driver lives on an OS thread of its own and every call has a deadline (see
//! [`PayloadActor`]): a plugin never blocks a tokio worker. When its plugin is reloaded the
//! driver is re-created on the new build ([`PayloadMsg::Refresh`]) without a failure.
//!
//! What outlives the actor is [`PayloadShared`]: the state and the last video frame the
//! payload published, so the API keeps showing them across restarts.

use crate::events::SwarmEvent;
use crate::vehicle::VehicleShared;
use crate::view::SwarmView;
use ractor::{Actor, ActorProcessingErr, ActorRef, RpcReplyPort};
use serde_json::{Value, json};
use skein_mavlink::MavMessage;
use skein_model::supervision::FaultKind;
use skein_model::vehicle::VehicleSnapshot;
use skein_payload::{
    PayloadDriver, PayloadFactory, PayloadHost, PayloadSpec, PayloadState, ProviderInfo,
};
use std::collections::BTreeMap;
use std::sync::{Arc, PoisonError, RwLock};
use std::time::{Duration, Instant};
use tokio::sync::{broadcast, watch};

pub use crate::protocol::PayloadCommandError;

/// What a payload published, kept across restarts of its actor.
pub struct PayloadShared {
    /// The payload's spec (slot, kind, plugin, config).
    pub spec: PayloadSpec,
    state: RwLock<Option<PayloadState>>,
    frame: watch::Sender<Option<Arc<Vec<u8>>>>,
    frames: std::sync::atomic::AtomicU64,
}

impl std::fmt::Debug for PayloadShared {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PayloadShared")
            .field("slot", &self.spec.slot)
            .finish_non_exhaustive()
    }
}

impl PayloadShared {
    /// Nothing published yet.
    pub fn new(spec: PayloadSpec) -> Arc<Self> {
        Arc::new(PayloadShared {
            spec,
            state: RwLock::new(None),
            frame: watch::channel(None).0,
            frames: std::sync::atomic::AtomicU64::new(0),
        })
    }

    /// The last published state.
    pub fn state(&self) -> Option<PayloadState> {
        self.state
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// The last published video frame (JPEG).
    pub fn frame(&self) -> Option<Arc<Vec<u8>>> {
        self.frame.borrow().clone()
    }

    /// A receiver that wakes at every new frame (MJPEG streaming).
    pub fn subscribe_frames(&self) -> watch::Receiver<Option<Arc<Vec<u8>>>> {
        self.frame.subscribe()
    }

    /// Frames published so far.
    pub fn frames_published(&self) -> u64 {
        self.frames.load(std::sync::atomic::Ordering::Relaxed)
    }
}

/// Degrades a simulated vehicle's radio link (implemented by the binary for the
/// in-process simulator).
pub trait SimulatorControl: Send + Sync {
    /// Sets the fraction of datagrams lost (0..1) and the one-way latency (ms) of the
    /// simulated vehicle `sysid`. Returns false when there is no such vehicle.
    fn set_link_quality(&self, sysid: u8, loss_fraction: f64, latency_ms: f64) -> bool;
}

/// The vehicle side of [`PayloadHost`] for one payload slot.
pub struct VehiclePayloadHost {
    vehicle: Arc<VehicleShared>,
    view: Arc<SwarmView>,
    events: broadcast::Sender<SwarmEvent>,
    slot: String,
    shared: Arc<PayloadShared>,
    siblings: Arc<BTreeMap<String, Arc<PayloadShared>>>,
}

impl VehiclePayloadHost {
    /// The host for `slot` of `vehicle`.
    pub fn new(
        vehicle: Arc<VehicleShared>,
        view: Arc<SwarmView>,
        events: broadcast::Sender<SwarmEvent>,
        siblings: Arc<BTreeMap<String, Arc<PayloadShared>>>,
        slot: &str,
    ) -> Arc<Self> {
        let shared = siblings[slot].clone();
        Arc::new(VehiclePayloadHost {
            vehicle,
            view,
            events,
            slot: slot.to_string(),
            shared,
            siblings,
        })
    }
}

impl PayloadHost for VehiclePayloadHost {
    fn vehicle_id(&self) -> &str {
        &self.vehicle.id
    }

    fn vehicle(&self) -> VehicleSnapshot {
        self.vehicle.snapshot()
    }

    fn swarm(&self) -> Vec<VehicleSnapshot> {
        self.view.snapshots()
    }

    fn simulated(&self) -> bool {
        self.vehicle.simulated
    }

    fn send_mavlink(&self, msg: &MavMessage) -> Result<(), String> {
        self.vehicle
            .link
            .endpoint
            .send(self.vehicle.link.sysid, msg)
            .map_err(|e| e.to_string())
    }

    fn emit_event(&self, kind: &str, data: Value) {
        let _ = self.events.send(SwarmEvent::PayloadEvent {
            id: self.vehicle.id.clone(),
            slot: self.slot.clone(),
            kind: kind.to_string(),
            data,
        });
    }

    fn publish_state(&self, state: PayloadState) {
        *self
            .shared
            .state
            .write()
            .unwrap_or_else(PoisonError::into_inner) = Some(state);
    }

    fn payload_state(&self, slot: &str) -> Option<PayloadState> {
        self.siblings.get(slot).and_then(|p| p.state())
    }

    fn publish_frame(&self, jpeg: Vec<u8>) {
        self.shared
            .frames
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.shared.frame.send_replace(Some(Arc::new(jpeg)));
    }

    fn set_simulated_link(&self, loss_fraction: f64, latency_ms: f64) -> bool {
        match self.view.simulator() {
            Some(sim) if self.vehicle.simulated => {
                sim.set_link_quality(self.vehicle.link.sysid, loss_fraction, latency_ms)
            }
            _ => false,
        }
    }
}

/// Arguments of [`PayloadActor`].
pub struct PayloadArgs {
    /// The spec.
    pub spec: PayloadSpec,
    /// Where drivers come from.
    pub factory: Arc<dyn PayloadFactory>,
    /// The vehicle's services.
    pub host: Arc<dyn PayloadHost>,
    /// How long one driver call (tick, command, MAVLink) may take before the actor gives
    /// its driver thread up and fails (the supervisor then re-creates the payload). Keep it
    /// below the watchdog deadline, so the failure names the call rather than a hang.
    pub call_deadline: Duration,
}

/// Messages of [`PayloadActor`].
pub enum PayloadMsg {
    /// Periodic tick.
    Tick,
    /// An operator command; the driver's answer or error goes back.
    Command(Value, RpcReplyPort<Result<Value, String>>),
    /// MAVLink from the vehicle (component id, message).
    Mavlink(u8, Box<MavMessage>),
    /// Watchdog probe.
    Ping(RpcReplyPort<()>),
    /// Fault injection.
    Fault(FaultKind),
    /// From the driver thread: the driver was created (its tick rate, Hz) or could not be.
    Ready(Result<f64, String>),
    /// The driver's plugin library was reloaded at this instant: re-create the driver on the
    /// new build unless it was created after that (a failure to re-create fails the actor).
    Refresh(Instant),
}

/// The payload actor (see module docs).
///
/// The driver never runs on a tokio worker: each instance has an OS thread of its own
/// (`payload-<vehicle>-<slot>`) that creates the driver, runs every call and drops it. The
/// actor sends a call and awaits its answer with [`PayloadArgs::call_deadline`]; a call
/// that does not return in time (an in-process plugin that hangs or spins) fails the actor
/// and the thread is abandoned (counted by [`abandoned_driver_threads`]), so a stuck plugin
/// never holds a worker the setpoint streams and other actors need. A panic on the thread
/// is caught and fails the actor too.
pub struct PayloadActor;

/// Driver threads given up because a call did not return in time, since the process
/// started (each holds its stuck driver until the call returns, if ever).
pub fn abandoned_driver_threads() -> u64 {
    ABANDONED.load(std::sync::atomic::Ordering::Relaxed)
}

static ABANDONED: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// One call into the driver, run on its thread.
enum DriverCall {
    Tick(f64),
    Handle(Value),
    Mavlink(u8, Box<MavMessage>),
    /// Re-create the driver if it was created before this instant.
    Refresh(Instant),
}

impl DriverCall {
    fn name(&self) -> &'static str {
        match self {
            DriverCall::Tick(_) => "tick",
            DriverCall::Handle(_) => "command",
            DriverCall::Mavlink(..) => "on_mavlink",
            DriverCall::Refresh(_) => "re-creation",
        }
    }
}

/// What the driver thread answers: the call's result (`Err(Ok(e))` the driver's error,
/// `Err(Err(why))` a failure that leaves no usable driver: a panic, a failed re-creation)
/// and the driver's tick rate after the call.
type CallReply = (Result<Value, Result<String, String>>, f64);

struct Job {
    call: DriverCall,
    reply: tokio::sync::oneshot::Sender<CallReply>,
}

/// True when a driver error says its plugin library was reloaded and the instance must be
/// re-created to run the new build (the plugin host's `STALE_INSTANCE_ERROR` prefix).
fn is_stale(error: &str) -> bool {
    error.starts_with("plugin reloaded:")
}

fn panic_text(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "non-string panic payload".into())
}

/// The driver thread: creates the driver, answers jobs until the actor drops its sender,
/// re-creates the driver when its library was reloaded, drops it on this thread.
fn driver_thread(
    args: PayloadArgs,
    jobs: std::sync::mpsc::Receiver<Job>,
    actor: ActorRef<PayloadMsg>,
) {
    use std::panic::{AssertUnwindSafe, catch_unwind};
    let create = || {
        catch_unwind(AssertUnwindSafe(|| {
            args.factory.create(&args.spec, args.host.clone())
        }))
        .unwrap_or_else(|p| Err(format!("panicked while creating: {}", panic_text(&*p))))
    };
    let mut created = Instant::now();
    let mut driver = match create() {
        Ok(d) => d,
        Err(e) => {
            let _ = actor.cast(PayloadMsg::Ready(Err(e)));
            return;
        }
    };
    if actor
        .cast(PayloadMsg::Ready(Ok(driver.tick_rate_hz())))
        .is_err()
    {
        return;
    }
    let run = |driver: &mut Box<dyn PayloadDriver>, call: &DriverCall| match call {
        DriverCall::Tick(dt) => driver.tick(*dt).map(|()| Value::Null),
        DriverCall::Handle(cmd) => driver.handle(cmd.clone()),
        DriverCall::Mavlink(compid, msg) => driver.on_mavlink(*compid, msg).map(|()| Value::Null),
        DriverCall::Refresh(_) => Ok(Value::Null),
    };
    // Replaces the driver by a new one from the current build of its plugin. The old one
    // is dropped first, so that what it restores at shutdown (the radio's link) does not
    // undo what the new one sets up.
    let recreate = |driver: &mut Box<dyn PayloadDriver>, created: &mut Instant| {
        drop(std::mem::replace(driver, Box::new(Retired)));
        let c = Instant::now();
        let fresh = create()?;
        *driver = fresh;
        *created = c;
        tracing::info!(
            vehicle = %args.host.vehicle_id(), slot = %args.spec.slot,
            "payload re-created on the reloaded plugin"
        );
        Ok::<(), String>(())
    };
    while let Ok(job) = jobs.recv() {
        if let DriverCall::Refresh(reloaded_at) = job.call {
            // Created before the reload: replace it now; created since (at its first call
            // after the reload, below): nothing to do.
            let result = if created < reloaded_at {
                recreate(&mut driver, &mut created)
                    .map(|()| Value::Null)
                    .map_err(|e| Ok(format!("re-creating it on the reloaded plugin failed: {e}")))
            } else {
                Ok(Value::Null)
            };
            let failed = result.is_err();
            if job.reply.send((result, driver.tick_rate_hz())).is_err() || failed {
                break;
            }
            continue;
        }
        let mut result = catch_unwind(AssertUnwindSafe(|| run(&mut driver, &job.call)));
        if let Ok(Err(e)) = &result
            && is_stale(e)
        {
            // The library was reloaded and the reload's notice has not reached us yet:
            // re-create on the new build and repeat the call (a fresh driver's tick is
            // harmless).
            if let Err(e2) = recreate(&mut driver, &mut created) {
                // No driver left: the actor must fail (its supervisor tries again).
                let _ = job
                    .reply
                    .send((Err(Err(format!("{e}; re-creating it failed: {e2}"))), 0.0));
                break;
            }
            result = catch_unwind(AssertUnwindSafe(|| run(&mut driver, &job.call)));
        }
        let rate = driver.tick_rate_hz();
        let panicked = result.is_err();
        let reply = match result {
            Ok(Ok(v)) => Ok(v),
            Ok(Err(e)) => Err(Ok(e)),
            Err(p) => Err(Err(format!("panicked: {}", panic_text(&*p)))),
        };
        if job.reply.send((reply, rate)).is_err() || panicked {
            // The actor gave up on this call, or the driver is poisoned by a panic.
            break;
        }
    }
    // The driver is dropped here, on its own thread (a process-isolated one reaps its
    // child; a stuck destructor blocks nobody else).
}

/// Stands in for a driver being replaced (between dropping the old and creating the new).
struct Retired;

impl PayloadDriver for Retired {
    fn tick_rate_hz(&self) -> f64 {
        0.0
    }

    fn tick(&mut self, _dt_s: f64) -> Result<(), String> {
        Err("the payload is being re-created".into())
    }

    fn handle(&mut self, _command: Value) -> Result<Value, String> {
        Err("the payload is being re-created".into())
    }
}

/// State of [`PayloadActor`].
pub struct PayloadActorState {
    jobs: std::sync::mpsc::Sender<Job>,
    thread: String,
    slot: String,
    vehicle: String,
    last_tick: Instant,
    tick_rate_hz: f64,
    ticker: Option<tokio::task::JoinHandle<()>>,
    call_deadline: Duration,
    /// The driver exists (its thread said so); before, MAVLink is dropped and commands are
    /// refused rather than queued behind a creation that may take seconds.
    ready: bool,
}

impl PayloadActorState {
    /// Runs `call` on the driver thread within the call deadline.
    async fn call(&mut self, call: DriverCall) -> Result<Result<Value, String>, String> {
        let what = call.name();
        let (tx, rx) = tokio::sync::oneshot::channel();
        if self.jobs.send(Job { call, reply: tx }).is_err() {
            return Err(format!(
                "payload `{}`: its driver thread has ended",
                self.slot
            ));
        }
        match tokio::time::timeout(self.call_deadline, rx).await {
            Ok(Ok((result, rate))) => {
                self.tick_rate_hz = rate;
                match result {
                    Ok(v) => Ok(Ok(v)),
                    Err(Ok(e)) => Ok(Err(e)),
                    Err(Err(why)) => Err(format!("payload `{}` {what}: {why}", self.slot)),
                }
            }
            Ok(Err(_)) => Err(format!(
                "payload `{}`: its driver thread ended during {what}",
                self.slot
            )),
            Err(_) => {
                ABANDONED.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let why = format!(
                    "payload `{}` {what} did not return within {} ms: driver thread `{}` \
                     abandoned (a plugin that can hang belongs in process isolation)",
                    self.slot,
                    self.call_deadline.as_millis(),
                    self.thread
                );
                tracing::error!(vehicle = %self.vehicle, "{why}");
                Err(why)
            }
        }
    }

    fn schedule_ticks(&mut self, myself: &ActorRef<PayloadMsg>) {
        if let Some(t) = self.ticker.take() {
            t.abort();
        }
        let rate = self.tick_rate_hz;
        if rate > 0.0 && rate.is_finite() {
            self.ticker = Some(
                myself.send_interval(Duration::from_secs_f64(1.0 / rate.min(1000.0)), || {
                    PayloadMsg::Tick
                }),
            );
        }
    }
}

impl Actor for PayloadActor {
    type Msg = PayloadMsg;
    type State = PayloadActorState;
    type Arguments = PayloadArgs;

    async fn pre_start(
        &self,
        myself: ActorRef<Self::Msg>,
        args: PayloadArgs,
    ) -> Result<Self::State, ActorProcessingErr> {
        let (jobs, rx) = std::sync::mpsc::channel();
        let slot = args.spec.slot.clone();
        let vehicle = args.host.vehicle_id().to_string();
        let call_deadline = args.call_deadline;
        let thread = format!("payload-{vehicle}-{slot}");
        let me = myself.clone();
        // The driver is created on its thread too: creating a process-isolated one starts a
        // child and waits for it, which must not hold a tokio worker.
        std::thread::Builder::new()
            .name(thread.clone())
            .spawn(move || driver_thread(args, rx, me))
            .map_err(|e| format!("payload `{slot}`: cannot start its thread: {e}"))?;
        Ok(PayloadActorState {
            jobs,
            thread,
            slot,
            vehicle,
            last_tick: Instant::now(),
            tick_rate_hz: 0.0,
            ticker: None,
            call_deadline,
            ready: false,
        })
    }

    async fn post_stop(
        &self,
        _myself: ActorRef<Self::Msg>,
        state: &mut Self::State,
    ) -> Result<(), ActorProcessingErr> {
        if let Some(t) = state.ticker.take() {
            t.abort();
        }
        Ok(())
    }

    async fn handle(
        &self,
        myself: ActorRef<Self::Msg>,
        msg: Self::Msg,
        state: &mut Self::State,
    ) -> Result<(), ActorProcessingErr> {
        match msg {
            PayloadMsg::Ready(Ok(rate)) => {
                state.ready = true;
                state.tick_rate_hz = rate;
                state.last_tick = Instant::now();
                state.schedule_ticks(&myself);
            }
            PayloadMsg::Ready(Err(e)) => {
                return Err(format!("payload `{}`: {e}", state.slot).into());
            }
            PayloadMsg::Tick => {
                let now = Instant::now();
                let dt = now.duration_since(state.last_tick).as_secs_f64();
                // Ticks queued while a slow call ran are coalesced.
                if state.tick_rate_hz > 0.0 && dt < 0.5 / state.tick_rate_hz {
                    return Ok(());
                }
                state.last_tick = now;
                let before = state.tick_rate_hz;
                state
                    .call(DriverCall::Tick(dt))
                    .await?
                    .map_err(|e| format!("payload `{}` tick failed: {e}", state.slot))?;
                if state.tick_rate_hz != before {
                    state.schedule_ticks(&myself);
                }
            }
            PayloadMsg::Command(_, reply) if !state.ready => {
                let _ = reply.send(Err(format!(
                    "payload `{}` is still starting: try again",
                    state.slot
                )));
            }
            // Before the driver exists: MAVLink is dropped, and a reload is left to the
            // new driver's first call (the host fails it if it came from the old build).
            PayloadMsg::Mavlink(..) | PayloadMsg::Refresh(_) if !state.ready => {}
            PayloadMsg::Command(cmd, reply) => {
                let before = state.tick_rate_hz;
                // On a panic or a missed deadline the reply is dropped (the caller sees the
                // payload fail) and the actor fails.
                let answer = state.call(DriverCall::Handle(cmd)).await?;
                let _ = reply.send(answer);
                if state.tick_rate_hz != before {
                    state.schedule_ticks(&myself);
                }
            }
            PayloadMsg::Mavlink(compid, msg) => {
                state
                    .call(DriverCall::Mavlink(compid, msg))
                    .await?
                    .map_err(|e| format!("payload `{}`: {e}", state.slot))?;
            }
            PayloadMsg::Refresh(at) => {
                let before = state.tick_rate_hz;
                state
                    .call(DriverCall::Refresh(at))
                    .await?
                    .map_err(|e| format!("payload `{}`: {e}", state.slot))?;
                if state.tick_rate_hz != before {
                    state.schedule_ticks(&myself);
                }
            }
            PayloadMsg::Ping(reply) => {
                let _ = reply.send(());
            }
            PayloadMsg::Fault(kind) => {
                let who = format!("payload {}", state.slot);
                skein_link::fault::inject(kind, &myself, &who).await?;
            }
        }
        Ok(())
    }
}

/// The built-in payload kinds: `fault-fixture`, a payload that fails on request, for
/// supervision tests and for users rehearsing recovery.
///
/// Commands (`{"action": ...}`): `"echo"` answers the command back; `"panic"` panics in
/// the handler; `"error"` answers an error (the operator sees it, the actor lives);
/// `"fail_next_tick"` makes the next tick fail (the actor fails and is restarted). State:
/// `{"ticks": n, "created_unix_ms": t}`, published every tick (10 Hz).
pub struct BuiltinPayloads;

/// Kind name of the built-in fault fixture.
pub const FAULT_FIXTURE: &str = "fault-fixture";

struct FaultFixture {
    host: Arc<dyn PayloadHost>,
    ticks: u64,
    created_unix_ms: u64,
    fail_next_tick: bool,
}

impl PayloadDriver for FaultFixture {
    fn tick_rate_hz(&self) -> f64 {
        10.0
    }

    fn tick(&mut self, _dt_s: f64) -> Result<(), String> {
        if std::mem::take(&mut self.fail_next_tick) {
            return Err("fault fixture: failing this tick as asked".into());
        }
        self.ticks += 1;
        self.host.publish_state(json!({
            "ticks": self.ticks,
            "created_unix_ms": self.created_unix_ms,
        }));
        Ok(())
    }

    fn handle(&mut self, command: Value) -> Result<Value, String> {
        match command.get("action").and_then(Value::as_str) {
            Some("echo") => Ok(command),
            Some("panic") => panic!("fault fixture: panic on request"),
            Some("error") => Err("fault fixture: error on request".into()),
            Some("fail_next_tick") => {
                self.fail_next_tick = true;
                Ok(json!({"ok": true}))
            }
            Some(other) => Err(format!(
                "action: unknown action `{other}` (echo, panic, error, fail_next_tick)"
            )),
            None => {
                Err("action: missing field `action` (echo, panic, error, fail_next_tick)".into())
            }
        }
    }
}

impl PayloadFactory for BuiltinPayloads {
    fn create(
        &self,
        spec: &PayloadSpec,
        host: Arc<dyn PayloadHost>,
    ) -> Result<Box<dyn PayloadDriver>, String> {
        match spec.kind.as_str() {
            FAULT_FIXTURE => Ok(Box::new(FaultFixture {
                host,
                ticks: 0,
                created_unix_ms: std::time::SystemTime::now()
                    .duration_since(std::time::UNIX_EPOCH)
                    .map_or(0, |d| d.as_millis() as u64),
                fail_next_tick: false,
            })),
            other => Err(format!("no built-in payload kind `{other}`")),
        }
    }

    fn providers(&self) -> Vec<ProviderInfo> {
        vec![ProviderInfo {
            name: "builtin".into(),
            version: env!("CARGO_PKG_VERSION").into(),
            kinds: vec![FAULT_FIXTURE.into()],
        }]
    }
}

/// Several factories, asked in order: the first that provides the spec's plugin (when
/// named) or kind creates the driver.
pub struct Factories(pub Vec<Arc<dyn PayloadFactory>>);

impl PayloadFactory for Factories {
    fn create(
        &self,
        spec: &PayloadSpec,
        host: Arc<dyn PayloadHost>,
    ) -> Result<Box<dyn PayloadDriver>, String> {
        let provides = |f: &Arc<dyn PayloadFactory>| {
            f.providers().iter().any(|p| {
                p.kinds.contains(&spec.kind)
                    && spec.plugin.as_ref().is_none_or(|name| *name == p.name)
            })
        };
        match self.0.iter().find(|f| provides(f)) {
            Some(f) => f.create(spec, host),
            None => Err(format!(
                "no loaded plugin provides payload kind `{}`{} (slot `{}`)",
                spec.kind,
                spec.plugin
                    .as_ref()
                    .map(|p| format!(" from plugin `{p}`"))
                    .unwrap_or_default(),
                spec.slot
            )),
        }
    }

    fn providers(&self) -> Vec<ProviderInfo> {
        self.0.iter().flat_map(|f| f.providers()).collect()
    }
}
