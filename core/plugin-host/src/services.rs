//! Host services as the plugin sees them: the [`Services`] a [`HostApi`] table calls into,
//! implemented on top of a vehicle's [`PayloadHost`] ([`HostServices`]), or, in a
//! `skein plugin-host` child, by messages to the parent (see `child.rs`).

use skein_mavlink::Decoder;
use skein_payload::PayloadHost;
use skein_plugin_sdk::abi::{ABI_VERSION, HostApi, RawBytes, RawSink, log_level, status};
use std::ffi::c_void;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::{Arc, Mutex};

/// What a [`HostApi`] table forwards to. Byte arguments and results are the ABI's (JSON,
/// MAVLink frames, JPEG). Implementations must not panic across the table (the trampolines
/// catch panics anyway).
pub(crate) trait Services: Sync {
    /// The vehicle id, UTF-8.
    fn vehicle_id(&self) -> Result<Vec<u8>, String>;
    /// The vehicle snapshot, JSON.
    fn vehicle(&self) -> Result<Vec<u8>, String>;
    /// The swarm, JSON array.
    fn swarm(&self) -> Result<Vec<u8>, String>;
    /// Simulated vehicle?
    fn simulated(&self) -> bool;
    /// Sends a MAVLink 2 frame's message.
    fn send_mavlink(&self, frame: &[u8]) -> Result<(), String>;
    /// Raises an event.
    fn emit_event(&self, kind: &[u8], data_json: &[u8]) -> Result<(), String>;
    /// Publishes the state (JSON object).
    fn publish_state(&self, state_json: &[u8]) -> Result<(), String>;
    /// Another slot's state, JSON (`null` when none).
    fn payload_state(&self, slot: &[u8]) -> Result<Vec<u8>, String>;
    /// Publishes a JPEG frame.
    fn publish_frame(&self, jpeg: &[u8]) -> Result<(), String>;
    /// Degrades the simulated link; true when applied.
    fn set_simulated_link(&self, loss_fraction: f64, latency_ms: f64) -> bool;
    /// A log line.
    fn log(&self, level: u32, message: &[u8]);
    /// The simulated non-cooperative aircraft, JSON array.
    fn sim_aircraft(&self) -> Result<Vec<u8>, String>;
    /// Another slot's latest frame, JPEG (empty when none).
    fn payload_frame(&self, slot: &[u8]) -> Result<Vec<u8>, String>;
}

/// The services of one payload instance on top of its vehicle's [`PayloadHost`].
pub(crate) struct HostServices {
    host: Arc<dyn PayloadHost>,
    plugin: String,
    slot: String,
    decoder: Mutex<Decoder>,
}

impl HostServices {
    /// Services for the instance in `slot` of plugin `plugin`.
    pub fn new(host: Arc<dyn PayloadHost>, plugin: &str, slot: &str) -> HostServices {
        HostServices {
            host,
            plugin: plugin.to_string(),
            slot: slot.to_string(),
            decoder: Mutex::new(Decoder::default()),
        }
    }

    /// The vehicle's id.
    pub fn host_vehicle_id(&self) -> String {
        self.host.vehicle_id().to_string()
    }
}

fn text(bytes: &[u8], what: &str) -> Result<String, String> {
    String::from_utf8(bytes.to_vec()).map_err(|_| format!("{what} is not UTF-8"))
}

impl Services for HostServices {
    fn vehicle_id(&self) -> Result<Vec<u8>, String> {
        Ok(self.host.vehicle_id().as_bytes().to_vec())
    }

    fn vehicle(&self) -> Result<Vec<u8>, String> {
        serde_json::to_vec(&self.host.vehicle()).map_err(|e| e.to_string())
    }

    fn swarm(&self) -> Result<Vec<u8>, String> {
        serde_json::to_vec(&self.host.swarm()).map_err(|e| e.to_string())
    }

    fn simulated(&self) -> bool {
        self.host.simulated()
    }

    fn send_mavlink(&self, frame: &[u8]) -> Result<(), String> {
        let mut msg = None;
        self.decoder
            .lock()
            .map_err(|_| "MAVLink decoder poisoned".to_string())?
            .decode_datagram(frame, |f| msg = Some(f.msg));
        let msg = msg.ok_or("send_mavlink: not a valid MAVLink frame of the common dialect")?;
        self.host.send_mavlink(&msg)
    }

    fn emit_event(&self, kind: &[u8], data_json: &[u8]) -> Result<(), String> {
        let kind = text(kind, "event kind")?;
        let data: serde_json::Value = serde_json::from_slice(data_json)
            .map_err(|e| format!("event data is not valid JSON: {e}"))?;
        self.host.emit_event(&kind, data);
        Ok(())
    }

