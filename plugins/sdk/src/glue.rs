//! The export glue behind [`crate::export_plugin!`]: the C functions of the vtable, each
//! generic over the plugin type and monomorphised inside the plugin library, each wrapping
//! the plugin's code in `catch_unwind` so that no panic ever unwinds across `extern "C"`
//! (the plugin has its own copy of std: an unwind into the host would abort the process).
//!
//! Not part of the public API: only the macro uses it.

use crate::abi::{ABI_VERSION, HostApi, PluginVTable, RawBytes, RawSink, build_stamp, status};
use crate::context::Context;
use crate::plugin::Plugin;
use serde_json::Value;
use skein_mavlink::Decoder;
use std::any::Any;
use std::collections::HashMap;
use std::ffi::c_void;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::{Mutex, Once, OnceLock};
use std::thread::ThreadId;

/// The plugin's vtable and the storage its pointers point into. Built once per library
/// (in the `OnceLock` the macro declares) and never moved or modified after.
pub struct Descriptor {
    vtable: PluginVTable,
    _stamp: String,
    _kinds: Vec<RawBytes>,
}

// SAFETY: a `Descriptor` is immutable once built; its raw pointers point into its own
// heap storage (`_stamp`, `_kinds`) or into `'static` strings, so sharing it between
// threads is sound.
unsafe impl Sync for Descriptor {}
// SAFETY: as above; nothing in it is tied to a thread.
unsafe impl Send for Descriptor {}

impl Descriptor {
    fn new<T: Plugin>(abi_version: u32, stamp: Option<String>) -> Descriptor {
        let stamp = stamp.unwrap_or_else(build_stamp);
        let kinds: Vec<RawBytes> = T::KINDS
            .iter()
            .map(|k| RawBytes::from_slice(k.as_bytes()))
            .collect();
        let vtable = PluginVTable {
            abi_version,
            struct_size: std::mem::size_of::<PluginVTable>() as u32,
            build_stamp: RawBytes::from_slice(stamp.as_bytes()),
            name: RawBytes::from_slice(T::NAME.as_bytes()),
            version: RawBytes::from_slice(T::VERSION.as_bytes()),
            kinds: kinds.as_ptr(),
            kinds_len: kinds.len(),
            create: create::<T>,
            destroy: destroy::<T>,
            tick_rate_hz: tick_rate_hz::<T>,
            tick: tick::<T>,
            handle: handle::<T>,
            on_mavlink: on_mavlink::<T>,
        };
        Descriptor {
            vtable,
            _stamp: stamp,
            _kinds: kinds,
        }
    }
}

/// The body of the exported entry point: installs the plugin's panic hook, builds the
/// descriptor once, returns its vtable (null if building it panicked).
pub fn entry<T: Plugin>(
    cell: &'static OnceLock<Descriptor>,
    abi_version: u32,
    stamp: Option<String>,
) -> *const PluginVTable {
    install_panic_hook(T::NAME);
    catch_unwind(AssertUnwindSafe(|| {
        &cell
            .get_or_init(|| Descriptor::new::<T>(abi_version, stamp))
            .vtable as *const PluginVTable
    }))
    .unwrap_or(std::ptr::null())
}

/// Panic locations recorded by the hook, per thread, taken by [`guard`].
static PANIC_LOCATIONS: Mutex<Option<HashMap<ThreadId, String>>> = Mutex::new(None);
static HOOK: Once = Once::new();

fn install_panic_hook(plugin: &'static str) {
    HOOK.call_once(|| {
        // One short line per panic, no backtrace: a plugin that panics in a tick at 20 Hz
        // would otherwise flood the log and slow its restart.
        std::panic::set_hook(Box::new(move |info| {
            let loc = info
                .location()
                .map(|l| format!("{}:{}", l.file(), l.line()))
                .unwrap_or_else(|| "unknown location".into());
            eprintln!(
                "skein plugin `{plugin}` panicked at {loc}: {}",
                payload_text(info.payload())
            );
            if let Ok(mut map) = PANIC_LOCATIONS.lock() {
                map.get_or_insert_with(HashMap::new)
                    .insert(std::thread::current().id(), loc);
            }
        }));
    });
}

fn payload_text(payload: &(dyn Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "non-string panic payload".to_string()
    }
}

