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
    let created = Instant::now();
    let driver = match create(&args) {
        Ok(d) => d,
        Err(e) => {
            let _ = actor.cast(PayloadMsg::Ready(Err(e)));
            return;
        }
    };
    let mut thread = DriverThread {
        args,
        driver,
        created,
    };
    thread.args.shared.set_served_by(thread.driver.served_by());
    if actor
        .cast(PayloadMsg::Ready(Ok(thread.driver.tick_rate_hz())))
        .is_err()
    {
        thread.retire();
        return;
    }
    while let Ok(job) = jobs.recv() {
        let go_on = match job.call {
            DriverCall::Shutdown => {
                thread.retire();
                let _ = job.reply.send((Ok(Value::Null), 0.0));
                false
            }
            DriverCall::Refresh(reloaded_at) => thread.refresh(reloaded_at, job.reply),
            _ => thread.call(job),
        };
        if !go_on {
            break;
        }
    }
    // The driver is dropped here, on its own thread (a process-isolated one reaps its
    // child; a stuck destructor blocks nobody else).
    thread.retire();
}

/// A driver made by the payload's factory (a panic while creating it is an error).
fn create(args: &PayloadArgs) -> Result<Box<dyn PayloadDriver>, String> {
    use std::panic::{AssertUnwindSafe, catch_unwind};
    catch_unwind(AssertUnwindSafe(|| {
        args.factory.create(&args.spec, args.host.clone())
    }))
    .unwrap_or_else(|p| Err(format!("panicked while creating: {}", panic_text(&*p))))
}

/// Runs `call` on `driver` (a refresh or shutdown does nothing here).
fn run(driver: &mut dyn PayloadDriver, call: &DriverCall) -> Result<Value, String> {
    match call {
        DriverCall::Tick(dt) => driver.tick(*dt).map(|()| Value::Null),
        DriverCall::Handle(cmd) => driver.handle(cmd.clone()),
        DriverCall::Mavlink(compid, msg) => driver.on_mavlink(*compid, msg).map(|()| Value::Null),
        DriverCall::Refresh(_) | DriverCall::Shutdown => Ok(Value::Null),
    }
}

/// What the driver thread holds: the payload, its driver and when it was created.
struct DriverThread {
    args: PayloadArgs,
    driver: Box<dyn PayloadDriver>,
    created: Instant,
}

impl DriverThread {
    /// Drops the driver (its `shutdown` runs) and says the slot is served by nobody.
    fn retire(&mut self) {
        drop(std::mem::replace(&mut self.driver, Box::new(Retired)));
        self.args.shared.set_served_by(None);
    }

    /// Replaces the driver by a new one from the current build of its plugin. The old
    /// one is dropped first, so that what it restores at shutdown (the radio's link)
    /// does not undo what the new one sets up.
    fn recreate(&mut self) -> Result<(), String> {
        drop(std::mem::replace(&mut self.driver, Box::new(Retired)));
        let c = Instant::now();
        self.driver = create(&self.args)?;
        self.created = c;
        self.args.shared.set_served_by(self.driver.served_by());
        tracing::info!(
            vehicle = %self.args.host.vehicle_id(), slot = %self.args.spec.slot,
            "payload re-created on the reloaded plugin"
        );
        Ok(())
    }

    /// A plugin reloaded at `reloaded_at`: a driver created before is replaced now; one
    /// created since (at its first call after the reload) is left. False when the thread
    /// must end (no driver left, or the actor gone).
    fn refresh(
        &mut self,
        reloaded_at: Instant,
        reply: tokio::sync::oneshot::Sender<CallReply>,
    ) -> bool {
        let result = if self.created < reloaded_at {
            self.recreate()
                .map(|()| Value::Null)
                .map_err(|e| Ok(format!("re-creating it on the reloaded plugin failed: {e}")))
        } else {
            Ok(Value::Null)
        };
        let failed = result.is_err();
        reply.send((result, self.driver.tick_rate_hz())).is_ok() && !failed
    }

    /// Runs `job`'s call and answers it; a driver whose library was reloaded is
    /// re-created and the call repeated. False when the thread must end (the actor gave
    /// up on the call, or the driver is poisoned by a panic or gone).
    fn call(&mut self, job: Job) -> bool {
        use std::panic::{AssertUnwindSafe, catch_unwind};
        let mut result = catch_unwind(AssertUnwindSafe(|| run(self.driver.as_mut(), &job.call)));
        if let Ok(Err(e)) = &result
            && is_stale(e)
        {
            // The library was reloaded and the reload's notice has not reached us yet:
            // re-create on the new build and repeat the call (a fresh driver's tick is
            // harmless).
            if let Err(e2) = self.recreate() {
                // No driver left: the actor must fail (its supervisor tries again).
                let _ = job
                    .reply
                    .send((Err(Err(format!("{e}; re-creating it failed: {e2}"))), 0.0));
                return false;
            }
            result = catch_unwind(AssertUnwindSafe(|| run(self.driver.as_mut(), &job.call)));
        }
        let rate = self.driver.tick_rate_hz();
        let panicked = result.is_err();
        let reply = match result {
            Ok(Ok(v)) => Ok(v),
            Ok(Err(e)) => Err(Ok(e)),
            Err(p) => Err(Err(format!("panicked: {}", panic_text(&*p)))),
        };
        job.reply.send((reply, rate)).is_ok() && !panicked
    }
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
