//! The payload plugins of `skein up` (and `skein agent`): where they are found, loading
//! them at start, and a warning for each payload kind no plugin provides.

use skein_swarm::EndpointSpec;
use std::path::PathBuf;

/// The plugin directory when none is configured: the directory of the running executable
/// (cargo builds the plugin libraries `libskein_plugin_*.so` next to `target/*/skein`).
///
/// # Errors
/// The executable's path cannot be found.
pub(super) fn default_plugin_dir() -> Result<PathBuf, String> {
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
pub(super) fn start_plugins(
    dir: &std::path::Path,
) -> Result<(skein_plugin_host::PluginManager, Refused), String> {
    let manager = skein_plugin_host::PluginManager::new(skein_plugin_host::HostConfig::new(dir))
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
pub(super) fn warn_missing_kinds(
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
