//! The skein plugin SDK: the only crate a payload plugin links.
//!
//! A payload plugin (a gimbal, a camera, a radio, a team's own device) is a `cdylib` that
//! skein loads at run time from its plugin directory, in its own process or in a
//! `skein plugin-host` child process. This crate gives the plugin author:
//! - [`Plugin`], a safe trait mirroring skein's `PayloadDriver` (create, tick, handle a
//!   JSON command, receive MAVLink, shut down);
//! - [`Context`], the host services lent to every call (the vehicle's snapshot and the
//!   swarm's, MAVLink to the vehicle, events, published state, the other payloads' states,
//!   video frames, the simulated link, logging);
//! - [`export_plugin!`], which exports the versioned C entry point `skein_plugin_entry`
//!   returning the plugin's [`abi::PluginVTable`], and wraps every export in
//!   `catch_unwind`, so a panicking plugin becomes an error for skein instead of an abort;
//! - helpers: [`args`] to read configs and commands with serde (errors naming the
//!   field), [`geometry`] for pointing maths (skein's own geodesy), [`vehicle`] for the
//!   typed snapshot, and the MAVLink common dialect ([`MavMessage`], [`dialect`],
//!   [`command_long`] / [`command_int`] for commands).
//!
//! Nothing but bytes crosses the boundary (JSON, MAVLink frames, JPEG): see [`abi`] for the
//! layout, the entry symbol and the versioning rules, and `plugins/README.md` for the
//! authoring guide.
//!
//! ```
//! use skein_plugin_sdk::serde_json::{Value, json};
//! use skein_plugin_sdk::{Context, Plugin, export_plugin};
//!
//! struct Hello;
//! impl Plugin for Hello {
//!     const NAME: &'static str = "hello";
//!     const VERSION: &'static str = "1.2.3";
//!     const KINDS: &'static [&'static str] = &["hello"];
//!     fn create(_kind: &str, _config: Value, _ctx: &Context) -> Result<Self, String> {
//!         Ok(Hello)
//!     }
//!     fn handle(&mut self, ctx: &Context, _command: Value) -> Result<Value, String> {
//!         Ok(json!({"hello": ctx.vehicle_id()}))
//!     }
//! }
//! export_plugin!(Hello);
//!
//! // What skein finds in the library: the vtable behind `skein_plugin_entry`.
//! // SAFETY: the entry returns a pointer to a vtable that lives as long as the program.
//! let vtable = unsafe { &*skein_plugin_entry() };
//! assert_eq!(vtable.abi_version, skein_plugin_sdk::abi::ABI_VERSION);
//! // SAFETY: `name` points to the plugin's `'static` name.
//! let name = unsafe { vtable.name.as_slice() };
//! assert_eq!(name, b"hello");
//! ```
#![warn(missing_docs)]

pub mod abi;
pub mod args;
mod context;
pub mod frame_meta;
pub mod geometry;
#[doc(hidden)]
pub mod glue;
mod plugin;
pub mod vehicle;

pub use context::Context;
pub use plugin::{MavlinkInterest, Plugin};
/// serde, for a plugin's own types (derive with `#[serde(crate = "skein_plugin_sdk::serde")]`).
pub use serde;
pub use serde_json;
/// A MAVLink message of the common dialect.
pub use skein_mavlink::MavMessage;
/// Per-message constants (`ID`, `NAME`) of the dialect's message structs.
pub use skein_mavlink::MessageData;
/// The MAVLink common dialect (message structs, enums, flags), as skein compiles it.
pub use skein_mavlink::dialect;
/// The command protocol's frames (`COMMAND_LONG`, `COMMAND_INT`), built as skein's own link
/// builds them.
pub use skein_mavlink::{CommandPosition, CommandTarget, command_int, command_long};
/// MAVLink framing (for plugins that talk MAVLink to devices of their own).
pub use skein_mavlink::{Decoder, Encoder};

/// Exports a [`Plugin`] type as this library's skein plugin: defines the C entry point
/// `skein_plugin_entry` (see [`abi::ENTRY_SYMBOL`]). Use it once per library.
///
/// `skein_plugin_sdk::export_plugin!(MyPlugin);` — see the crate-level example.
#[macro_export]
macro_rules! export_plugin {
    ($plugin:ty) => {
        $crate::export_plugin!(@entry $plugin, $crate::abi::ABI_VERSION, ::std::option::Option::None);
    };
    // Test fixtures only: a plugin that lies about its ABI version or build stamp, to check
    // that the host refuses it. Never use this in a real plugin.
    ($plugin:ty, unchecked_fixture_header(abi_version = $abi:expr, build_stamp = $stamp:expr $(,)?)) => {
        $crate::export_plugin!(@entry $plugin, $abi, $stamp);
    };
    (@entry $plugin:ty, $abi:expr, $stamp:expr) => {
        /// The skein plugin entry point (see `skein_plugin_sdk::abi`).
        #[unsafe(no_mangle)]
        pub extern "C" fn skein_plugin_entry() -> *const $crate::abi::PluginVTable {
            static DESCRIPTOR: ::std::sync::OnceLock<$crate::glue::Descriptor> =
                ::std::sync::OnceLock::new();
            $crate::glue::entry::<$plugin>(&DESCRIPTOR, $abi, $stamp)
        }
    };
}
