//! [`PluginManager`]: the plugin directory, the loaded libraries, load / unload / reload,
//! and the [`PayloadFactory`](skein_payload::PayloadFactory) the vehicles use ([`factory`]).

use crate::error::HostError;
use crate::isolated::ChildCommand;
use crate::library::LoadedLibrary;
use crate::registry::{InstanceRecord, LibraryEntry, LibraryInfo, StalePolicy};
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, Weak};
use std::time::Duration;

mod factory;

/// Configuration of a [`PluginManager`].
#[derive(Debug, Clone)]
pub struct HostConfig {
    /// The plugin directory (`--plugin-dir`): [`PluginManager::scan`] loads every
    /// `lib*.so` in it, and relative paths given to [`PluginManager::load`] are inside it.
    pub plugin_dir: PathBuf,
    /// Refuse to load files outside `plugin_dir` (default true: the HTTP API can ask for a
    /// load, and loading a library runs its code).
    pub restrict_to_plugin_dir: bool,
    /// Where the private copies of libraries and the isolation sockets live (default:
    /// `$TMPDIR/skein-plugins-<pid>`; created with mode 0700; emptied as libraries are
    /// retired; directories of dead skein processes are removed at start).
    pub work_dir: Option<PathBuf>,
    /// How to start a `skein plugin-host` child for process isolation; `None`: the running
    /// executable's `plugin-host` subcommand ([`ChildCommand::skein_subcommand`]).
    pub child: Option<ChildCommand>,
    /// Deadline of each call into a process-isolated instance (tick, handle, MAVLink);
    /// a child that misses it is killed and the call fails. Default 5 s. In-process calls
    /// cannot be given a deadline (a thread cannot be pre-empted).
    pub call_timeout: Duration,
    /// Deadline for a child to start, load its library and create its instance. Default
    /// 10 s.
    pub spawn_timeout: Duration,
    /// What happens to the instances of a reloaded library.
    pub stale_instances: StalePolicy,
}

impl HostConfig {
    /// The defaults for a plugin directory.
    pub fn new(plugin_dir: impl Into<PathBuf>) -> HostConfig {
        HostConfig {
            plugin_dir: plugin_dir.into(),
            restrict_to_plugin_dir: true,
            work_dir: None,
            child: None,
            call_timeout: Duration::from_secs(5),
            spawn_timeout: Duration::from_secs(10),
            stale_instances: StalePolicy::FailNextCall,
        }
    }
}

/// What changed in the manager, for whoever owns payload instances (a callback registered
/// with [`PluginManager::subscribe`]).
#[derive(Debug, Clone, PartialEq)]
pub enum PluginEvent {
    /// A library was loaded.
    Loaded {
        /// Plugin name.
        name: String,
        /// Version.
        version: String,
        /// Generation.
        generation: u64,
        /// File.
        file: PathBuf,
    },
    /// A library was replaced by a new build. The listed instances run the old code: their
    /// owners should re-create them (with [`StalePolicy::FailNextCall`] they fail their
    /// next call anyway).
    Reloaded {
        /// Plugin name.
        name: String,
        /// The replaced version.
        previous_version: String,
        /// The new version.
        version: String,
        /// The new generation.
        generation: u64,
        /// Instances still on the old generation.
        stale_instances: Vec<InstanceRecord>,
    },
    /// A library was unloaded. With [`PluginManager::unload_force`] its live instances are
    /// listed: their owners should stop them (no new instance can come from it).
    Unloaded {
        /// Plugin name.
        name: String,
        /// Its version.
        version: String,
        /// Instances still alive (empty for a plain [`PluginManager::unload`]).
        live_instances: Vec<InstanceRecord>,
    },
    /// A file was refused (scan or load).
    Refused {
        /// The file.
        file: PathBuf,
        /// Why (the [`HostError`] text).
        reason: String,
    },
}

/// The outcome of one file of [`PluginManager::scan`].
#[derive(Debug, Clone, PartialEq)]
pub struct ScanEntry {
    /// The file.
    pub file: PathBuf,
    /// Loaded, or why not.
    pub result: Result<LibraryInfo, HostError>,
}

