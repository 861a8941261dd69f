//! The payload plugins of every role: where they are found, loading them at start, a
//! warning for each payload kind no plugin provides, and the vehicles told when a plugin
//! is loaded, unloaded or reloaded at run time.

use super::options::UpArgs;
use super::vehicles::Fleet;
use crate::config::ConfigFile;
use skein_plugin_host::{PluginEvent, PluginManager};
use skein_swarm::{EndpointSpec, PayloadMsg, Swarm};
use std::path::PathBuf;
use std::sync::Arc;

/// The plugins of the process: the manager, the files it refused at start, and the
/// payload factory the vehicles create their payloads with (the plugins first, then the
/// built-in payloads).
pub(super) struct Plugins {
    /// The plugin manager (the API loads, unloads and reloads through it).
    pub(super) manager: PluginManager,
    /// Files the scan at start refused, with the reason.
    pub(super) refused: Refused,
    /// The vehicles' payload factory.
    pub(super) factory: Arc<dyn skein_payload::PayloadFactory>,
}

impl Plugins {
    /// Loads every plugin of the directory `--plugin-dir`, `[plugins] dir` or the
    /// default names, and warns of the payload kinds `fleet` needs that none provides.
    ///
    /// # Errors
    /// As [`start_plugins`], or the default directory cannot be found.
    pub(super) fn start(
        args: &UpArgs,
        file: &ConfigFile,
        fleet: &Fleet,
    ) -> Result<Plugins, String> {
        let plugin_dir = match args.plugin_dir.clone().or(file.plugins.dir.clone()) {
            Some(d) => d,
            None => default_plugin_dir()?,
        };
        let (manager, refused) = start_plugins(&plugin_dir)?;
        let factory: Arc<dyn skein_payload::PayloadFactory> =
            Arc::new(skein_swarm::payload::Factories(vec![
                Arc::new(manager.clone()),
                Arc::new(skein_swarm::payload::BuiltinPayloads),
            ]));
        let spec = &fleet.spec;
        warn_missing_kinds(&spec.config, &spec.endpoints, factory.as_ref(), &plugin_dir);
        Ok(Plugins {
            manager,
            refused,
            factory,
        })
    }

    /// Tells `swarm`'s coordinator of every plugin change: a reloaded plugin, and the
    /// vehicles re-create its instances on the new build at once (an instance that calls
    /// first re-creates itself; either way no failure is counted); a loaded or unloaded
    /// one, and the vehicles start the slots waiting for it, or stop its instances (their
    /// slots wait again).
    pub(super) fn follow(&self, swarm: &Swarm) {
        let coordinator = swarm.coordinator.clone();
        self.manager.subscribe(move |event| match event {
            PluginEvent::Reloaded {
                stale_instances, ..
            } => {
                let list = stale_instances
                    .iter()
                    .map(|i| (i.vehicle_id.clone(), i.slot.clone()))
                    .collect();
                let _ = coordinator
                    .cast(PayloadMsg::RefreshPayloads(list, std::time::Instant::now()).into());
            }
            PluginEvent::Loaded { .. } | PluginEvent::Unloaded { .. } => {
                let _ = coordinator.cast(PayloadMsg::PluginsChanged.into());
            }
            PluginEvent::Refused { .. } => {}
        });
    }
}

/// The plugin directory when none is configured: the directory of the running executable
/// (cargo builds the plugin libraries `libskein_plugin_*.so` next to `target/*/skein`).
///
/// # Errors
/// The executable's path cannot be found.
fn default_plugin_dir() -> Result<PathBuf, String> {
    let exe = std::env::current_exe()
        .map_err(|e| format!("cannot find the skein executable's directory: {e}"))?;
    exe.parent()
        .map(std::path::Path::to_path_buf)
        .ok_or_else(|| format!("{}: no parent directory", exe.display()))
}

/// Creates the plugin manager for `dir` and loads every library in it. The manager logs
/// each loaded library and each refused file (naming the file and what differs); one
/// summary line goes to stdout.
///
/// Returns the manager and the refused files with the reason.
///
/// # Errors
/// `dir` cannot be read, or the plugin work directory cannot be created.
fn start_plugins(dir: &std::path::Path) -> Result<(PluginManager, Refused), String> {
    let manager = PluginManager::new(skein_plugin_host::HostConfig::new(dir))
        .map_err(|e| format!("plugins: {e}"))?;
    let entries = manager
        .scan()
        .map_err(|e| format!("--plugin-dir {}: {e}", dir.display()))?;
    let loaded: Vec<String> = entries
        .iter()
        .filter_map(|e| e.result.as_ref().ok())
        .map(|i| format!("{} {}", i.name, i.version))
        .collect();
    let refused: Refused = entries
        .iter()
        .filter_map(|e| match &e.result {
            Err(err) => Some((e.file.clone(), err.to_string())),
            Ok(_) => None,
        })
        .collect();
    println!(
        "skein: plugins from {}: {} loaded ({}), {} refused",
        dir.display(),
        loaded.len(),
        loaded.join(", "),
        refused.len()
    );
    Ok((manager, refused))
}

/// Files the plugin scan refused, with the reason.
pub(super) type Refused = Vec<(PathBuf, String)>;

/// Warns once per payload kind that a vehicle's model needs and no loaded plugin (nor a
/// built-in) provides: those payloads wait for a plugin (loaded later through the API)
/// while the vehicles fly on.
fn warn_missing_kinds(
    config: &skein_swarm::SwarmConfig,
    endpoints: &[EndpointSpec],
    factory: &dyn skein_payload::PayloadFactory,
    plugin_dir: &std::path::Path,
) {
    let providers = factory.providers();
    let mut warned = std::collections::BTreeSet::new();
    for v in endpoints.iter().flat_map(|e| &e.vehicles) {
        let model = config.model(v.model.as_deref().unwrap_or("generic"));
        for p in &model.payloads {
            let provided = providers.iter().any(|pr| {
                pr.kinds.contains(&p.kind) && p.plugin.as_ref().is_none_or(|n| *n == pr.name)
            });
            if !provided && warned.insert(p.kind.clone()) {
                tracing::warn!(
                    "no plugin in {} provides payload kind `{}` (model `{}`, slot `{}`): those \
                     payloads wait for one while the vehicles fly on; build the plugins with \
                     `cargo build --release` (they land next to the skein binary) or give \
                     --plugin-dir, or load one at run time (POST /api/v1/plugins/load)",
                    plugin_dir.display(),
                    p.kind,
                    model.name,
                    p.slot
                );
            }
        }
    }
}
