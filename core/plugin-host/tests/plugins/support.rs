//! Test support: building the plugin crates (cargo does not build cdylib dependencies for
//! tests), a fake vehicle world implementing `PayloadHost`, and polling helpers.

use serde_json::Value;
use skein_mavlink::MavMessage;
use skein_model::geo::{GeoPoint, Ned, NedFrame};
use skein_model::vehicle::VehicleSnapshot;
use skein_plugin_host::{ChildCommand, HostConfig, PayloadHost, PluginManager};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};

/// Every plugin crate of the workspace.
pub const PLUGIN_PACKAGES: [&str; 7] = [
    "skein-plugin-example",
    "skein-plugin-gimbal",
    "skein-plugin-camera",
    "skein-plugin-detector",
    "skein-plugin-radio",
    "skein-plugin-fault",
    "skein-plugin-abi-mismatch",
];

/// The plugin build, shared with skein's end-to-end tests.
#[path = "../../../../tests/support/plugin_build.rs"]
mod plugin_build;
pub use plugin_build::{build_into, lib_file};

/// A directory private to this test process.
pub fn scratch(name: &str) -> PathBuf {
    static BASE: OnceLock<PathBuf> = OnceLock::new();
    let base = BASE.get_or_init(|| {
        // Remove what earlier runs left (their process is gone), then make ours.
        if let Ok(dir) = std::fs::read_dir(std::env::temp_dir()) {
            for e in dir.flatten() {
                let name = e.file_name().to_string_lossy().into_owned();
                if let Some(pid) = name.strip_prefix("skein-plugin-tests-")
                    && !Path::new(&format!("/proc/{pid}")).exists()
                {
                    let _ = std::fs::remove_dir_all(e.path());
                }
            }
        }
        let b = std::env::temp_dir().join(format!("skein-plugin-tests-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&b);
        std::fs::create_dir_all(&b).unwrap();
        b
    });
    static COUNTER: Mutex<u32> = Mutex::new(0);
    let mut n = COUNTER.lock().unwrap();
    *n += 1;
    let dir = base.join(format!("{name}-{n}"));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The default build of every plugin (once per test process): a directory of copies.
pub fn built_plugins() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = scratch("built");
        build_into(&PLUGIN_PACKAGES, &[], &dir);
        dir
    })
}

/// One package built with `env` (e.g. `SKEIN_EXAMPLE_VERSION=9.9.9`): the library copy.
pub fn built_variant(package: &str, env: &[(&str, &str)]) -> PathBuf {
    static CACHE: Mutex<Option<HashMap<String, PathBuf>>> = Mutex::new(None);
    let key = format!("{package}{env:?}");
    if let Some(p) = CACHE
        .lock()
        .unwrap()
        .get_or_insert_with(HashMap::new)
        .get(&key)
    {
        return p.clone();
    }
    let dir = scratch("variant");
    let file = build_into(&[package], env, &dir).remove(0);
    CACHE
        .lock()
        .unwrap()
        .get_or_insert_with(HashMap::new)
        .insert(key, file.clone());
    file
}

/// A fresh plugin directory holding copies of the given packages' default builds.
pub fn plugin_dir_with(packages: &[&str]) -> PathBuf {
    let dir = scratch("plugins");
    for p in packages {
        std::fs::copy(built_plugins().join(lib_file(p)), dir.join(lib_file(p))).unwrap();
    }
    dir
}

/// The child command for process isolation in tests: this crate's standalone binary.
pub fn child_command() -> ChildCommand {
    ChildCommand::standalone(env!("CARGO_BIN_EXE_skein-plugin-host"))
}

/// A manager over a fresh plugin directory with `packages`, scanned.
pub fn manager_with(packages: &[&str]) -> PluginManager {
    let dir = plugin_dir_with(packages);
    let mut cfg = HostConfig::new(&dir);
    cfg.child = Some(child_command());
    cfg.work_dir = Some(scratch("work"));
    let m = PluginManager::new(cfg).unwrap();
    for e in m.scan().unwrap() {
        e.result
            .unwrap_or_else(|err| panic!("{}: {err}", e.file.display()));
    }
    m
}

