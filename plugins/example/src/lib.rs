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

// Everything a plugin needs comes from the SDK, the only crate it links.
use skein_plugin_sdk::args::{Args, command_name};
use skein_plugin_sdk::serde_json::{Value, json};
use skein_plugin_sdk::{Context, Plugin, export_plugin};

/// The plugin's version. Normally `env!("CARGO_PKG_VERSION")`; here a build may override it
/// with the `SKEIN_EXAMPLE_VERSION` environment variable (read at compile time), which is
/// how skein's tests build two versions of the same plugin to exercise reload.
const VERSION: &str = match option_env!("SKEIN_EXAMPLE_VERSION") {
    Some(v) => v,
    None => env!("CARGO_PKG_VERSION"),
};

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
        // `Args` refuses unknown fields (typos) and names the field in every error.
        let cfg = Args::new(&config, "example config", &["greeting", "rate_hz"])?;
        let greeting = cfg.opt_str("greeting")?.unwrap_or("hello").to_string();
        let rate_hz = cfg.f64_in("rate_hz", 1.0, 0.0, 100.0)?;
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
        match command_name(&command, &["ping", "echo", "status", "emit"])? {
            "ping" => {
                Args::new(&command, "command `ping`", &["command"])?;
                Ok(json!({
                    "pong": true,
                    "plugin": Self::NAME,
                    "version": VERSION,
                    "vehicle": ctx.vehicle_id(),
                    "greeting": self.greeting,
                }))
            }
            "echo" => {
                let args = Args::new(&command, "command `echo`", &["command", "data"])?;
                Ok(json!({ "echo": args.get("data").cloned().unwrap_or(Value::Null) }))
            }
            "status" => {
                Args::new(&command, "command `status`", &["command"])?;
                Ok(self.state(ctx))
            }
            "emit" => {
                let args = Args::new(&command, "command `emit`", &["command", "message"])?;
                let message = args.str("message")?;
                ctx.emit_event("example", &json!({ "message": message }))?;
                Ok(json!({ "emitted": true }))
            }
            // `command_name` only returns one of the names listed above.
            other => Err(format!("unhandled command `{other}`")),
        }
    }
}

// Defines the C entry point skein looks for.
export_plugin!(Example);
