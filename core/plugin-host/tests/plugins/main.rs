//! Integration tests of the plugin host: the plugin crates are built by the tests (cargo
//! does not build cdylib dependencies for tests) and loaded with real `dlopen`, in-process
//! and in `skein-plugin-host` child processes.

mod camera;
mod detector;
mod faults;
mod gimbal;
mod loading;
mod radio;
mod reload;
mod support;

use serde_json::Value;
use skein_plugin_host::{Isolation, PayloadSpec};

/// A payload spec: `slot` of `kind`, hosted as `isolation`, configured with `config`.
pub fn spec(slot: &str, kind: &str, isolation: Isolation, config: Value) -> PayloadSpec {
    PayloadSpec {
        slot: slot.into(),
        kind: kind.into(),
        plugin: None,
        isolation,
        config,
    }
}