    fn publish_state(&self, state_json: &[u8]) -> Result<(), String> {
        let state: serde_json::Value = serde_json::from_slice(state_json)
            .map_err(|e| format!("state is not valid JSON: {e}"))?;
        if !state.is_object() {
            return Err("a payload state must be a JSON object".into());
        }
        self.host.publish_state(state);
        Ok(())
    }

    fn payload_state(&self, slot: &[u8]) -> Result<Vec<u8>, String> {
        let slot = text(slot, "slot")?;
        let state = self
            .host
            .payload_state(&slot)
            .unwrap_or(serde_json::Value::Null);
        serde_json::to_vec(&state).map_err(|e| e.to_string())
    }

    fn publish_frame(&self, jpeg: &[u8]) -> Result<(), String> {
        // A JPEG starts with SOI (FF D8) and ends with EOI (FF D9).
        if jpeg.len() < 4 || jpeg[..2] != [0xFF, 0xD8] || jpeg[jpeg.len() - 2..] != [0xFF, 0xD9] {
            return Err("publish_frame: not a JPEG image (no SOI/EOI markers)".into());
        }
        self.host.publish_frame(jpeg.to_vec());
        Ok(())
    }

    fn set_simulated_link(&self, loss_fraction: f64, latency_ms: f64) -> bool {
        let valid =
            (0.0..=1.0).contains(&loss_fraction) && latency_ms.is_finite() && latency_ms >= 0.0;
        if !valid {
            tracing::warn!(
                plugin = %self.plugin, slot = %self.slot,
                "set_simulated_link ignored: loss {loss_fraction} not in [0, 1] or latency {latency_ms} ms negative"
            );
            return false;
        }
        self.host.set_simulated_link(loss_fraction, latency_ms)
    }

    fn sim_aircraft(&self) -> Result<Vec<u8>, String> {
        serde_json::to_vec(&self.host.sim_aircraft()).map_err(|e| e.to_string())
    }

    fn payload_frame(&self, slot: &[u8]) -> Result<Vec<u8>, String> {
        let slot = text(slot, "slot")?;
        Ok(self
            .host
            .payload_frame(&slot)
            .map(|f| f.as_ref().clone())
            .unwrap_or_default())
    }

    fn log(&self, level: u32, message: &[u8]) {
        let message = String::from_utf8_lossy(message);
        let vehicle = self.host.vehicle_id();
        let (plugin, slot) = (self.plugin.as_str(), self.slot.as_str());
        match level {
            log_level::ERROR => tracing::error!(plugin, vehicle, slot, "{message}"),
            log_level::WARN => tracing::warn!(plugin, vehicle, slot, "{message}"),
            log_level::INFO => tracing::info!(plugin, vehicle, slot, "{message}"),
            _ => tracing::debug!(plugin, vehicle, slot, "{message}"),
        }
    }
}

/// Runs a service under `catch_unwind` (the host's `PayloadHost` is not ours to trust not
/// to panic, and a panic must not unwind into the plugin) and writes its output.
fn guarded(out: RawSink, f: impl FnOnce() -> Result<Vec<u8>, String>) -> u32 {
    let (st, bytes) = match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(b)) => (status::OK, b),
        Ok(Err(e)) => (status::ERROR, e.into_bytes()),
        Err(p) => {
            let msg = p
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| p.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "panic".into());
            (status::PANIC, msg.into_bytes())
        }
    };
    // SAFETY: `out` is the sink the plugin passed to this callback; its storage lives until
    // the callback returns.
    unsafe { out.put(&bytes) };
    st
}

/// # Safety
/// `ctx` must be the `&S` the table was built with, alive for the call.
unsafe fn services<'a, S: Services>(ctx: *const c_void) -> &'a S {
    // SAFETY: guaranteed by the caller.
    unsafe { &*(ctx as *const S) }
}

/// # Safety
/// `b` must be valid for the call (the ABI guarantees it for arguments).
unsafe fn bytes<'a>(b: RawBytes) -> &'a [u8] {
    // SAFETY: guaranteed by the caller.
    unsafe { b.as_slice() }
}

unsafe extern "C" fn t_vehicle_id<S: Services>(ctx: *const c_void, out: RawSink) -> u32 {
    // SAFETY: `ctx` is the services pointer of the table (see `host_api`).
    let s = unsafe { services::<S>(ctx) };
    guarded(out, || s.vehicle_id())
}

unsafe extern "C" fn t_vehicle<S: Services>(ctx: *const c_void, out: RawSink) -> u32 {
    // SAFETY: as in `t_vehicle_id`.
    let s = unsafe { services::<S>(ctx) };
    guarded(out, || s.vehicle())
}

unsafe extern "C" fn t_swarm<S: Services>(ctx: *const c_void, out: RawSink) -> u32 {
    // SAFETY: as in `t_vehicle_id`.
    let s = unsafe { services::<S>(ctx) };
    guarded(out, || s.swarm())
}

