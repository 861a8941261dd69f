//! The C ABI between skein (the host) and a plugin library.
//!
//! Everything here is `#[repr(C)]` and crosses the boundary by value or by pointer; no
//! Rust type with a layout of its own (no `String`, `Vec`, trait object, `serde_json::Value`)
//! ever does. Payloads travel as bytes:
//!
//! | what | encoding |
//! |---|---|
//! | config, commands, replies, state, events, vehicle snapshots | UTF-8 JSON |
//! | MAVLink | one MAVLink 2 frame (common dialect), as on the wire |
//! | video frames | one baseline JPEG image |
//! | errors | UTF-8 text, shown to the operator as it is |
//!
//! # Entry point
//! A plugin library exports one symbol, [`ENTRY_SYMBOL`] (`skein_plugin_entry`), of type
//! [`EntryFn`]: it returns a pointer to a [`PluginVTable`] that lives as long as the library
//! is mapped (or null if the plugin could not describe itself).
//!
//! # Versioning rules
//! - The first three fields of [`PluginVTable`] (`abi_version: u32`, `struct_size: u32`,
//!   `build_stamp: RawBytes`) are frozen forever, so any host can read them from any plugin.
//!   The host reads them and nothing else until they match: first `abi_version`, then
//!   `struct_size`, then the build stamp.
//! - [`ABI_VERSION`] changes whenever the layout or meaning of anything in this module
//!   changes (a field added, a signature or status code changed). Host and plugin must agree
//!   exactly.
//! - The build stamp ([`build_stamp`]) names what the bytes mean beyond the layout: the
//!   message generation ([`MESSAGES_VERSION`], bumped when a JSON shape the host sends, such
//!   as the vehicle snapshot, changes incompatibly), the MAVLink dialect, and the target
//!   (architecture, OS, pointer width, endianness). It is `key=value` pairs joined by `;` so
//!   a mismatch can name the key that differs. The SDK's crate version is deliberately *not*
//!   part of it: a plugin built with an older SDK of the same ABI and message generation
//!   keeps working.
//! - [`HostApi`] carries its own `abi_version` and `struct_size`, checked by the plugin at
//!   `create`.
//!
//! # Threads and panics
//! The host calls one instance from one thread at a time, but successive calls may come
//! from different threads (instances must be `Send`). Different instances may be called
//! concurrently. Nothing may unwind across any function of this module: every plugin export
//! and every host callback catches its own panics and reports them as [`status::PANIC`].
//!
//! # Memory
//! Bytes handed *into* a call ([`RawBytes`]) are borrowed for the duration of the call only.
//! Bytes handed *out* are written through a [`RawSink`] owned by the caller, so each side
//! only ever frees memory its own allocator produced.

use std::ffi::c_void;

/// Version of this ABI (layouts and meanings of everything in this module).
pub const ABI_VERSION: u32 = 2;

/// Generation of the message formats (the JSON the host sends: vehicle snapshots, swarm
/// lists, payload states; the MAVLink dialect). Part of the build stamp.
pub const MESSAGES_VERSION: u32 = 1;

/// Name of the symbol every plugin library exports.
pub const ENTRY_SYMBOL: &str = "skein_plugin_entry";

/// [`ENTRY_SYMBOL`] with its terminating NUL, as `dlsym` wants it.
pub const ENTRY_SYMBOL_NUL: &[u8] = b"skein_plugin_entry\0";

/// Type of the entry point: returns the plugin's vtable (valid while the library is
/// mapped), or null when the plugin failed to describe itself (it panicked).
pub type EntryFn = unsafe extern "C" fn() -> *const PluginVTable;

/// Status codes returned by every fallible function of the ABI.
pub mod status {
    /// Success; the sink (if any) holds the result.
    pub const OK: u32 = 0;
    /// The callee refused or failed; the sink holds a UTF-8 error message.
    pub const ERROR: u32 = 1;
    /// The callee panicked (and caught it); the sink holds the panic message. A plugin
    /// instance that panicked is poisoned: every later call returns [`ERROR`].
    pub const PANIC: u32 = 2;
}

/// Log levels of [`HostApi::log`].
pub mod log_level {
    /// Errors.
    pub const ERROR: u32 = 1;
    /// Warnings.
    pub const WARN: u32 = 2;
    /// Information.
    pub const INFO: u32 = 3;
    /// Debugging detail.
    pub const DEBUG: u32 = 4;
}

/// A borrowed byte string: `len` bytes at `ptr` (`ptr` may be dangling or null when `len`
/// is 0). Valid for the duration of the call it is passed to, or, in [`PluginVTable`], for
/// as long as the library is mapped.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct RawBytes {
    /// First byte.
    pub ptr: *const u8,
    /// Number of bytes.
    pub len: usize,
}