/// The outcome of [`PluginManager::reload`].
#[derive(Debug, Clone, PartialEq)]
pub struct ReloadReport {
    /// The new library.
    pub library: LibraryInfo,
    /// The replaced version.
    pub previous_version: String,
    /// The replaced generation.
    pub previous_generation: u64,
    /// Instances still running the replaced generation.
    pub stale_instances: Vec<InstanceRecord>,
}

/// The outcome of [`PluginManager::unload_force`].
#[derive(Debug, Clone)]
pub struct ForcedUnload {
    /// The library as it was when unloaded (with the instances alive then).
    pub library: LibraryInfo,
    entry: Weak<LibraryEntry>,
}

impl ForcedUnload {
    /// Instances of the unloaded library still alive (empty once their owners stopped
    /// them all).
    pub fn live_instances(&self) -> Vec<InstanceRecord> {
        self.entry
            .upgrade()
            .map(|e| e.instances())
            .unwrap_or_default()
    }
}

/// Identifies a subscription, for [`PluginManager::unsubscribe`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SubscriptionId(u64);

type Listener = Arc<dyn Fn(&PluginEvent) + Send + Sync>;

#[derive(Default)]
struct Registry {
    current: BTreeMap<String, Arc<LibraryEntry>>,
    superseded: Vec<Weak<LibraryEntry>>,
    generations: HashMap<String, u64>,
}

struct Inner {
    config: HostConfig,
    work_dir: PathBuf,
    registry: Mutex<Registry>,
    listeners: Mutex<Vec<(u64, Listener)>>,
    next_subscription: AtomicU64,
}

impl Drop for Inner {
    fn drop(&mut self) {
        // Release our libraries first (their private copies go with them), then the
        // directory: that only succeeds once every copy is gone, and instances may outlive
        // the manager (a later start removes what is left).
        if let Ok(reg) = self.registry.get_mut() {
            *reg = Registry::default();
        }
        let _ = std::fs::remove_dir(&self.work_dir);
    }
}

/// Loads plugin libraries and creates payload drivers from them.
///
/// Cheap to clone (shared state): give one clone to the vehicles as their
/// [`PayloadFactory`](skein_payload::PayloadFactory) and another to the HTTP layer for list / load / unload / reload.
///
/// A library stays in the listing while any instance created from it lives (each instance
/// holds its library), also after a reload; its code is never unmapped (see the crate
/// docs). [`PluginManager::unload`] is refused
/// while instances live. [`PluginManager::reload`] maps the new build next to the old one,
/// bumps the library's generation, and tells subscribers which instances run the old code.
#[derive(Clone)]
pub struct PluginManager {
    inner: Arc<Inner>,
}

/// Removes the work directories of skein processes that no longer exist.
fn clean_stale_work_dirs(parent: &Path) {
    let Ok(dir) = std::fs::read_dir(parent) else {
        return;
    };
    for e in dir.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if let Some(pid) = name
            .strip_prefix("skein-plugins-")
            .and_then(|p| p.parse::<u32>().ok())
            && pid != std::process::id()
            && !Path::new(&format!("/proc/{pid}")).exists()
        {
            let _ = std::fs::remove_dir_all(e.path());
        }
    }
}

