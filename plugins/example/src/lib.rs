//! The example skein payload plugin: the smallest complete plugin, meant to be copied.
//!
//! It provides one payload kind, `example`. Each instance counts its ticks, answers a few
//! commands, reads its vehicle's state through the host services and publishes its own
//! state. Copy this crate, rename it (package name, [`Example::NAME`], the kind), and
//! replace the bodies. See `plugins/README.md` for the whole guide.
//!
//! Configuration (`PayloadSpec.config`, all optional):
//! `{"greeting": "hello", "rate_hz": 1.0}`.
//!
//! Commands (`POST /api/v1/vehicles/{id}/payloads/{slot}`):
//! - `{"command": "ping"}` → `{"pong": true, "plugin": "example", "version": "0.1.0", "vehicle": "uav-1", "greeting": "hello"}`
//! - `{"command": "echo", "data": <any JSON>}` → `{"echo": <data>}`
//! - `{"command": "status"}` → the published state
//! - `{"command": "emit", "message": "text"}` → raises an `example` event, `{"emitted": true}`
//!
//! Published state: `{"ticks": 12, "version": "0.1.0", "relative_alt_m": 10.0 | null,
//! "vehicle_state": "Hovering"}`.

// Everything a plugin needs comes from the SDK, the only crate it links (serde included:
// derives name it with `crate = "skein_plugin_sdk::serde"`).
use skein_plugin_sdk::args;
use skein_plugin_sdk::serde::Deserialize;
use skein_plugin_sdk::serde_json::{Value, json};
use skein_plugin_sdk::{Context, Plugin, export_plugin};

/// The plugin's version. Normally `env!("CARGO_PKG_VERSION")`; here a build may override it
/// with the `SKEIN_EXAMPLE_VERSION` environment variable (read at compile time), which is
/// how skein's tests build two versions of the same plugin to exercise reload.
const VERSION: &str = match option_env!("SKEIN_EXAMPLE_VERSION") {
    Some(v) => v,
    None => env!("CARGO_PKG_VERSION"),
};

/// The configuration: every field optional, unknown ones refused (a typo is an error that
/// names it, not a silently ignored setting).
#[derive(Deserialize)]
#[serde(crate = "skein_plugin_sdk::serde", deny_unknown_fields)]
struct Config {
    /// Returned by `ping`; default `"hello"`.
    greeting: Option<String>,
    /// Tick rate, Hz, 0–100; default 1.
    rate_hz: Option<f64>,
}

/// The commands, one variant per `command` name (`args::command` reads the tag).
#[derive(Deserialize)]
#[serde(crate = "skein_plugin_sdk::serde")]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
enum Command {
    /// `{"command": "ping"}`.
    Ping,
    /// `{"command": "echo", "data": <any JSON>}` (`data` may be left out: `null`).
    Echo {
        #[serde(default)]
        data: Value,
    },
    /// `{"command": "status"}`.
    Status,
    /// `{"command": "emit", "message": "text"}`.
    Emit { message: String },
}

/// One instance of the `example` payload (one slot on one vehicle).
pub struct Example {
    /// Configured greeting, returned by `ping`.
    greeting: String,
    /// Configured tick rate, Hz.
    rate_hz: f64,
    /// Ticks since creation.
    ticks: u64,
}

impl Example {
    /// The state this instance publishes (also the reply to `status`).
    fn state(&self, ctx: &Context) -> Value {
        // Host services can fail (e.g. in a child process whose parent went away): a plugin
        // decides what a failure means for it. Here, an unknown altitude is just `null`.
        let vehicle = ctx.vehicle().ok();
        json!({
            "ticks": self.ticks,
            "version": VERSION,
            "relative_alt_m": vehicle.as_ref().and_then(|v| v.position).map(|p| p.relative_alt_m),
            "vehicle_state": vehicle.map(|v| v.state),
        })
    }
}

impl Plugin for Example {
    // Identity: the name must be unique among loaded plugins; the kinds are what vehicle
    // models ask for in their payload slots.
    const NAME: &'static str = "example";
    const VERSION: &'static str = VERSION;
    const KINDS: &'static [&'static str] = &["example"];

    fn create(_kind: &str, config: Value, ctx: &Context) -> Result<Self, String> {
        // Errors name the field (`rate_hz: 500 is outside [0, 100]`).
        let cfg: Config = args::config(config)?;
        let greeting = cfg.greeting.unwrap_or_else(|| "hello".to_string());
        let rate_hz = args::in_range("rate_hz", cfg.rate_hz.unwrap_or(1.0), 0.0, 100.0)?;
        ctx.log_info(&format!("example payload created on {}", ctx.vehicle_id()));
        Ok(Example {
            greeting,
            rate_hz,
            ticks: 0,
        })
    }

    fn tick_rate_hz(&self) -> f64 {
        self.rate_hz
    }

    fn tick(&mut self, ctx: &Context, _dt_s: f64) -> Result<(), String> {
        self.ticks += 1;
        ctx.publish_state(&self.state(ctx))
    }

    fn handle(&mut self, ctx: &Context, command: Value) -> Result<Value, String> {
        match args::command(command)? {
            Command::Ping => Ok(json!({
                "pong": true,
                "plugin": Self::NAME,
                "version": VERSION,
                "vehicle": ctx.vehicle_id(),
                "greeting": self.greeting,
            })),
            Command::Echo { data } => Ok(json!({ "echo": data })),
            Command::Status => Ok(self.state(ctx)),
            Command::Emit { message } => {
                ctx.emit_event("example", &json!({ "message": message }))?;
                Ok(json!({ "emitted": true }))
            }
        }
    }
}

// Defines the C entry point skein looks for.
export_plugin!(Example);
