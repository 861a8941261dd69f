//! Built-in payload providers: the `fault-fixture` kind, and [`Factories`], the chain
//! of factories the vehicles create drivers from (plugins first, then the built-ins).

use serde_json::{Value, json};
use skein_payload::{PayloadDriver, PayloadFactory, PayloadHost, PayloadSpec, ProviderInfo};
use std::sync::Arc;

/// The built-in payload kinds: `fault-fixture`, a payload that fails on request, for
/// supervision tests and for users rehearsing recovery.
///
/// Commands (`{"action": ...}`): `"echo"` answers the command back; `"panic"` panics in
/// the handler; `"error"` answers an error (the operator sees it, the actor lives);
/// `"fail_next_tick"` makes the next tick fail (the actor fails and is restarted). State:
/// `{"ticks": n, "created_unix_ms": t}`, published every tick (10 Hz).
pub struct BuiltinPayloads;

/// Kind name of the built-in fault fixture.
pub const FAULT_FIXTURE: &str = "fault-fixture";

struct FaultFixture {
    host: Arc<dyn PayloadHost>,
    ticks: u64,
    created_unix_ms: u64,
    fail_next_tick: bool,
}

impl PayloadDriver for FaultFixture {
    fn tick_rate_hz(&self) -> f64 {
        10.0
    }

    fn served_by(&self) -> Option<skein_payload::ServedBy> {
        Some(skein_payload::ServedBy {
            plugin: "builtin".into(),
            version: env!("CARGO_PKG_VERSION").into(),
            generation: 0,
        })
    }

    fn tick(&mut self, _dt_s: f64) -> Result<(), String> {
        if std::mem::take(&mut self.fail_next_tick) {
            return Err("fault fixture: failing this tick as asked".into());
        }
        self.ticks += 1;
        self.host.publish_state(json!({
            "ticks": self.ticks,
            "created_unix_ms": self.created_unix_ms,
        }));
        Ok(())
    }

    fn handle(&mut self, command: Value) -> Result<Value, String> {
        match command.get("action").and_then(Value::as_str) {
            Some("echo") => Ok(command),
            Some("panic") => panic!("fault fixture: panic on request"),
            Some("error") => Err("fault fixture: error on request".into()),
            Some("fail_next_tick") => {
                self.fail_next_tick = true;
                Ok(json!({"ok": true}))
            }
            Some(other) => Err(format!(
                "action: unknown action `{other}` (echo, panic, error, fail_next_tick)"
            )),
            None => {
                Err("action: missing field `action` (echo, panic, error, fail_next_tick)".into())
            }
        }
    }
}

impl PayloadFactory for BuiltinPayloads {
    fn create(
        &self,
        spec: &PayloadSpec,
        host: Arc<dyn PayloadHost>,
    ) -> Result<Box<dyn PayloadDriver>, String> {
        match spec.kind.as_str() {
            FAULT_FIXTURE => Ok(Box::new(FaultFixture {
                host,
                ticks: 0,
                created_unix_ms: std::time::SystemTime::now()
                    .duration_since(std::time::UNIX_EPOCH)
                    .map_or(0, |d| d.as_millis() as u64),
                fail_next_tick: false,
            })),
            other => Err(format!("no built-in payload kind `{other}`")),
        }
    }

    fn providers(&self) -> Vec<ProviderInfo> {
        vec![ProviderInfo {
            name: "builtin".into(),
            version: env!("CARGO_PKG_VERSION").into(),
            kinds: vec![FAULT_FIXTURE.into()],
        }]
    }
}

/// Several factories, asked in order: the first that provides the spec's plugin (when
/// named) or kind creates the driver.
pub struct Factories(pub Vec<Arc<dyn PayloadFactory>>);

impl PayloadFactory for Factories {
    fn create(
        &self,
        spec: &PayloadSpec,
        host: Arc<dyn PayloadHost>,
    ) -> Result<Box<dyn PayloadDriver>, String> {
        let provides = |f: &Arc<dyn PayloadFactory>| {
            f.providers().iter().any(|p| {
                p.kinds.contains(&spec.kind)
                    && spec.plugin.as_ref().is_none_or(|name| *name == p.name)
            })
        };
        match self.0.iter().find(|f| provides(f)) {
            Some(f) => f.create(spec, host),
            None => Err(format!(
                "no loaded plugin provides payload kind `{}`{} (slot `{}`)",
                spec.kind,
                spec.plugin
                    .as_ref()
                    .map(|p| format!(" from plugin `{p}`"))
                    .unwrap_or_default(),
                spec.slot
            )),
        }
    }

    fn providers(&self) -> Vec<ProviderInfo> {
        self.0.iter().flat_map(|f| f.providers()).collect()
    }
}

impl Default for crate::services::SwarmServices {
    /// The built-in payloads only, no simulator.
    fn default() -> Self {
        crate::services::SwarmServices {
            payloads: Arc::new(BuiltinPayloads),
            simulator: None,
        }
    }
}