impl PluginManager {
    /// A manager with no library loaded yet (call [`PluginManager::scan`]).
    ///
    /// # Errors
    /// The work directory cannot be created.
    pub fn new(config: HostConfig) -> Result<PluginManager, HostError> {
        let work_dir = match &config.work_dir {
            Some(d) => d.clone(),
            None => {
                let tmp = std::env::temp_dir();
                clean_stale_work_dirs(&tmp);
                tmp.join(format!("skein-plugins-{}", std::process::id()))
            }
        };
        // Private (0700): it holds the mapped library copies and the sockets the children
        // connect to, which no other user may reach first.
        std::fs::create_dir_all(&work_dir)
            .and_then(|_| {
                use std::os::unix::fs::PermissionsExt;
                std::fs::set_permissions(&work_dir, std::fs::Permissions::from_mode(0o700))
            })
            .map_err(|e| HostError::Load {
                file: work_dir.clone(),
                reason: format!("cannot create the plugin work directory: {e}"),
            })?;
        Ok(PluginManager {
            inner: Arc::new(Inner {
                config,
                work_dir,
                registry: Mutex::new(Registry::default()),
                listeners: Mutex::new(Vec::new()),
                next_subscription: AtomicU64::new(1),
            }),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &HostConfig {
        &self.inner.config
    }

    fn registry(&self) -> MutexGuard<'_, Registry> {
        // A panic while holding the lock leaves the maps consistent (every update is a
        // single insert/remove), so a poisoned lock is still usable.
        self.inner
            .registry
            .lock()
            .unwrap_or_else(|p| p.into_inner())
    }

    fn emit(&self, event: PluginEvent) {
        let listeners: Vec<Listener> = self
            .inner
            .listeners
            .lock()
            .map(|l| l.iter().map(|(_, f)| Arc::clone(f)).collect())
            .unwrap_or_default();
        for f in listeners {
            if std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| f(&event))).is_err() {
                tracing::warn!("a plugin event listener panicked");
            }
        }
    }

    /// Calls `listener` on every [`PluginEvent`] from now on (from the thread that caused
    /// it: keep it short, e.g. post a message to an actor).
    pub fn subscribe(
        &self,
        listener: impl Fn(&PluginEvent) + Send + Sync + 'static,
    ) -> SubscriptionId {
        let id = self.inner.next_subscription.fetch_add(1, Ordering::Relaxed);
        if let Ok(mut l) = self.inner.listeners.lock() {
            l.push((id, Arc::new(listener)));
        }
        SubscriptionId(id)
    }

    /// Stops a subscription.
    pub fn unsubscribe(&self, id: SubscriptionId) {
        if let Ok(mut l) = self.inner.listeners.lock() {
            l.retain(|(i, _)| *i != id.0);
        }
    }

    /// Resolves a path given to `load` (relative: inside the plugin directory).
    fn resolve(&self, file: &Path) -> Result<PathBuf, HostError> {
        let cfg = &self.inner.config;
        let path = if file.is_absolute() {
            file.to_path_buf()
        } else {
            cfg.plugin_dir.join(file)
        };
        let canonical = path.canonicalize().map_err(|e| HostError::Load {
            file: path.clone(),
            reason: e.to_string(),
        })?;
        if cfg.restrict_to_plugin_dir {
            let dir = cfg.plugin_dir.canonicalize().map_err(|e| HostError::Load {
                file: cfg.plugin_dir.clone(),
                reason: format!("the plugin directory is not accessible: {e}"),
            })?;
            if !canonical.starts_with(&dir) {
                return Err(HostError::Forbidden {
                    file: canonical,
                    reason: format!("it is outside the plugin directory {}", dir.display()),
                });
            }
        }
        Ok(canonical)
    }

    fn refused(&self, e: HostError) -> HostError {
        let file = match &e {
            HostError::Load { file, .. }
            | HostError::NotAPlugin { file, .. }
            | HostError::Incompatible { file, .. }
            | HostError::Forbidden { file, .. }
            | HostError::AlreadyLoaded { file, .. } => file.clone(),
            HostError::NotFound { .. } | HostError::InUse { .. } => PathBuf::new(),
        };
        tracing::warn!("{e}");
        self.emit(PluginEvent::Refused {
            file,
            reason: e.to_string(),
        });
        e
    }

    /// Loads every `lib*.so` of the plugin directory that is not loaded yet, in file-name
    /// order. A refused file (ABI mismatch, not a plugin, duplicate name) is reported in its
    /// entry and does not stop the others.
    ///
    /// # Errors
    /// The plugin directory cannot be read.
    pub fn scan(&self) -> Result<Vec<ScanEntry>, HostError> {
        let dir = &self.inner.config.plugin_dir;
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(|e| HostError::Load {
                file: dir.clone(),
                reason: format!("cannot read the plugin directory: {e}"),
            })?
            .flatten()
            .map(|e| e.path())
            .filter(|p| {
                p.is_file()
                    && p.file_name()
                        .and_then(|n| n.to_str())
                        .is_some_and(|n| n.starts_with("lib") && n.ends_with(".so"))
            })
            .collect();
        files.sort();
        let loaded: Vec<PathBuf> = self
            .registry()
            .current
            .values()
            .map(|e| e.lib.source.clone())
            .collect();
        Ok(files
            .into_iter()
            .filter(|f| {
                f.canonicalize()
                    .map(|c| !loaded.contains(&c))
                    .unwrap_or(true)
            })
            .map(|file| ScanEntry {
                result: self.load(&file),
                file,
            })
            .collect())
    }