impl RawBytes {
    /// A view of `bytes` (borrowed: keep `bytes` alive while the view is used).
    pub fn from_slice(bytes: &[u8]) -> RawBytes {
        RawBytes {
            ptr: bytes.as_ptr(),
            len: bytes.len(),
        }
    }

    /// The empty byte string.
    pub const EMPTY: RawBytes = RawBytes {
        ptr: std::ptr::null(),
        len: 0,
    };

    /// The bytes.
    ///
    /// # Safety
    /// `ptr` must point to `len` initialised bytes that stay valid and unmodified for `'a`
    /// (or `len` must be 0).
    pub unsafe fn as_slice<'a>(self) -> &'a [u8] {
        if self.len == 0 || self.ptr.is_null() {
            &[]
        } else {
            // SAFETY: guaranteed by the caller (see above).
            unsafe { std::slice::from_raw_parts(self.ptr, self.len) }
        }
    }
}

/// Where a callee writes its output (a reply, an error message): `write(ctx, ptr, len)`
/// appends `len` bytes. The caller owns the storage behind `ctx`; the callee may call
/// `write` any number of times during the call and never after it returns.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct RawSink {
    /// The caller's storage.
    pub ctx: *mut c_void,
    /// Appends bytes to the storage. Must not unwind.
    pub write: unsafe extern "C" fn(ctx: *mut c_void, ptr: *const u8, len: usize),
}

unsafe extern "C" fn write_to_vec(ctx: *mut c_void, ptr: *const u8, len: usize) {
    if ctx.is_null() || (ptr.is_null() && len > 0) {
        return;
    }
    // SAFETY: `ctx` was made from `&mut Vec<u8>` by `RawSink::for_vec`, whose borrow lasts
    // for the call this sink was passed to; the callee guarantees `ptr` holds `len` bytes.
    let (vec, bytes) = unsafe {
        (
            &mut *(ctx as *mut Vec<u8>),
            RawBytes { ptr, len }.as_slice(),
        )
    };
    // Only an allocation failure can fail here, and that aborts rather than unwinds.
    vec.extend_from_slice(bytes);
}

impl RawSink {
    /// A sink that appends to `out`. The sink borrows `out`: use it only while `out` is
    /// alive and not otherwise accessed (i.e. pass it to one call and read `out` after).
    pub fn for_vec(out: &mut Vec<u8>) -> RawSink {
        RawSink {
            ctx: out as *mut Vec<u8> as *mut c_void,
            write: write_to_vec,
        }
    }

    /// Appends `bytes`.
    ///
    /// # Safety
    /// The sink must be one passed to the current call (its storage alive).
    pub unsafe fn put(&self, bytes: &[u8]) {
        // SAFETY: the caller vouches for the sink; `bytes` is a valid slice.
        unsafe { (self.write)(self.ctx, bytes.as_ptr(), bytes.len()) }
    }
}

/// Creates an instance. `kind`: UTF-8 payload kind (one of the vtable's `kinds`);
/// `config_json`: the instance's JSON configuration (`PayloadSpec.config`, may be empty for
/// `null`); `host`: the host services for this instance, valid until `destroy` returns.
/// On [`status::OK`], `*out_instance` is the new instance and `out` holds the instance's
/// info JSON: `{"mavlink": "none" | "all" | [message ids]}`. Otherwise `out` holds the
/// error.
pub type CreateFn = unsafe extern "C" fn(
    kind: RawBytes,
    config_json: RawBytes,
    host: *const HostApi,
    out_instance: *mut *mut c_void,
    out: RawSink,
) -> u32;

/// Destroys an instance (runs its shutdown, then drops it). Always frees the instance;
/// returns [`status::PANIC`] with the message in `err` when its shutdown or drop panicked.
pub type DestroyFn = unsafe extern "C" fn(instance: *mut c_void, err: RawSink) -> u32;

/// Ticks per second the instance wants (0 = no ticks), written to `*out_hz`.
pub type TickRateFn =
    unsafe extern "C" fn(instance: *mut c_void, out_hz: *mut f64, err: RawSink) -> u32;

/// Periodic work; `dt_s` seconds since the previous tick. Errors go to `err`.
pub type TickFn = unsafe extern "C" fn(instance: *mut c_void, dt_s: f64, err: RawSink) -> u32;

/// An operator command (UTF-8 JSON); the reply JSON (or the error) goes to `out`.
pub type HandleFn =
    unsafe extern "C" fn(instance: *mut c_void, command_json: RawBytes, out: RawSink) -> u32;

