//! `skein bench plugins`: message round trips to a plugin instance (in-process and
//! process-isolated), load and reload times, and restart times after a crash, measured on
//! the `example` and `fault` plugins of a plugin directory.

use crate::PluginsBenchArgs;
use serde_json::{Value, json};
use skein_mavlink::MavMessage;
use skein_model::geo::{GeoPoint, NedFrame};
use skein_model::vehicle::VehicleSnapshot;
use skein_payload::{
    Isolation, PayloadDriver, PayloadFactory, PayloadHost, PayloadSpec, PayloadState,
};
use skein_plugin_host::{ChildCommand, HostConfig, PluginManager};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

/// What `bench_plugins` measures and with what.
#[derive(Debug, Clone)]
pub struct BenchConfig {
    /// A directory holding `libskein_plugin_example.so` (required) and
    /// `libskein_plugin_fault.so` (for the restart figures; skipped when absent).
    pub plugin_dir: PathBuf,
    /// How to start the `skein plugin-host` child.
    pub child: ChildCommand,
    /// In-process round trips measured.
    pub round_trips: usize,
    /// Process-isolated round trips measured.
    pub isolated_round_trips: usize,
    /// Loads and reloads measured.
    pub loads: usize,
    /// Restarts after a panic measured (and a fifth as many after an abort).
    pub restarts: usize,
}

impl BenchConfig {
    /// The default counts (20 000 and 2 000 round trips, 30 loads and reloads, 50
    /// restarts).
    pub fn new(plugin_dir: impl Into<PathBuf>, child: ChildCommand) -> BenchConfig {
        BenchConfig {
            plugin_dir: plugin_dir.into(),
            child,
            round_trips: 20_000,
            isolated_round_trips: 2_000,
            loads: 30,
            restarts: 50,
        }
    }
}

/// A still vehicle, enough for the example and fault plugins.
struct BenchHost {
    snapshot: VehicleSnapshot,
}

impl BenchHost {
    fn new() -> BenchHost {
        let frame = NedFrame::new(GeoPoint::new(47.3977, 8.5456, 488.0));
        let ned = skein_model::geo::Ned::new(0.0, 0.0, -10.0);
        BenchHost {
            snapshot: VehicleSnapshot::hovering_at("bench-1", 1, &frame, ned),
        }
    }
}

impl PayloadHost for BenchHost {
    fn vehicle_id(&self) -> &str {
        &self.snapshot.id
    }
    fn vehicle(&self) -> VehicleSnapshot {
        self.snapshot.clone()
    }
    fn swarm(&self) -> Vec<VehicleSnapshot> {
        vec![self.snapshot.clone()]
    }
    fn simulated(&self) -> bool {
        true
    }
    fn send_mavlink(&self, _msg: &MavMessage) -> Result<(), String> {
        Ok(())
    }
    fn emit_event(&self, _kind: &str, _data: Value) {}
    fn publish_state(&self, _state: PayloadState) {}
    fn payload_state(&self, _slot: &str) -> Option<PayloadState> {
        None
    }
    fn publish_frame(&self, _jpeg: Vec<u8>) {}
    fn set_simulated_link(&self, _loss_fraction: f64, _latency_ms: f64) -> bool {
        false
    }
}

/// `{"n", "p50", "p99", "mean", "max"}` of durations in microseconds (nearest-rank
/// percentiles, rounded to 0.1 µs); `null` for no samples. Also used by `skein bench
/// restart`.
pub fn summary(mut us: Vec<f64>) -> Value {
    if us.is_empty() {
        return Value::Null;
    }
    us.sort_by(f64::total_cmp);
    let pct = |p: f64| us[((p * us.len() as f64).ceil() as usize).clamp(1, us.len()) - 1];
    let round = |v: f64| (v * 10.0).round() / 10.0;
    json!({
        "n": us.len(),
        "p50": round(pct(0.50)),
        "p99": round(pct(0.99)),
        "mean": round(us.iter().sum::<f64>() / us.len() as f64),
        "max": round(us[us.len() - 1]),
    })
}

fn micros(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e6
}

fn spec(kind: &str, isolation: Isolation) -> PayloadSpec {
    PayloadSpec {
        slot: kind.into(),
        kind: kind.into(),
        plugin: None,
        isolation,
        config: Value::Null,
    }
}

fn round_trips(driver: &mut dyn PayloadDriver, n: usize) -> Result<Vec<f64>, String> {
    let cmd = json!({"command": "echo", "data": 1});
    for _ in 0..n.min(100) {
        driver.handle(cmd.clone())?;
    }
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let c = cmd.clone();
        let t = Instant::now();
        driver.handle(c)?;
        out.push(micros(t));
    }
    Ok(out)
}

/// Time from a crash's error to the first answer of a re-created instance.
fn restarts(
    m: &PluginManager,
    isolation: Isolation,
    crash: &str,
    n: usize,
) -> Result<Vec<f64>, String> {
    let host: Arc<dyn PayloadHost> = Arc::new(BenchHost::new());
    let mut out = Vec::with_capacity(n);
    let mut driver = m.create(&spec("fault", isolation), Arc::clone(&host))?;
    for _ in 0..n {
        if driver.handle(json!({"command": crash})).is_ok() {
            return Err(format!("the fault plugin survived `{crash}`"));
        }
        let t = Instant::now();
        drop(driver);
        driver = m.create(&spec("fault", isolation), Arc::clone(&host))?;
        driver.handle(json!({"command": "ping"}))?;
        out.push(micros(t));
    }
    Ok(out)
}