fn panic_message(payload: Box<dyn Any + Send>) -> String {
    let text = payload_text(payload.as_ref());
    // Dropping a payload can itself panic (a payload type with a panicking Drop).
    let _ = catch_unwind(AssertUnwindSafe(move || drop(payload)));
    let loc = PANIC_LOCATIONS
        .lock()
        .ok()
        .and_then(|mut m| m.as_mut()?.remove(&std::thread::current().id()));
    match loc {
        Some(loc) => format!("{text} (at {loc})"),
        None => text,
    }
}

/// Writes `bytes` to the caller's sink.
fn put(out: RawSink, bytes: &[u8]) {
    // SAFETY: `out` is the sink the host passed to the call being executed; the host keeps
    // its storage alive until the call returns.
    unsafe { out.put(bytes) }
}

/// Runs `f` under `catch_unwind` and turns its outcome into a status code plus sink output.
/// On a panic, returns the message as the second value too.
fn guard(out: RawSink, f: impl FnOnce() -> Result<Vec<u8>, String>) -> (u32, Option<String>) {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(bytes)) => {
            put(out, &bytes);
            (status::OK, None)
        }
        Ok(Err(msg)) => {
            put(out, msg.as_bytes());
            (status::ERROR, None)
        }
        Err(payload) => {
            let msg = panic_message(payload);
            put(out, msg.as_bytes());
            (status::PANIC, Some(msg))
        }
    }
}

/// One live instance: the plugin value, its host services, and whether it panicked.
struct Instance<T> {
    plugin: T,
    host: *const HostApi,
    poisoned: Option<String>,
    decoder: Decoder,
}

/// Runs `f` on the instance behind `instance` with its context, guarded; poisons the
/// instance when `f` panics; refuses to run on a poisoned instance.
///
/// # Safety
/// `instance` must be null or a pointer returned by `create::<T>` and not yet destroyed,
/// not used concurrently by another call.
unsafe fn with_instance<T: Plugin>(
    instance: *mut c_void,
    out: RawSink,
    op: &str,
    f: impl FnOnce(&mut Instance<T>, &Context) -> Result<Vec<u8>, String>,
) -> u32 {
    if instance.is_null() {
        put(
            out,
            format!("`{op}` called with a null instance").as_bytes(),
        );
        return status::ERROR;
    }
    // SAFETY: guaranteed by the caller: a live `Instance<T>` made by `create::<T>`,
    // exclusively ours for this call.
    let inst = unsafe { &mut *(instance as *mut Instance<T>) };
    if let Some(why) = &inst.poisoned {
        put(
            out,
            format!("instance is poisoned: it panicked earlier ({why}); re-create it").as_bytes(),
        );
        return status::ERROR;
    }
    // SAFETY: `inst.host` is the HostApi the host passed to `create`, valid until destroy.
    let Some(ctx) = (unsafe { Context::from_raw(inst.host) }) else {
        put(out, b"instance has no host services");
        return status::ERROR;
    };
    let (st, panic) = guard(out, || f(inst, &ctx));
    if let Some(msg) = panic {
        inst.poisoned = Some(msg);
    }
    st
}

unsafe extern "C" fn create<T: Plugin>(
    kind: RawBytes,
    config_json: RawBytes,
    host: *const HostApi,
    out_instance: *mut *mut c_void,
    out: RawSink,
) -> u32 {
    guard(out, || {
        if out_instance.is_null() {
            return Err("`create` called without a place for the instance".into());
        }
        // SAFETY: the host passes a HostApi valid until `destroy`, or null (checked).
        let host_ref = unsafe { host.as_ref() }.ok_or("`create` called without host services")?;
        if host_ref.abi_version != ABI_VERSION {
            return Err(format!(
                "host services are ABI {}, plugin `{}` is ABI {ABI_VERSION}",
                host_ref.abi_version,
                T::NAME
            ));
        }
        if (host_ref.struct_size as usize) < std::mem::size_of::<HostApi>() {
            return Err(format!(
                "host services table is {} bytes, plugin `{}` needs {}",
                host_ref.struct_size,
                T::NAME,
                std::mem::size_of::<HostApi>()
            ));
        }
        // SAFETY: the host keeps `kind` and `config_json` alive for this call.
        let (kind, config) = unsafe { (kind.as_slice(), config_json.as_slice()) };
        let kind = std::str::from_utf8(kind).map_err(|_| "payload kind is not UTF-8")?;
        if !T::KINDS.contains(&kind) {
            return Err(format!(
                "plugin `{}` does not provide payload kind `{kind}` (it provides: {})",
                T::NAME,
                T::KINDS.join(", ")
            ));
        }
        let config: Value = if config.is_empty() {
            Value::Null
        } else {
            serde_json::from_slice(config).map_err(|e| format!("config is not valid JSON: {e}"))?
        };
        // SAFETY: validated above; valid for this call.
        let ctx = unsafe { Context::from_raw(host) }.ok_or("no host services")?;
        let plugin = T::create(kind, config, &ctx)?;
        let info = serde_json::json!({ "mavlink": plugin.mavlink_interest().to_json() });
        let instance = Box::new(Instance {
            plugin,
            host,
            poisoned: None,
            decoder: Decoder::default(),
        });
        // SAFETY: `out_instance` is non-null (checked) and points to writable storage of
        // the host's.
        unsafe { *out_instance = Box::into_raw(instance) as *mut c_void };
        serde_json::to_vec(&info).map_err(|e| e.to_string())
    })
    .0
}