    /// Loads one library file (absolute, or relative to the plugin directory).
    ///
    /// # Errors
    /// See [`HostError`]: unreadable, not a plugin, incompatible, already loaded (same
    /// name), or outside the plugin directory.
    pub fn load(&self, file: &Path) -> Result<LibraryInfo, HostError> {
        let source = self.resolve(file).map_err(|e| self.refused(e))?;
        let lib =
            LoadedLibrary::open(&source, &self.inner.work_dir).map_err(|e| self.refused(e))?;
        let entry = {
            let mut reg = self.registry();
            if let Some(existing) = reg.current.get(&lib.name) {
                let e = HostError::AlreadyLoaded {
                    name: lib.name.clone(),
                    file: existing.lib.source.clone(),
                };
                drop(reg);
                return Err(self.refused(e));
            }
            let generation = reg.generations.get(&lib.name).copied().unwrap_or(0) + 1;
            reg.generations.insert(lib.name.clone(), generation);
            let entry = Arc::new(LibraryEntry::new(lib, generation));
            reg.current
                .insert(entry.name().to_string(), Arc::clone(&entry));
            entry
        };
        let info = entry.info();
        tracing::info!(
            plugin = %info.name, version = %info.version, generation = info.generation,
            file = %info.file.display(), kinds = ?info.kinds, "plugin loaded"
        );
        self.emit(PluginEvent::Loaded {
            name: info.name.clone(),
            version: info.version.clone(),
            generation: info.generation,
            file: info.file.clone(),
        });
        Ok(info)
    }

    /// Unloads a plugin: no new instance can be created from it and it leaves the listing.
    /// Refused while instances of it live (stop their payloads first). Its code stays
    /// mapped until skein exits (see the crate docs: a Rust cdylib cannot be unmapped
    /// safely).
    ///
    /// # Errors
    /// [`HostError::NotFound`], [`HostError::InUse`] (naming the instances).
    pub fn unload(&self, name: &str) -> Result<LibraryInfo, HostError> {
        let entry = {
            let mut reg = self.registry();
            let entry = reg
                .current
                .get(name)
                .cloned()
                .ok_or_else(|| HostError::NotFound {
                    name: name.to_string(),
                })?;
            let live = entry.instances();
            if !live.is_empty() {
                return Err(HostError::InUse {
                    name: name.to_string(),
                    instances: live
                        .iter()
                        .map(|r| format!("{}/{}", r.vehicle_id, r.slot))
                        .collect(),
                });
            }
            reg.current.remove(name);
            entry
        };
        let info = entry.info();
        drop(entry);
        tracing::info!(plugin = %info.name, version = %info.version, "plugin unloaded");
        self.emit(PluginEvent::Unloaded {
            name: info.name.clone(),
            version: info.version.clone(),
            live_instances: vec![],
        });
        Ok(info)
    }

    /// Unloads a plugin even while instances of it live: it leaves the loaded set at once
    /// (no new instance can come from it, [`PayloadFactory::providers`](skein_payload::PayloadFactory::providers) no longer lists
    /// it), and subscribers get [`PluginEvent::Unloaded`] naming the live instances, which
    /// their owners stop. The library is listed as [`crate::LibraryStatus::Unloading`]
    /// until the last of them is gone; [`ForcedUnload::live_instances`] says which remain.
    ///
    /// # Errors
    /// [`HostError::NotFound`].
    pub fn unload_force(&self, name: &str) -> Result<ForcedUnload, HostError> {
        let entry = {
            let mut reg = self.registry();
            let entry = reg
                .current
                .remove(name)
                .ok_or_else(|| HostError::NotFound {
                    name: name.to_string(),
                })?;
            entry.mark_unloaded();
            reg.superseded.retain(|w| w.strong_count() > 0);
            reg.superseded.push(Arc::downgrade(&entry));
            entry
        };
        let info = entry.info();
        let live = entry.instances();
        let weak = Arc::downgrade(&entry);
        drop(entry);
        tracing::info!(
            plugin = %info.name, version = %info.version, instances = live.len(),
            "plugin unloaded with force: stopping its instances"
        );
        self.emit(PluginEvent::Unloaded {
            name: info.name.clone(),
            version: info.version.clone(),
            live_instances: live,
        });
        Ok(ForcedUnload {
            library: info,
            entry: weak,
        })
    }