/// Polls `f` until it returns `Some` or `limit` passes.
pub fn wait_for<T>(limit: Duration, what: &str, mut f: impl FnMut() -> Option<T>) -> T {
    let deadline = Instant::now() + limit;
    loop {
        if let Some(v) = f() {
            return v;
        }
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// The swarm origin of the fake world.
pub const ORIGIN: GeoPoint = GeoPoint::new(47.397_742, 8.545_594, 488.0);

/// A vehicle snapshot at a swarm-frame NED position with a heading.
pub fn snapshot(id: &str, sysid: u8, ned: (f64, f64, f64), heading_deg: f64) -> VehicleSnapshot {
    let frame = NedFrame::new(ORIGIN);
    VehicleSnapshot {
        heading_deg,
        ..VehicleSnapshot::hovering_at(id, sysid, &frame, Ned::new(ned.0, ned.1, ned.2))
    }
}

/// A fake swarm: vehicles whose snapshots the test moves, and everything the payloads
/// publish, per vehicle and slot.
#[derive(Default)]
pub struct World {
    pub simulated: bool,
    pub vehicles: Mutex<Vec<VehicleSnapshot>>,
    pub states: Mutex<HashMap<(String, String), Value>>,
    pub frames: Mutex<HashMap<String, Vec<Vec<u8>>>>,
    pub events: Mutex<Vec<(String, String, Value)>>,
    pub links: Mutex<Vec<(String, f64, f64)>>,
    pub mavlink: Mutex<Vec<(String, MavMessage)>>,
    /// The simulator's intruders, as `sim_aircraft` gives them to simulated vehicles.
    pub sim_aircraft: Mutex<Vec<skein_payload::SimAircraft>>,
}

impl World {
    pub fn new(simulated: bool) -> Arc<World> {
        Arc::new(World {
            simulated,
            ..Default::default()
        })
    }

    /// Adds or moves a vehicle.
    pub fn put(&self, id: &str, sysid: u8, ned: (f64, f64, f64), heading_deg: f64) {
        let mut v = self.vehicles.lock().unwrap();
        let s = snapshot(id, sysid, ned, heading_deg);
        match v.iter_mut().find(|x| x.id == id) {
            Some(x) => *x = s,
            None => v.push(s),
        }
    }

    pub fn host(self: &Arc<Self>, vehicle: &str, slot: &str) -> Arc<dyn PayloadHost> {
        Arc::new(FakeHost {
            world: Arc::clone(self),
            vehicle_id: vehicle.into(),
            slot: slot.into(),
        })
    }

    pub fn state(&self, vehicle: &str, slot: &str) -> Option<Value> {
        self.states
            .lock()
            .unwrap()
            .get(&(vehicle.to_string(), slot.to_string()))
            .cloned()
    }

    pub fn set_state(&self, vehicle: &str, slot: &str, state: Value) {
        self.states
            .lock()
            .unwrap()
            .insert((vehicle.to_string(), slot.to_string()), state);
    }

    pub fn frames(&self, vehicle: &str) -> Vec<Vec<u8>> {
        self.frames
            .lock()
            .unwrap()
            .get(vehicle)
            .cloned()
            .unwrap_or_default()
    }

    pub fn links(&self, vehicle: &str) -> Vec<(f64, f64)> {
        self.links
            .lock()
            .unwrap()
            .iter()
            .filter(|(v, _, _)| v == vehicle)
            .map(|(_, l, t)| (*l, *t))
            .collect()
    }
}

/// One payload's view of the world.
pub struct FakeHost {
    world: Arc<World>,
    vehicle_id: String,
    slot: String,
}

impl PayloadHost for FakeHost {
    fn vehicle_id(&self) -> &str {
        &self.vehicle_id
    }
    fn vehicle(&self) -> VehicleSnapshot {
        self.world
            .vehicles
            .lock()
            .unwrap()
            .iter()
            .find(|v| v.id == self.vehicle_id)
            .cloned()
            .expect("the payload's vehicle is in the world")
    }
    fn swarm(&self) -> Vec<VehicleSnapshot> {
        self.world.vehicles.lock().unwrap().clone()
    }
    fn simulated(&self) -> bool {
        self.world.simulated
    }
    fn send_mavlink(&self, msg: &MavMessage) -> Result<(), String> {
        self.world
            .mavlink
            .lock()
            .unwrap()
            .push((self.vehicle_id.clone(), msg.clone()));
        Ok(())
    }
    fn emit_event(&self, kind: &str, data: Value) {
        self.world
            .events
            .lock()
            .unwrap()
            .push((self.vehicle_id.clone(), kind.to_string(), data));
    }
    fn publish_state(&self, state: Value) {
        self.world.set_state(&self.vehicle_id, &self.slot, state);
    }
    fn payload_state(&self, slot: &str) -> Option<Value> {
        self.world.state(&self.vehicle_id, slot)
    }
    fn publish_frame(&self, jpeg: Vec<u8>) {
        self.world
            .frames
            .lock()
            .unwrap()
            .entry(self.vehicle_id.clone())
            .or_default()
            .push(jpeg);
    }
    fn sim_aircraft(&self) -> Vec<skein_payload::SimAircraft> {
        if self.world.simulated {
            self.world.sim_aircraft.lock().unwrap().clone()
        } else {
            Vec::new()
        }
    }
    fn payload_frame(&self, _slot: &str) -> Option<Arc<Vec<u8>>> {
        // Only cameras publish frames in these tests: the vehicle's latest one.
        self.world.frames(&self.vehicle_id).pop().map(Arc::new)
    }
    fn set_simulated_link(&self, loss_fraction: f64, latency_ms: f64) -> bool {
        self.world
            .links
            .lock()
            .unwrap()
            .push((self.vehicle_id.clone(), loss_fraction, latency_ms));
        self.world.simulated
    }
}