unsafe extern "C" fn destroy<T: Plugin>(instance: *mut c_void, err: RawSink) -> u32 {
    if instance.is_null() {
        return status::OK;
    }
    // SAFETY: the host passes an instance made by `create::<T>` exactly once to destroy;
    // we take ownership back.
    let mut inst = unsafe { Box::from_raw(instance as *mut Instance<T>) };
    let (st, _) = guard(err, || {
        // A poisoned instance may be in a broken state: skip its shutdown, only drop it.
        if inst.poisoned.is_none() {
            // SAFETY: the HostApi stays valid until `destroy` returns.
            if let Some(ctx) = unsafe { Context::from_raw(inst.host) } {
                inst.plugin.shutdown(&ctx);
            }
        }
        Ok(Vec::new())
    });
    let (drop_st, _) = guard(err, move || {
        drop(inst);
        Ok(Vec::new())
    });
    if st != status::OK { st } else { drop_st }
}

unsafe extern "C" fn tick_rate_hz<T: Plugin>(
    instance: *mut c_void,
    out_hz: *mut f64,
    err: RawSink,
) -> u32 {
    // SAFETY: forwarded contract of the vtable (a live instance, exclusive for this call).
    unsafe {
        with_instance::<T>(instance, err, "tick_rate_hz", |inst, _| {
            let hz = inst.plugin.tick_rate_hz();
            if out_hz.is_null() {
                return Err("`tick_rate_hz` called without an output".into());
            }
            // SAFETY: non-null (checked), the host's storage for this call.
            *out_hz = if hz.is_finite() && hz > 0.0 { hz } else { 0.0 };
            Ok(Vec::new())
        })
    }
}

unsafe extern "C" fn tick<T: Plugin>(instance: *mut c_void, dt_s: f64, err: RawSink) -> u32 {
    // SAFETY: forwarded contract of the vtable.
    unsafe {
        with_instance::<T>(instance, err, "tick", |inst, ctx| {
            inst.plugin.tick(ctx, dt_s).map(|_| Vec::new())
        })
    }
}

unsafe extern "C" fn handle<T: Plugin>(
    instance: *mut c_void,
    command_json: RawBytes,
    out: RawSink,
) -> u32 {
    // SAFETY: forwarded contract of the vtable; the host keeps `command_json` alive.
    unsafe {
        with_instance::<T>(instance, out, "handle", |inst, ctx| {
            let bytes = command_json.as_slice();
            let command: Value = serde_json::from_slice(bytes)
                .map_err(|e| format!("command is not valid JSON: {e}"))?;
            let reply = inst.plugin.handle(ctx, command)?;
            serde_json::to_vec(&reply).map_err(|e| e.to_string())
        })
    }
}

unsafe extern "C" fn on_mavlink<T: Plugin>(
    instance: *mut c_void,
    compid: u8,
    frame: RawBytes,
    err: RawSink,
) -> u32 {
    // SAFETY: forwarded contract of the vtable; the host keeps `frame` alive.
    unsafe {
        with_instance::<T>(instance, err, "on_mavlink", |inst, ctx| {
            let mut decoded = None;
            inst.decoder
                .decode_datagram(frame.as_slice(), |f| decoded = Some(f.msg));
            let msg = decoded.ok_or("on_mavlink: the frame is not a valid MAVLink 2 frame")?;
            inst.plugin
                .on_mavlink(ctx, compid, &msg)
                .map(|_| Vec::new())
        })
    }
}
