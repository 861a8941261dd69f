//! What the manager knows of each loaded library and its live instances.

use crate::library::LoadedLibrary;
use serde::{Deserialize, Serialize};
use skein_payload::Isolation;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{SystemTime, UNIX_EPOCH};

/// The start of the error a stale instance returns after its library was reloaded (see
/// [`StalePolicy::FailNextCall`]); test with [`is_stale_instance_error`].
pub const STALE_INSTANCE_ERROR: &str = "plugin reloaded:";

/// True when a driver error means "your library was reloaded: re-create this payload", not
/// a fault (a supervisor may restart such a payload without counting it as a failure).
pub fn is_stale_instance_error(error: &str) -> bool {
    error.starts_with(STALE_INSTANCE_ERROR)
}

/// What happens to the instances of a library that was reloaded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StalePolicy {
    /// Their next `tick`, `handle` or `on_mavlink` returns an error starting with
    /// [`STALE_INSTANCE_ERROR`], so the supervisor re-creates them on the new code even if
    /// their owner ignores [`crate::PluginEvent::Reloaded`]. The default.
    #[default]
    FailNextCall,
    /// They keep running the old code (the old library stays mapped) until their owner
    /// re-creates them, e.g. on [`crate::PluginEvent::Reloaded`].
    KeepRunning,
}

/// One live payload instance of a library.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct InstanceRecord {
    /// Instance id, unique in the manager.
    pub id: u64,
    /// The vehicle it belongs to (`"uav-1"`).
    pub vehicle_id: String,
    /// Its slot on the vehicle (`"gimbal"`).
    pub slot: String,
    /// The payload kind.
    pub kind: String,
    /// How it is hosted.
    pub isolation: Isolation,
    /// The `skein plugin-host` child's process id (process isolation).
    pub pid: Option<u32>,
    /// Generation of the library it runs.
    pub generation: u64,
}

/// Whether a listed library is the current one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum LibraryStatus {
    /// Loaded and used for new instances.
    Loaded,
    /// Replaced by a reload; still mapped because instances of it are still alive.
    Superseded,
    /// Unloaded with force: no new instance comes from it, and its instances are being
    /// stopped by their vehicles (it leaves the listing with the last of them).
    Unloading,
}

/// One library as `GET /api/v1/plugins` shows it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct LibraryInfo {
    /// Plugin name.
    pub name: String,
    /// Plugin version.
    pub version: String,
    /// Payload kinds it provides.
    pub kinds: Vec<String>,
    /// The file it was loaded from.
    #[schema(value_type = String)]
    pub file: PathBuf,
    /// Generation: 1 at the first load of this name, +1 at each reload (and each load after
    /// an unload). Instances record the generation they run.
    pub generation: u64,
    /// Current or superseded.
    pub status: LibraryStatus,
    /// Number of live instances.
    pub instance_count: usize,
    /// The live instances.
    pub instances: Vec<InstanceRecord>,
    /// ABI version (equal to the host's).
    pub abi_version: u32,
    /// Build stamp (equal to the host's).
    pub build_stamp: String,
    /// When it was loaded, milliseconds since the Unix epoch.
    pub loaded_at_unix_ms: u64,
}

/// A loaded library with its generation and instances.
pub(crate) struct LibraryEntry {
    pub lib: LoadedLibrary,
    pub generation: u64,
    loaded_at: SystemTime,
    superseded: AtomicBool,
    unloaded: AtomicBool,
    instances: Mutex<BTreeMap<u64, InstanceRecord>>,
}

static NEXT_INSTANCE: AtomicU64 = AtomicU64::new(1);

impl LibraryEntry {
    pub fn new(lib: LoadedLibrary, generation: u64) -> LibraryEntry {
        LibraryEntry {
            lib,
            generation,
            loaded_at: SystemTime::now(),
            superseded: AtomicBool::new(false),
            unloaded: AtomicBool::new(false),
            instances: Mutex::new(BTreeMap::new()),
        }
    }

