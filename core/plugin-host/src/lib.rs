//! The skein plugin host: payload plugins (`cdylib` libraries built with
//! `skein-plugin-sdk`) loaded at run time, in-process or in a `skein plugin-host` child.
//!
//! [`PluginManager`] scans the plugin directory for `lib*.so`, maps each from a private
//! copy with `libloading`, and checks its ABI version, vtable size and build stamp before
//! reading or calling anything else; a mismatch is refused with an error naming the file
//! and what differs, and the others load. The manager is the vehicles' [`PayloadFactory`]
//! (they never know a payload is a plugin) and offers the operations of
//! `/api/v1/plugins`: list, load, unload, reload (with a generation per library and
//! [`PluginEvent`]s so instance owners learn when to re-create their payloads).
//!
//! Drivers come in two kinds, chosen by [`skein_payload::PayloadSpec::isolation`]:
//! - in-process: direct calls through the plugin's vtable; a panic in the plugin becomes an
//!   error (the SDK catches it at the boundary) and the process lives on;
//! - process: the plugin runs in a child process speaking [`wire`] over a Unix socket;
//!   an abort, a segfault or a missed call deadline kills only the child, and the driver
//!   reports it from its next call, so the supervisor re-creates it (a new child).
//!
//! Libraries are never unmapped. A Rust cdylib carries its own std, which registers
//! thread-local destructors in the host's threads whenever plugin code touches a
//! thread-local; glibc would run them at thread exit even after `dlclose` and crash. So
//! unload and reload *retire* a library (no new instances, out of the listing once its
//! last instance is gone, its private file copy deleted) while its code stays mapped until
//! skein exits: a few MB per retired build.
//!
//! [`plugin_host_main`] is the child's entry point (the `skein plugin-host` subcommand);
//! `skein bench plugins` (crate `skein-bench`) measures round trips, loads, reloads and
//! restarts through this crate's public API.
//!
//! `unsafe` code lives only at the FFI boundary: `library.rs` (mapping and header checks),
//! `services.rs` (the host callbacks), `inprocess.rs` and `child.rs` (vtable calls).
#![warn(missing_docs)]

mod child;
mod error;
mod inprocess;
mod isolated;
mod library;
mod manager;
mod registry;
mod services;
pub mod wire;

pub use child::{PluginHostArgs, plugin_host_main};
pub use error::HostError;
pub use isolated::ChildCommand;
pub use manager::{
    ForcedUnload, HostConfig, PluginEvent, PluginManager, ReloadReport, ScanEntry, SubscriptionId,
};
pub use registry::{
    InstanceRecord, LibraryInfo, LibraryStatus, STALE_INSTANCE_ERROR, StalePolicy,
    is_stale_instance_error,
};
/// The payload contract the drivers implement.
pub use skein_payload::{Isolation, PayloadDriver, PayloadFactory, PayloadHost, PayloadSpec};
