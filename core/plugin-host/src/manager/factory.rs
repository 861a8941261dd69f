//! How a payload slot's spec becomes a driver ([`PayloadFactory`] for
//! [`PluginManager`]): the library that provides the kind (the named plugin, or the first
//! loaded one that provides it), then an in-process driver or an isolated child process.
//! A refusal names the slot, the kind and what is loaded.

use super::{PluginManager, Registry};
use crate::inprocess::InProcessDriver;
use crate::isolated::{ChildCommand, IsolatedDriver, IsolationSettings};
use crate::registry::LibraryEntry;
use crate::services::HostServices;
use skein_payload::{
    Isolation, PayloadDriver, PayloadFactory, PayloadHost, PayloadSpec, ProviderInfo,
};
use std::sync::Arc;

impl PluginManager {
    fn isolation_settings(&self) -> Result<IsolationSettings, String> {
        let cfg = &self.inner.config;
        let child = match &cfg.child {
            Some(c) => c.clone(),
            None => ChildCommand::skein_subcommand().map_err(|e| {
                format!("cannot find the skein executable for process isolation: {e}")
            })?,
        };
        Ok(IsolationSettings {
            child,
            call_timeout: cfg.call_timeout,
            spawn_timeout: cfg.spawn_timeout,
            socket_dir: self.inner.work_dir.clone(),
        })
    }

    fn pick(&self, spec: &PayloadSpec) -> Result<Arc<LibraryEntry>, String> {
        let reg = self.registry();
        let provides = |e: &LibraryEntry| e.lib.kinds.contains(&spec.kind);
        match &spec.plugin {
            Some(name) => {
                let entry = reg.current.get(name).ok_or_else(|| {
                    format!(
                        "slot `{}`: no plugin named `{name}` is loaded (loaded: {})",
                        spec.slot,
                        list_loaded(&reg)
                    )
                })?;
                if !provides(entry) {
                    return Err(format!(
                        "slot `{}`: plugin `{name}` does not provide payload kind `{}` (it provides: {})",
                        spec.slot,
                        spec.kind,
                        entry.lib.kinds.join(", ")
                    ));
                }
                Ok(Arc::clone(entry))
            }
            None => reg
                .current
                .values()
                .find(|e| provides(e))
                .cloned()
                .ok_or_else(|| {
                    format!(
                        "slot `{}`: no loaded plugin provides payload kind `{}` (loaded: {})",
                        spec.slot,
                        spec.kind,
                        list_loaded(&reg)
                    )
                }),
        }
    }
}

fn list_loaded(reg: &Registry) -> String {
    if reg.current.is_empty() {
        return "none".into();
    }
    reg.current
        .values()
        .map(|e| format!("{} ({})", e.name(), e.lib.kinds.join(", ")))
        .collect::<Vec<_>>()
        .join(", ")
}

impl PayloadFactory for PluginManager {
    fn create(
        &self,
        spec: &PayloadSpec,
        host: Arc<dyn PayloadHost>,
    ) -> Result<Box<dyn PayloadDriver>, String> {
        let entry = self.pick(spec)?;
        let name = entry.name().to_string();
        let services = HostServices::new(Arc::clone(&host), &name, &spec.slot);
        let guard = entry.register(host.vehicle_id(), &spec.slot, &spec.kind, spec.isolation);
        drop(entry);
        let policy = self.inner.config.stale_instances;
        let driver: Result<Box<dyn PayloadDriver>, String> = match spec.isolation {
            Isolation::InProcess => {
                InProcessDriver::create(guard, &spec.kind, &spec.config, services, policy)
                    .map(|d| Box::new(d) as Box<dyn PayloadDriver>)
            }
            Isolation::Process => {
                let settings = self.isolation_settings()?;
                IsolatedDriver::spawn(
                    guard,
                    &spec.kind,
                    &spec.slot,
                    &spec.config,
                    services,
                    policy,
                    &settings,
                )
                .map(|d| Box::new(d) as Box<dyn PayloadDriver>)
            }
        };
        driver.map_err(|e| {
            format!(
                "plugin `{name}` could not create slot `{}` on {}: {e}",
                spec.slot,
                host.vehicle_id()
            )
        })
    }

    fn providers(&self) -> Vec<ProviderInfo> {
        self.registry()
            .current
            .values()
            .map(|e| ProviderInfo {
                name: e.lib.name.clone(),
                version: e.lib.version.clone(),
                kinds: e.lib.kinds.clone(),
            })
            .collect()
    }
}