unsafe extern "C" fn t_simulated<S: Services>(ctx: *const c_void) -> u32 {
    // SAFETY: as in `t_vehicle_id`.
    let s = unsafe { services::<S>(ctx) };
    catch_unwind(AssertUnwindSafe(|| u32::from(s.simulated()))).unwrap_or(0)
}

unsafe extern "C" fn t_send_mavlink<S: Services>(
    ctx: *const c_void,
    frame: RawBytes,
    err: RawSink,
) -> u32 {
    // SAFETY: as in `t_vehicle_id`; `frame` is valid for the call.
    let (s, frame) = unsafe { (services::<S>(ctx), bytes(frame)) };
    guarded(err, || s.send_mavlink(frame).map(|_| Vec::new()))
}

unsafe extern "C" fn t_emit_event<S: Services>(
    ctx: *const c_void,
    kind: RawBytes,
    data: RawBytes,
    err: RawSink,
) -> u32 {
    // SAFETY: as in `t_send_mavlink`.
    let (s, kind, data) = unsafe { (services::<S>(ctx), bytes(kind), bytes(data)) };
    guarded(err, || s.emit_event(kind, data).map(|_| Vec::new()))
}

unsafe extern "C" fn t_publish_state<S: Services>(
    ctx: *const c_void,
    state: RawBytes,
    err: RawSink,
) -> u32 {
    // SAFETY: as in `t_send_mavlink`.
    let (s, state) = unsafe { (services::<S>(ctx), bytes(state)) };
    guarded(err, || s.publish_state(state).map(|_| Vec::new()))
}

unsafe extern "C" fn t_payload_state<S: Services>(
    ctx: *const c_void,
    slot: RawBytes,
    out: RawSink,
) -> u32 {
    // SAFETY: as in `t_send_mavlink`.
    let (s, slot) = unsafe { (services::<S>(ctx), bytes(slot)) };
    guarded(out, || s.payload_state(slot))
}

unsafe extern "C" fn t_publish_frame<S: Services>(
    ctx: *const c_void,
    jpeg: RawBytes,
    err: RawSink,
) -> u32 {
    // SAFETY: as in `t_send_mavlink`.
    let (s, jpeg) = unsafe { (services::<S>(ctx), bytes(jpeg)) };
    guarded(err, || s.publish_frame(jpeg).map(|_| Vec::new()))
}

unsafe extern "C" fn t_set_simulated_link<S: Services>(
    ctx: *const c_void,
    loss_fraction: f64,
    latency_ms: f64,
) -> u32 {
    // SAFETY: as in `t_vehicle_id`.
    let s = unsafe { services::<S>(ctx) };
    catch_unwind(AssertUnwindSafe(|| {
        u32::from(s.set_simulated_link(loss_fraction, latency_ms))
    }))
    .unwrap_or(0)
}

unsafe extern "C" fn t_sim_aircraft<S: Services>(ctx: *const c_void, out: RawSink) -> u32 {
    // SAFETY: as in `t_vehicle_id`.
    let s = unsafe { services::<S>(ctx) };
    guarded(out, || s.sim_aircraft())
}

unsafe extern "C" fn t_payload_frame<S: Services>(
    ctx: *const c_void,
    slot: RawBytes,
    out: RawSink,
) -> u32 {
    // SAFETY: as in `t_send_mavlink`.
    let (s, slot) = unsafe { (services::<S>(ctx), bytes(slot)) };
    guarded(out, || s.payload_frame(slot))
}

unsafe extern "C" fn t_log<S: Services>(ctx: *const c_void, level: u32, message: RawBytes) {
    // SAFETY: as in `t_send_mavlink`.
    let (s, message) = unsafe { (services::<S>(ctx), bytes(message)) };
    let _ = catch_unwind(AssertUnwindSafe(|| s.log(level, message)));
}

/// The [`HostApi`] table over `services`. The table holds a raw pointer to `services`:
/// keep `services` alive and in place (boxed) for as long as the table is used.
pub(crate) fn host_api<S: Services>(services: &S) -> HostApi {
    HostApi {
        abi_version: ABI_VERSION,
        struct_size: std::mem::size_of::<HostApi>() as u32,
        ctx: services as *const S as *const c_void,
        vehicle_id: t_vehicle_id::<S>,
        vehicle: t_vehicle::<S>,
        swarm: t_swarm::<S>,
        simulated: t_simulated::<S>,
        send_mavlink: t_send_mavlink::<S>,
        emit_event: t_emit_event::<S>,
        publish_state: t_publish_state::<S>,
        payload_state: t_payload_state::<S>,
        publish_frame: t_publish_frame::<S>,
        set_simulated_link: t_set_simulated_link::<S>,
        log: t_log::<S>,
        sim_aircraft: t_sim_aircraft::<S>,
        payload_frame: t_payload_frame::<S>,
    }
}
