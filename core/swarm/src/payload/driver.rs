//! The driver thread of a payload actor: it creates the driver, runs every call on it,
//! re-creates it when its plugin was reloaded, and drops it (so the driver's `shutdown`
//! runs there). A driver never runs on a tokio worker: a plugin call that blocks holds
//! this thread only.

use super::actor::{PayloadArgs, PayloadMsg};
use crate::supervision::panic_text;
use ractor::ActorRef;
use serde_json::Value;
use skein_mavlink::MavMessage;
use skein_payload::PayloadDriver;
use std::time::Instant;

pub(super) static ABANDONED: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// One call into the driver, run on its thread.
pub(super) enum DriverCall {
    Tick(f64),
    Handle(Value),
    Mavlink(u8, Box<MavMessage>),
    /// Re-create the driver if it was created before this instant.
    Refresh(Instant),
    /// Drop the driver (its `shutdown` runs) and end the thread.
    Shutdown,
}

impl DriverCall {
    pub(super) fn name(&self) -> &'static str {
        match self {
            DriverCall::Tick(_) => "tick",
            DriverCall::Handle(_) => "command",
            DriverCall::Mavlink(..) => "on_mavlink",
            DriverCall::Refresh(_) => "re-creation",
            DriverCall::Shutdown => "shutdown",
        }
    }
}

/// What the driver thread answers: the call's result (`Err(Ok(e))` the driver's error,
/// `Err(Err(why))` a failure that leaves no usable driver: a panic, a failed re-creation)
/// and the driver's tick rate after the call.
pub(super) type CallReply = (Result<Value, Result<String, String>>, f64);

pub(super) struct Job {
    pub(super) call: DriverCall,
    pub(super) reply: tokio::sync::oneshot::Sender<CallReply>,
}

/// True when a driver error says its plugin library was reloaded and the instance must be
/// re-created to run the new build (the plugin host's `STALE_INSTANCE_ERROR` prefix).
pub(super) fn is_stale(error: &str) -> bool {
    error.starts_with("plugin reloaded:")
}

/// The driver thread: creates the driver, answers jobs until the actor drops its sender,
/// re-creates the driver when its library was reloaded, drops it on this thread.
pub(super) fn driver_thread(
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
    args.shared.set_served_by(driver.served_by());
    if actor
        .cast(PayloadMsg::Ready(Ok(driver.tick_rate_hz())))
        .is_err()
    {
        drop(driver);
        args.shared.set_served_by(None);
        return;
    }
    let run = |driver: &mut Box<dyn PayloadDriver>, call: &DriverCall| match call {
        DriverCall::Tick(dt) => driver.tick(*dt).map(|()| Value::Null),
        DriverCall::Handle(cmd) => driver.handle(cmd.clone()),
        DriverCall::Mavlink(compid, msg) => driver.on_mavlink(*compid, msg).map(|()| Value::Null),
        DriverCall::Refresh(_) | DriverCall::Shutdown => Ok(Value::Null),
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
        args.shared.set_served_by(driver.served_by());
        tracing::info!(
            vehicle = %args.host.vehicle_id(), slot = %args.spec.slot,
            "payload re-created on the reloaded plugin"
        );
        Ok::<(), String>(())
    };
    while let Ok(job) = jobs.recv() {
        if let DriverCall::Shutdown = job.call {
            drop(std::mem::replace(&mut driver, Box::new(Retired)));
            args.shared.set_served_by(None);
            let _ = job.reply.send((Ok(Value::Null), 0.0));
            break;
        }
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
    drop(driver);
    args.shared.set_served_by(None);
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