    pub fn name(&self) -> &str {
        &self.lib.name
    }

    pub fn superseded(&self) -> bool {
        self.superseded.load(Ordering::Acquire)
    }

    pub fn mark_superseded(&self) {
        self.superseded.store(true, Ordering::Release);
    }

    /// Marks it unloaded with force (see [`LibraryStatus::Unloading`]).
    pub fn mark_unloaded(&self) {
        self.unloaded.store(true, Ordering::Release);
    }

    pub fn instances(&self) -> Vec<InstanceRecord> {
        self.instances
            .lock()
            .map(|m| m.values().cloned().collect())
            .unwrap_or_default()
    }

    pub fn info(&self) -> LibraryInfo {
        let instances = self.instances();
        LibraryInfo {
            name: self.lib.name.clone(),
            version: self.lib.version.clone(),
            kinds: self.lib.kinds.clone(),
            file: self.lib.source.clone(),
            generation: self.generation,
            status: if self.unloaded.load(Ordering::Acquire) {
                LibraryStatus::Unloading
            } else if self.superseded() {
                LibraryStatus::Superseded
            } else {
                LibraryStatus::Loaded
            },
            instance_count: instances.len(),
            instances,
            abi_version: skein_plugin_sdk::abi::ABI_VERSION,
            build_stamp: self.lib.build_stamp.clone(),
            loaded_at_unix_ms: self
                .loaded_at
                .duration_since(UNIX_EPOCH)
                .map(|d| d.as_millis() as u64)
                .unwrap_or(0),
        }
    }

    /// Records a new instance; the returned guard removes it when dropped and keeps the
    /// library mapped meanwhile.
    pub fn register(
        self: &Arc<Self>,
        vehicle_id: &str,
        slot: &str,
        kind: &str,
        isolation: Isolation,
    ) -> InstanceGuard {
        let id = NEXT_INSTANCE.fetch_add(1, Ordering::Relaxed);
        let record = InstanceRecord {
            id,
            vehicle_id: vehicle_id.to_string(),
            slot: slot.to_string(),
            kind: kind.to_string(),
            isolation,
            pid: None,
            generation: self.generation,
        };
        if let Ok(mut m) = self.instances.lock() {
            m.insert(id, record);
        }
        InstanceGuard {
            entry: Arc::clone(self),
            id,
        }
    }
}

/// A live instance's hold on its library (see [`LibraryEntry::register`]).
pub(crate) struct InstanceGuard {
    pub entry: Arc<LibraryEntry>,
    pub id: u64,
}

impl InstanceGuard {
    /// Records the child process id of a process-isolated instance.
    pub fn set_pid(&self, pid: Option<u32>) {
        if let Ok(mut m) = self.entry.instances.lock()
            && let Some(r) = m.get_mut(&self.id)
        {
            r.pid = pid;
        }
    }

    /// The library and generation this instance runs.
    pub fn served_by(&self) -> skein_payload::ServedBy {
        skein_payload::ServedBy {
            plugin: self.entry.lib.name.clone(),
            version: self.entry.lib.version.clone(),
            generation: self.entry.generation,
        }
    }

    /// The error a stale instance returns under `policy`, if it is stale.
    pub fn stale_error(&self, policy: StalePolicy) -> Option<String> {
        (policy == StalePolicy::FailNextCall && self.entry.superseded()).then(|| {
            format!(
                "{STALE_INSTANCE_ERROR} plugin `{}` was reloaded; this instance runs the replaced \
                 generation {} (version {}): re-create the payload to run the new code",
                self.entry.lib.name, self.entry.generation, self.entry.lib.version
            )
        })
    }
}

impl Drop for InstanceGuard {
    fn drop(&mut self) {
        if let Ok(mut m) = self.entry.instances.lock() {
            m.remove(&self.id);
        }
    }
}
