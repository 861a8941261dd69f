//! Payload actors: one per payload slot of a vehicle, supervised by its Vehicle actor.
//!
//! The actor owns a [`PayloadDriver`] created by the configured [`PayloadFactory`]
//! (plugins, or the built-in fault fixture), ticks it at the rate it asks for, forwards
//! operator commands and MAVLink from the vehicle's components to it, and answers the
//! watchdog. A driver error during a tick fails the actor (a crashed process-isolated
//! plugin shows up that way), and the supervisor restarts it, which creates a new driver.
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

/// Why a payload command got no answer from the payload.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub enum PayloadCommandError {
    /// No such vehicle or slot (HTTP 404).
    NotFound(String),
    /// The payload is not running: failed, disabled or restarting (HTTP 503).
    Unavailable(String),
    /// The payload refused the command; its message (HTTP 400).
    Refused(String),
}

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
}

/// The payload actor (see module docs).
pub struct PayloadActor;

/// State of [`PayloadActor`].
pub struct PayloadActorState {
    driver: Box<dyn PayloadDriver>,
    slot: String,
    last_tick: Instant,
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
        let driver = args
            .factory
            .create(&args.spec, args.host)
            .map_err(|e| format!("payload `{}`: {e}", args.spec.slot))?;
        let rate = driver.tick_rate_hz();
        if rate > 0.0 {
            myself.send_interval(Duration::from_secs_f64(1.0 / rate), || PayloadMsg::Tick);
        }
        Ok(PayloadActorState {
            driver,
            slot: args.spec.slot,
            last_tick: Instant::now(),
        })
    }

    async fn handle(
        &self,
        myself: ActorRef<Self::Msg>,
        msg: Self::Msg,
        state: &mut Self::State,
    ) -> Result<(), ActorProcessingErr> {
        match msg {
            PayloadMsg::Tick => {
                let now = Instant::now();
                let dt = now.duration_since(state.last_tick).as_secs_f64();
                state.last_tick = now;
                state
                    .driver
                    .tick(dt)
                    .map_err(|e| format!("payload `{}` tick failed: {e}", state.slot))?;
            }
            PayloadMsg::Command(cmd, reply) => {
                let _ = reply.send(state.driver.handle(cmd));
            }
            PayloadMsg::Mavlink(compid, msg) => {
                state
                    .driver
                    .on_mavlink(compid, &msg)
                    .map_err(|e| format!("payload `{}`: {e}", state.slot))?;
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