/// Runs the plugin benchmark and returns its figures as JSON (microseconds):
/// `{"plugin": {...}, "round_trip_us": {"in_process": S, "process": S}, "load_us": S,
/// "reload_us": S, "restart_after_panic_us": S, "restart_after_abort_us": S, "notes": [..]}`
/// where each `S` is `{"n", "p50", "p99", "mean", "max"}` (or `null` when skipped).
///
/// # Errors
/// The example plugin is missing or fails, or a child cannot be started.
pub fn bench_plugins(cfg: &BenchConfig) -> Result<Value, String> {
    let example = cfg.plugin_dir.join("libskein_plugin_example.so");
    let fault = cfg.plugin_dir.join("libskein_plugin_fault.so");
    if !example.is_file() {
        return Err(format!(
            "{} not found (build the example plugin)",
            example.display()
        ));
    }
    let mut host_cfg = HostConfig::new(&cfg.plugin_dir);
    host_cfg.child = Some(cfg.child.clone());
    let m = PluginManager::new(host_cfg).map_err(|e| e.to_string())?;
    let mut notes = Vec::new();

    let mut loads = Vec::with_capacity(cfg.loads);
    for _ in 0..cfg.loads {
        let t = Instant::now();
        let info = m.load(&example).map_err(|e| e.to_string())?;
        loads.push(micros(t));
        m.unload(&info.name).map_err(|e| e.to_string())?;
    }
    let info = m.load(&example).map_err(|e| e.to_string())?;
    let mut reloads = Vec::with_capacity(cfg.loads);
    for _ in 0..cfg.loads {
        let t = Instant::now();
        m.reload(&info.name).map_err(|e| e.to_string())?;
        reloads.push(micros(t));
    }

    let host: Arc<dyn PayloadHost> = Arc::new(BenchHost::new());
    let mut local = m.create(&spec("example", Isolation::InProcess), Arc::clone(&host))?;
    let in_process = round_trips(local.as_mut(), cfg.round_trips)?;
    drop(local);
    let t = Instant::now();
    let mut remote = m.create(&spec("example", Isolation::Process), Arc::clone(&host))?;
    let spawn_us = micros(t);
    let process = round_trips(remote.as_mut(), cfg.isolated_round_trips)?;
    drop(remote);

    let (panic_restarts, abort_restarts) = if fault.is_file() {
        m.load(&fault).map_err(|e| e.to_string())?;
        (
            summary(restarts(&m, Isolation::InProcess, "panic", cfg.restarts)?),
            summary(restarts(
                &m,
                Isolation::Process,
                "abort",
                (cfg.restarts / 5).max(1),
            )?),
        )
    } else {
        notes.push(format!(
            "{} not found: restart figures skipped",
            fault.display()
        ));
        (Value::Null, Value::Null)
    };
    notes.push(
        "round trip: handle({\"command\":\"echo\"}) to the example plugin, JSON both ways".into(),
    );
    notes.push("restart: from the crash's error to the first answer of a re-created instance (process: a new child)".into());
    Ok(json!({
        "plugin": {"name": info.name, "version": info.version},
        "round_trip_us": {"in_process": summary(in_process), "process": summary(process)},
        "load_us": summary(loads),
        "reload_us": summary(reloads),
        "spawn_isolated_instance_us": (spawn_us * 10.0).round() / 10.0,
        "restart_after_panic_us": panic_restarts,
        "restart_after_abort_us": abort_restarts,
        "notes": notes,
    }))
}

/// `skein bench plugins`: [`bench_plugins`] on the plugin directory,
/// the isolated instances in `skein plugin-host` children of the `skein` executable
/// ([`crate::skein_exe`]). JSON:
/// `round_trip_us` (`in_process`, `process`: `n`, `p50`, `p99`, `max`), `load_us`,
/// `reload_us`, `restart_after_panic_us`, `restart_after_abort_us`, and the plugin measured.
///
/// # Errors
/// No example plugin in the directory, or a measurement failed.
pub fn plugins(args: &PluginsBenchArgs) -> Result<Value, String> {
    let skein = crate::skein_exe()?;
    let dir = match &args.plugin_dir {
        Some(d) => d.clone(),
        None => skein
            .parent()
            .map(std::path::Path::to_path_buf)
            .ok_or("cannot find the skein executable's directory: give --plugin-dir")?,
    };
    let child = ChildCommand {
        program: skein,
        args: vec!["plugin-host".into()],
    };
    let mut cfg = BenchConfig::new(&dir, child);
    cfg.round_trips = args.round_trips.max(1);
    cfg.isolated_round_trips = args.isolated_round_trips.max(1);
    cfg.loads = args.loads.max(1);
    cfg.restarts = args.restarts.max(1);
    let mut report = bench_plugins(&cfg)?;
    report["bench"] = json!("plugins");
    report["plugin_dir"] = json!(dir.display().to_string());
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summary_percentiles() {
        let s = summary((1..=100).map(f64::from).collect());
        assert_eq!(s["p50"], 50.0);
        assert_eq!(s["p99"], 99.0);
        assert_eq!(s["max"], 100.0);
        assert_eq!(s["n"], 100);
        assert_eq!(summary(vec![]), Value::Null);
    }
}