/// A MAVLink message from the vehicle's component `compid`, as one MAVLink 2 frame (its
/// header's system and component ids are informative only). Errors go to `err`.
pub type OnMavlinkFn =
    unsafe extern "C" fn(instance: *mut c_void, compid: u8, frame: RawBytes, err: RawSink) -> u32;

/// What a plugin library exports (through [`EntryFn`]).
#[repr(C)]
#[derive(Debug)]
pub struct PluginVTable {
    /// Frozen: the [`ABI_VERSION`] the plugin was built for.
    pub abi_version: u32,
    /// Frozen: `size_of::<PluginVTable>()` in the plugin's build.
    pub struct_size: u32,
    /// Frozen: the plugin's [`build_stamp`] (UTF-8).
    pub build_stamp: RawBytes,
    /// Plugin name (UTF-8, unique among loaded plugins, e.g. `"gimbal"`).
    pub name: RawBytes,
    /// Plugin version (UTF-8, e.g. `"0.1.0"`).
    pub version: RawBytes,
    /// Payload kinds the plugin provides: `kinds_len` UTF-8 strings at `kinds`.
    pub kinds: *const RawBytes,
    /// Number of kinds (at least 1).
    pub kinds_len: usize,
    /// See [`CreateFn`].
    pub create: CreateFn,
    /// See [`DestroyFn`].
    pub destroy: DestroyFn,
    /// See [`TickRateFn`].
    pub tick_rate_hz: TickRateFn,
    /// See [`TickFn`].
    pub tick: TickFn,
    /// See [`HandleFn`].
    pub handle: HandleFn,
    /// See [`OnMavlinkFn`].
    pub on_mavlink: OnMavlinkFn,
}

/// Host services for one plugin instance, passed to `create` and valid until `destroy`
/// returns. `ctx` is the host's and is passed back to every callback. Callbacks may be
/// called only from within a call of the host into this instance (they are synchronous and
/// never block for long). Each returns a [`status`] code; output goes to the given sink.
#[repr(C)]
#[derive(Debug)]
pub struct HostApi {
    /// The [`ABI_VERSION`] the host was built for.
    pub abi_version: u32,
    /// `size_of::<HostApi>()` in the host's build.
    pub struct_size: u32,
    /// The host's context for this instance.
    pub ctx: *const c_void,
    /// The vehicle's id (`"uav-1"`), UTF-8, to `out`.
    pub vehicle_id: unsafe extern "C" fn(ctx: *const c_void, out: RawSink) -> u32,
    /// The vehicle's snapshot as JSON (the `GET /api/v1/vehicles/{id}` object), to `out`.
    pub vehicle: unsafe extern "C" fn(ctx: *const c_void, out: RawSink) -> u32,
    /// Every vehicle of the swarm, a JSON array of snapshots, to `out`.
    pub swarm: unsafe extern "C" fn(ctx: *const c_void, out: RawSink) -> u32,
    /// 1 when the vehicle is simulated, 0 when it is real.
    pub simulated: unsafe extern "C" fn(ctx: *const c_void) -> u32,
    /// Sends one MAVLink 2 frame's message to the vehicle's system, from skein's identity
    /// (the frame's own sysid, compid and sequence are ignored). Errors to `err`.
    pub send_mavlink:
        unsafe extern "C" fn(ctx: *const c_void, frame: RawBytes, err: RawSink) -> u32,
    /// Raises an event: `kind` (UTF-8), `data_json` (JSON). Errors to `err`.
    pub emit_event: unsafe extern "C" fn(
        ctx: *const c_void,
        kind: RawBytes,
        data_json: RawBytes,
        err: RawSink,
    ) -> u32,
    /// Publishes the instance's state (a JSON object). Errors to `err`.
    pub publish_state:
        unsafe extern "C" fn(ctx: *const c_void, state_json: RawBytes, err: RawSink) -> u32,
    /// The state another payload of the same vehicle published, by slot (UTF-8): JSON to
    /// `out`, `null` when that slot has published nothing.
    pub payload_state:
        unsafe extern "C" fn(ctx: *const c_void, slot: RawBytes, out: RawSink) -> u32,
    /// Publishes one video frame (a JPEG image). Errors to `err`.
    pub publish_frame:
        unsafe extern "C" fn(ctx: *const c_void, jpeg: RawBytes, err: RawSink) -> u32,
    /// Degrades the simulated link of the vehicle: `loss_fraction` of datagrams dropped
    /// (0..1), `latency_ms` one-way delay added. Returns 1 when a simulator applied it,
    /// 0 otherwise.
    pub set_simulated_link:
        unsafe extern "C" fn(ctx: *const c_void, loss_fraction: f64, latency_ms: f64) -> u32,
    /// A log line (UTF-8) at a [`log_level`], attributed to the instance.
    pub log: unsafe extern "C" fn(ctx: *const c_void, level: u32, message: RawBytes),
    /// The simulated non-cooperative aircraft (intruders) near a simulated vehicle, a JSON
    /// array of `{"id", "north_m", "east_m", "down_m", "velocity": {"north_m_s", "east_m_s",
    /// "down_m_s"}, "span_m"}` (swarm-frame NED), to `out`; `[]` for a real vehicle or
    /// without intruders. What a simulated camera renders besides the swarm (ABI 2).
    pub sim_aircraft: unsafe extern "C" fn(ctx: *const c_void, out: RawSink) -> u32,
    /// The latest video frame (JPEG) another payload of the same vehicle published, by slot
    /// (UTF-8), to `out`; nothing written when that slot has published none (ABI 2).
    pub payload_frame:
        unsafe extern "C" fn(ctx: *const c_void, slot: RawBytes, out: RawSink) -> u32,
}

