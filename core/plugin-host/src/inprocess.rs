//! A payload driver whose plugin runs in skein's own process: each call is a direct call
//! through the library's vtable (a few nanoseconds plus the JSON).
//!
//! A panic in the plugin comes back as an error (the SDK's export glue catches it) and
//! poisons the instance. What this cannot survive: an abort, a segfault, or a call that
//! never returns. A hung call blocks the calling thread for good, since a thread cannot be
//! pre-empted from outside; the owner's watchdog (an actor `call` with a timeout) notices,
//! but the thread is lost. Plugins that may do that belong in process isolation.

use crate::registry::{InstanceGuard, StalePolicy};
use crate::services::{HostServices, host_api};
use skein_mavlink::{Encoder, MavMessage, message_id};
use skein_payload::PayloadDriver;
use skein_plugin_sdk::MavlinkInterest;
use skein_plugin_sdk::abi::{HostApi, PluginVTable, RawBytes, RawSink, status};
use std::ffi::c_void;

/// Turns a status and its sink output into a result; `op` and `plugin` name the call in
/// panic messages.
pub(crate) fn outcome(st: u32, out: Vec<u8>, plugin: &str, op: &str) -> Result<Vec<u8>, String> {
    match st {
        status::OK => Ok(out),
        status::ERROR => Err(String::from_utf8_lossy(&out).into_owned()),
        status::PANIC => Err(format!(
            "plugin `{plugin}` panicked in `{op}`: {}",
            String::from_utf8_lossy(&out)
        )),
        other => Err(format!(
            "plugin `{plugin}` returned an unknown status {other} from `{op}`"
        )),
    }
}

/// Parses the create reply (`{"mavlink": ...}`).
pub(crate) fn parse_instance_info(bytes: &[u8]) -> Result<MavlinkInterest, String> {
    let info: serde_json::Value = serde_json::from_slice(bytes)
        .map_err(|e| format!("the plugin's instance info is not JSON: {e}"))?;
    MavlinkInterest::from_json(&info["mavlink"])
}

/// An in-process plugin instance.
pub(crate) struct InProcessDriver {
    instance: *mut c_void,
    /// The table the instance calls back into; points into `_services`.
    api: Box<HostApi>,
    /// Kept alive (and in place) for `api`.
    _services: Box<HostServices>,
    interest: MavlinkInterest,
    tick_rate_hz: f64,
    policy: StalePolicy,
    /// Keeps the library mapped (dropped after the instance is destroyed).
    guard: InstanceGuard,
}

// SAFETY: the ABI requires instances to be movable between threads (SDK plugins are
// `Send`), and this driver is only used through `&mut self` (one call at a time).
unsafe impl Send for InProcessDriver {}

impl InProcessDriver {
    /// Creates an instance of `kind` with `config` (JSON) in the guard's library.
    ///
    /// # Errors
    /// The plugin refused (its message), or panicked.
    pub fn create(
        guard: InstanceGuard,
        kind: &str,
        config: &serde_json::Value,
        services: HostServices,
        policy: StalePolicy,
    ) -> Result<InProcessDriver, String> {
        let services = Box::new(services);
        let api = Box::new(host_api(services.as_ref()));
        let config = serde_json::to_vec(config).map_err(|e| e.to_string())?;
        let vt = guard.entry.lib.vtable();
        let mut instance: *mut c_void = std::ptr::null_mut();
        let mut out = Vec::new();
        // SAFETY: the vtable was validated at load and its library stays mapped (the guard
        // holds it); `kind` and `config` outlive the call; `api` is boxed and outlives the
        // instance (dropped after destroy); `instance` and `out` are valid for writing.
        let st = unsafe {
            (vt.create)(
                RawBytes::from_slice(kind.as_bytes()),
                RawBytes::from_slice(&config),
                api.as_ref() as *const HostApi,
                &mut instance,
                RawSink::for_vec(&mut out),
            )
        };
        let info = outcome(st, out, guard.entry.name(), "create")?;
        if instance.is_null() {
            return Err(format!(
                "plugin `{}` reported success from `create` but returned no instance",
                guard.entry.name()
            ));
        }
        let mut driver = InProcessDriver {
            instance,
            api,
            _services: services,
            interest: MavlinkInterest::None,
            tick_rate_hz: 0.0,
            policy,
            guard,
        };
        // From here on, `driver`'s Drop destroys the instance whatever happens.
        driver.interest = parse_instance_info(&info)?;
        driver.refresh_tick_rate()?;
        Ok(driver)
    }

