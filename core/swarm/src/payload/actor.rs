//! The payload actor: one per running payload slot of a vehicle, supervised by its
//! Vehicle actor. It owns the driver's thread ([`super::driver`]), ticks the driver at
//! the rate it asks for, forwards operator commands and MAVLink to it, answers the
//! watchdog, and shuts the driver down on request (a detach) before it stops.

use super::driver::{ABANDONED, DriverCall, Job, driver_thread};
use super::shared::PayloadShared;
use crate::load::LoadMonitor;
use crate::ticker::{TickGate, Ticker};
use ractor::{Actor, ActorProcessingErr, ActorRef, RpcReplyPort};
use serde_json::Value;
use skein_mavlink::MavMessage;
use skein_model::supervision::FaultKind;
use skein_payload::{PayloadFactory, PayloadHost, PayloadSpec};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Arguments of [`PayloadActor`].
pub struct PayloadArgs {
    /// The spec.
    pub spec: PayloadSpec,
    /// Where drivers come from.
    pub factory: Arc<dyn PayloadFactory>,
    /// The vehicle's services.
    pub host: Arc<dyn PayloadHost>,
    /// What outlives the actor (the driver thread records which library serves it).
    pub shared: Arc<PayloadShared>,
    /// Told once the driver exists (an attach answers then); dropped unanswered if the
    /// driver could not be created (the actor fails).
    pub ready: Option<tokio::sync::oneshot::Sender<()>>,
    /// How long one driver call (tick, command, MAVLink) may take before the actor gives
    /// its driver thread up and fails (the supervisor then re-creates the payload). Keep it
    /// below the watchdog deadline, so the failure names the call rather than a hang.
    /// While the whole process runs late, a call gets more time (see [`crate::load`]).
    pub call_deadline: Duration,
    /// How late the process runs.
    pub load: Arc<LoadMonitor>,
    /// The process's clocks (the driver's ticks come from them).
    pub ticker: Ticker,
}

/// Longest a driver call may take, however late the process runs, in call deadlines: a
/// driver stuck that long is given up even under overload.
const MAX_EXTENSIONS: u32 = 10;

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
    /// Drop the driver now (its `shutdown` runs on its thread), answer, then stop: a
    /// detach. Answers within the call deadline or not at all.
    Shutdown(RpcReplyPort<()>),
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

/// State of [`PayloadActor`].
pub struct PayloadActorState {
    jobs: std::sync::mpsc::Sender<Job>,
    thread: String,
    slot: String,
    vehicle: String,
    last_tick: Instant,
    tick_rate_hz: f64,
    ticker: Ticker,
    /// The tick now registered with the ticker, and its generation (a rate change
    /// registers a new one; the old one stops at its next tick).
    tick: Option<TickGate>,
    tick_generation: Arc<std::sync::atomic::AtomicU64>,
    call_deadline: Duration,
    load: Arc<LoadMonitor>,
    /// The driver exists (its thread said so); before, MAVLink is dropped and commands are
    /// refused rather than queued behind a creation that may take seconds.
    ready: bool,
    /// Told when the driver exists (see [`PayloadArgs::ready`]).
    notify_ready: Option<tokio::sync::oneshot::Sender<()>>,
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
        let sent = Instant::now();
        let mut rx = rx;
        let mut extensions = 0;
        let answer = loop {
            match tokio::time::timeout(self.call_deadline, &mut rx).await {
                // Late while the whole process is late: the driver is slow, not stuck.
                Err(_) if extensions < MAX_EXTENSIONS && self.load.lagging_since(sent) => {
                    extensions += 1;
                    self.load.call_extended();
                }
                answer => break answer,
            }
        };
        match answer {
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
        use std::sync::atomic::Ordering;
        let generation = self.tick_generation.fetch_add(1, Ordering::Relaxed) + 1;
        self.tick = None;
        let rate = self.tick_rate_hz;
        if rate > 0.0 && rate.is_finite() {
            let (me, current) = (myself.clone(), self.tick_generation.clone());
            self.tick = Some(self.ticker.every(
                Duration::from_secs_f64(1.0 / rate.min(1000.0)),
                move || {
                    current.load(Ordering::Relaxed) == generation
                        && me.cast(PayloadMsg::Tick).is_ok()
                },
            ));
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
        let mut args = args;
        let notify_ready = args.ready.take();
        let slot = args.spec.slot.clone();
        let vehicle = args.host.vehicle_id().to_string();
        let call_deadline = args.call_deadline;
        let load = args.load.clone();
        let ticker = args.ticker.clone();
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
            ticker,
            tick: None,
            tick_generation: Arc::default(),
            call_deadline,
            load,
            ready: false,
            notify_ready,
        })
    }

    async fn post_stop(
        &self,
        _myself: ActorRef<Self::Msg>,
        state: &mut Self::State,
    ) -> Result<(), ActorProcessingErr> {
        // The registered tick stops at its next round.
        state
            .tick_generation
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        state.tick = None;
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
                if let Some(tx) = state.notify_ready.take() {
                    let _ = tx.send(());
                }
                state.tick_rate_hz = rate;
                state.last_tick = Instant::now();
                state.schedule_ticks(&myself);
            }
            PayloadMsg::Ready(Err(e)) => {
                return Err(format!("payload `{}`: {e}", state.slot).into());
            }
            PayloadMsg::Tick => {
                if let Some(gate) = &state.tick {
                    gate.done();
                }
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
            PayloadMsg::Shutdown(reply) => {
                // Before the driver exists there is nothing to shut down yet: the thread
                // drops it as soon as it is created (this actor is gone by then).
                if state.ready {
                    state.call(DriverCall::Shutdown).await?.map_err(|e| {
                        format!("payload `{}`: shutting down failed: {e}", state.slot)
                    })?;
                }
                let _ = reply.send(());
                myself.stop(Some("detached".into()));
            }
            PayloadMsg::Fault(kind) => {
                let who = format!("payload {}", state.slot);
                skein_link::fault::inject(kind, &myself, &who).await?;
            }
        }
        Ok(())
    }
}