/// The build stamp of this SDK: `key=value` pairs joined by `;`, e.g.
/// `abi=2;messages=1;dialect=common;arch=x86_64;os=linux;pointer_width=64;endian=little`.
/// Host and plugin must have equal stamps (see the module docs for what is in it and why).
pub fn build_stamp() -> String {
    format!(
        "abi={ABI_VERSION};messages={MESSAGES_VERSION};dialect=common;arch={};os={};pointer_width={};endian={}",
        std::env::consts::ARCH,
        std::env::consts::OS,
        usize::BITS,
        if cfg!(target_endian = "little") {
            "little"
        } else {
            "big"
        },
    )
}

/// Compares two build stamps key by key and describes every difference as
/// `"<key>: plugin <value>, host <value>"` (a missing key shows as `(none)`). Empty when
/// they are equal.
pub fn stamp_differences(plugin: &str, host: &str) -> Vec<String> {
    fn pairs(s: &str) -> Vec<(&str, &str)> {
        s.split(';')
            .filter(|p| !p.is_empty())
            .map(|p| p.split_once('=').unwrap_or((p, "")))
            .collect()
    }
    let (p, h) = (pairs(plugin), pairs(host));
    let mut keys: Vec<&str> = p.iter().chain(h.iter()).map(|(k, _)| *k).collect();
    let mut seen = std::collections::HashSet::new();
    keys.retain(|k| seen.insert(*k));
    let get = |v: &[(&str, &str)], k: &str| {
        v.iter()
            .find(|(key, _)| *key == k)
            .map(|(_, val)| (*val).to_string())
    };
    keys.into_iter()
        .filter_map(|k| {
            let (pv, hv) = (get(&p, k), get(&h, k));
            (pv != hv).then(|| {
                format!(
                    "{k}: plugin {}, host {}",
                    pv.as_deref().unwrap_or("(none)"),
                    hv.as_deref().unwrap_or("(none)")
                )
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stamp_is_key_value_pairs_with_the_abi_first() {
        let s = build_stamp();
        assert!(s.starts_with(&format!("abi={ABI_VERSION};messages={MESSAGES_VERSION};")));
        assert!(s.split(';').all(|p| p.contains('=')), "{s}");
        assert!(stamp_differences(&s, &s).is_empty());
    }

    #[test]
    fn stamp_differences_name_each_key() {
        let d = stamp_differences("abi=1;messages=2;os=linux", "abi=1;messages=1;arch=x");
        assert_eq!(
            d,
            vec![
                "messages: plugin 2, host 1".to_string(),
                "os: plugin linux, host (none)".to_string(),
                "arch: plugin (none), host x".to_string()
            ]
        );
    }

    #[test]
    fn vec_sink_appends() {
        let mut out = Vec::new();
        let sink = RawSink::for_vec(&mut out);
        // SAFETY: `out` outlives the sink's use and is not touched meanwhile.
        unsafe {
            sink.put(b"ab");
            sink.put(b"");
            sink.put(b"c");
        }
        assert_eq!(out, b"abc");
    }

    #[test]
    fn frozen_header_layout() {
        // The first three fields never move: any host can read any plugin's header.
        assert_eq!(std::mem::offset_of!(PluginVTable, abi_version), 0);
        assert_eq!(std::mem::offset_of!(PluginVTable, struct_size), 4);
        assert_eq!(std::mem::offset_of!(PluginVTable, build_stamp), 8);
    }
}