    fn vt(&self) -> &PluginVTable {
        self.guard.entry.lib.vtable()
    }

    fn name(&self) -> &str {
        self.guard.entry.name()
    }

    fn refresh_tick_rate(&mut self) -> Result<(), String> {
        let mut hz = 0.0f64;
        let mut err = Vec::new();
        // SAFETY: live instance (destroyed only in Drop), exclusive through `&mut self`;
        // `hz` and `err` valid for the call.
        let st =
            unsafe { (self.vt().tick_rate_hz)(self.instance, &mut hz, RawSink::for_vec(&mut err)) };
        outcome(st, err, self.name(), "tick_rate_hz")?;
        self.tick_rate_hz = hz;
        Ok(())
    }

    /// Runs one vtable call on the instance, after the stale check.
    fn call(
        &mut self,
        op: &str,
        f: impl FnOnce(&PluginVTable, *mut c_void, RawSink) -> u32,
    ) -> Result<Vec<u8>, String> {
        if let Some(e) = self.guard.stale_error(self.policy) {
            return Err(e);
        }
        let mut out = Vec::new();
        let st = f(self.vt(), self.instance, RawSink::for_vec(&mut out));
        let result = outcome(st, out, self.name(), op);
        if result.is_ok() {
            self.refresh_tick_rate()?;
        }
        result
    }
}

impl PayloadDriver for InProcessDriver {
    fn served_by(&self) -> Option<skein_payload::ServedBy> {
        Some(self.guard.served_by())
    }

    fn tick_rate_hz(&self) -> f64 {
        self.tick_rate_hz
    }

    fn tick(&mut self, dt_s: f64) -> Result<(), String> {
        // SAFETY: live instance, exclusive; the sink is valid for the call.
        self.call("tick", |vt, inst, out| unsafe {
            (vt.tick)(inst, dt_s, out)
        })
        .map(|_| ())
    }

    fn handle(&mut self, command: serde_json::Value) -> Result<serde_json::Value, String> {
        let bytes = serde_json::to_vec(&command).map_err(|e| e.to_string())?;
        // SAFETY: live instance, exclusive; `bytes` outlives the call.
        let reply = self.call("handle", |vt, inst, out| unsafe {
            (vt.handle)(inst, RawBytes::from_slice(&bytes), out)
        })?;
        serde_json::from_slice(&reply)
            .map_err(|e| format!("plugin `{}` replied with invalid JSON: {e}", self.name()))
    }

    fn on_mavlink(&mut self, compid: u8, msg: &MavMessage) -> Result<(), String> {
        if !self.interest.wants(message_id(msg)) {
            return Ok(());
        }
        let frame = Encoder::new(0, compid).encode(msg);
        // SAFETY: live instance, exclusive; `frame` outlives the call.
        self.call("on_mavlink", |vt, inst, out| unsafe {
            (vt.on_mavlink)(inst, compid, RawBytes::from_slice(frame.as_bytes()), out)
        })
        .map(|_| ())
    }
}

impl Drop for InProcessDriver {
    fn drop(&mut self) {
        let mut err = Vec::new();
        // SAFETY: the instance is live and destroyed exactly once, here; the host table
        // (`api`, `services`) and the library (`guard`) are dropped after this body.
        let st = unsafe { (self.vt().destroy)(self.instance, RawSink::for_vec(&mut err)) };
        if st != status::OK {
            tracing::warn!(
                plugin = %self.name(),
                "destroying the instance failed: {}",
                String::from_utf8_lossy(&err)
            );
        }
        self.instance = std::ptr::null_mut();
        // Keep the table alive until here (the plugin may call back during destroy).
        let _ = &self.api;
    }
}