    /// Replaces a plugin by the current content of the file it was loaded from (a new
    /// build). The new library is validated first (a refused build leaves the old one in
    /// place); then new instances use it, its generation is bumped, the old library is
    /// marked superseded (kept mapped while its instances live), and subscribers get
    /// [`PluginEvent::Reloaded`] with the instances to re-create.
    ///
    /// # Errors
    /// [`HostError::NotFound`]; any load error of the new build; a new build that calls
    /// itself by another name ([`HostError::Load`]).
    pub fn reload(&self, name: &str) -> Result<ReloadReport, HostError> {
        let source = {
            let reg = self.registry();
            reg.current
                .get(name)
                .map(|e| e.lib.source.clone())
                .ok_or_else(|| HostError::NotFound {
                    name: name.to_string(),
                })?
        };
        let lib =
            LoadedLibrary::open(&source, &self.inner.work_dir).map_err(|e| self.refused(e))?;
        if lib.name != name {
            let e = HostError::Load {
                file: source,
                reason: format!(
                    "the new build is plugin `{}`, not `{name}`; unload `{name}` and load it instead",
                    lib.name
                ),
            };
            return Err(self.refused(e));
        }
        let (old, new) = {
            let mut reg = self.registry();
            let Some(old) = reg.current.get(name).cloned() else {
                return Err(HostError::NotFound {
                    name: name.to_string(),
                });
            };
            let generation = reg.generations.get(name).copied().unwrap_or(old.generation) + 1;
            reg.generations.insert(name.to_string(), generation);
            let new = Arc::new(LibraryEntry::new(lib, generation));
            old.mark_superseded();
            reg.current.insert(name.to_string(), Arc::clone(&new));
            reg.superseded.retain(|w| w.strong_count() > 0);
            reg.superseded.push(Arc::downgrade(&old));
            (old, new)
        };
        let stale_instances = old.instances();
        let report = ReloadReport {
            library: new.info(),
            previous_version: old.lib.version.clone(),
            previous_generation: old.generation,
            stale_instances: stale_instances.clone(),
        };
        drop(old);
        tracing::info!(
            plugin = %name, from = %report.previous_version, to = %report.library.version,
            generation = report.library.generation, stale = stale_instances.len(), "plugin reloaded"
        );
        self.emit(PluginEvent::Reloaded {
            name: name.to_string(),
            previous_version: report.previous_version.clone(),
            version: report.library.version.clone(),
            generation: report.library.generation,
            stale_instances,
        });
        Ok(report)
    }

    /// Every library: the loaded ones (by name), then superseded ones still mapped for
    /// their instances.
    pub fn libraries(&self) -> Vec<LibraryInfo> {
        let mut reg = self.registry();
        reg.superseded.retain(|w| w.strong_count() > 0);
        let mut out: Vec<LibraryInfo> = reg.current.values().map(|e| e.info()).collect();
        out.extend(
            reg.superseded
                .iter()
                .filter_map(|w| w.upgrade())
                .map(|e| e.info()),
        );
        out
    }

    /// One loaded library by plugin name.
    pub fn library(&self, name: &str) -> Option<LibraryInfo> {
        self.registry().current.get(name).map(|e| e.info())
    }

    /// The current generation of a loaded plugin (1 at first load, +1 per reload): an
    /// instance owner can compare it with the generation its instance was created under
    /// (in [`LibraryInfo::instances`]) to know it must re-create it.
    pub fn generation(&self, name: &str) -> Option<u64> {
        self.registry().current.get(name).map(|e| e.generation)
    }
}
