//! `/api/v1/plugins`: the payload plugin libraries, their instances, and load / unload /
//! reload at run time.
//!
//! - `GET /api/v1/plugins` → `{"plugin_dir", "libraries": [...], "providers": [...],
//!   "refused": [{"file", "reason"}]}`. Each library: `name`, `version`, `kinds`, `file`,
//!   `generation`, `status` (`loaded` | `superseded`), `instances` (`vehicle_id`, `slot`,
//!   `kind`, `isolation`, `pid`, `generation`, `status`: `running` or `stale` when it still
//!   runs a replaced build), `abi_version`, `build_stamp`, `loaded_at_unix_ms`. `providers`
//!   lists every payload provider the vehicles use, plugins and the built-in one.
//! - `POST /api/v1/plugins/load` `{"file": "libx.so"}` (relative to the plugin directory;
//!   a file outside it is refused with 403) → the library.
//! - `POST /api/v1/plugins/unload` `{"name": "x"}` → the library (409 while instances live,
//!   naming them). With `"force": true` the library's instances are stopped first (each
//!   driver's `shutdown` runs; their slots go back to `waiting_for_plugin`, or start on
//!   another provider of their kind) and the answer, once they are gone (at most
//!   [`FORCED_UNLOAD_WAIT`]), adds `stopped_instances` and `still_stopping`.
//! - `POST /api/v1/plugins/reload` `{"name": "x"}` → `{"library", "previous_version",
//!   "previous_generation", "stale_instances"}`; the vehicles re-create the stale
//!   instances on the new build.
//!
//! Errors: 400 for a bad body (naming the field; the bodies are
//! [`requests::plugins`]), 404 unknown plugin, 409 conflicts, 403
//! outside the plugin directory, 422 a file that is not a loadable plugin (the message
//! names the file and, for an ABI mismatch, what differs), 503 without a plugin host
//! (the plugin host's errors become these in [`crate::error`]).

use crate::ApiState;
use crate::error::ApiError;
use crate::requests;
use crate::requests::plugins::{LoadRequest, ReloadRequest, UnloadRequest};
use crate::responses::{PluginsListing, ProviderEntry, RefusedFile, Reloaded};
use axum::Json;
use axum::body::Bytes;
use axum::extract::State;
use axum::http::StatusCode;
use serde_json::{Value, json};
use skein_payload::PayloadFactory;
use skein_plugin_host::{HostError, LibraryInfo, PluginManager};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};

/// How long a forced unload waits for the vehicles to stop the library's instances
/// before it answers (listing those still stopping).
pub const FORCED_UNLOAD_WAIT: std::time::Duration = std::time::Duration::from_secs(5);

/// Most refused files remembered for the listing.
const MAX_REFUSED: usize = 64;

/// The plugin host as the API sees it: the manager and the files it refused.
pub struct PluginsApi {
    manager: PluginManager,
    refused: Mutex<Vec<(PathBuf, String)>>,
}

impl PluginsApi {
    /// Wraps `manager`; `refused` are the files its start-up scan refused (file, reason).
    pub fn new(manager: PluginManager, refused: Vec<(PathBuf, String)>) -> Arc<Self> {
        Arc::new(PluginsApi {
            manager,
            refused: Mutex::new(refused),
        })
    }

    fn remember_refused(&self, file: &Path, reason: String) {
        let mut r = self.refused.lock().unwrap_or_else(PoisonError::into_inner);
        r.retain(|(f, _)| f != file);
        r.push((file.to_path_buf(), reason));
        if r.len() > MAX_REFUSED {
            r.remove(0);
        }
    }

    fn forget_refused(&self, file: &Path) {
        self.refused
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .retain(|(f, _)| f != file);
    }
}

fn library_json(info: &LibraryInfo, current_generation: Option<u64>) -> Value {
    let mut v = serde_json::to_value(info).unwrap_or(Value::Null);
    if let Some(list) = v.get_mut("instances").and_then(Value::as_array_mut) {
        for i in list {
            let stale = match (current_generation, i["generation"].as_u64()) {
                (Some(cur), Some(g)) => g < cur,
                _ => true,
            };
            i["status"] = json!(if stale { "stale" } else { "running" });
        }
    }
    v
}

/// The listing of `GET /api/v1/plugins`.
pub fn list(plugins: Option<&PluginsApi>) -> PluginsListing {
    let builtin = skein_swarm::payload::BuiltinPayloads.providers();
    let provider = |p: &skein_payload::ProviderInfo, source: &'static str| ProviderEntry {
        name: p.name.clone(),
        version: p.version.clone(),
        kinds: p.kinds.clone(),
        source,
    };
    let Some(pl) = plugins else {
        return PluginsListing {
            plugin_dir: None,
            libraries: vec![],
            providers: builtin.iter().map(|p| provider(p, "builtin")).collect(),
            refused: vec![],
        };
    };
    let m = &pl.manager;
    let libraries: Vec<Value> = m
        .libraries()
        .iter()
        .map(|l| library_json(l, m.generation(&l.name)))
        .collect();
    let mut providers: Vec<ProviderEntry> = m
        .providers()
        .iter()
        .map(|p| provider(p, "plugin"))
        .collect();
    providers.extend(builtin.iter().map(|p| provider(p, "builtin")));
    let refused = pl
        .refused
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .iter()
        .map(|(f, r)| RefusedFile {
            file: f.clone(),
            reason: r.clone(),
        })
        .collect();
    PluginsListing {
        plugin_dir: Some(m.config().plugin_dir.clone()),
        libraries,
        providers,
        refused,
    }
}

impl PluginsApi {
    /// Lists the file of a load that failed on the file itself (not a loadable plugin,
    /// or built for another ABI) among the refused files.
    fn remember_if_refused(&self, e: &HostError) {
        if let HostError::Load { file, .. }
        | HostError::NotAPlugin { file, .. }
        | HostError::Incompatible { file, .. } = e
        {
            self.remember_refused(file, e.to_string());
        }
    }
}

/// The plugin host of this API: 503 without one.
fn host(s: &ApiState) -> Result<Arc<PluginsApi>, ApiError> {
    s.plugins
        .clone()
        .ok_or_else(|| ApiError::unavailable("this skein runs without a plugin host"))
}

/// Runs a manager operation off the async workers (it copies and maps files).
async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> Result<T, HostError> + Send + 'static,
) -> Result<Result<T, HostError>, ApiError> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(|e| ApiError::status(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))
}

/// Plugin libraries, their instances, payload providers and refused files
#[utoipa::path(get, path = "/api/v1/plugins",
    responses((status = 200, body = PluginsListing)))]
pub(crate) async fn listing(State(s): State<ApiState>) -> Json<PluginsListing> {
    Json(list(s.plugins.as_deref()))
}

/// Load a plugin library from the plugin directory
#[utoipa::path(post, path = "/api/v1/plugins/load", request_body = LoadRequest,
    responses((status = 200, body = LibraryInfo), (status = 400), (status = 403),
        (status = 409), (status = 422), (status = 503)),
    extensions(("x-skein-swarm-checks" = json!({
        "file": "a loadable plugin library in the plugin directory"
    }))))]
pub(crate) async fn load(State(s): State<ApiState>, body: Bytes) -> Result<Json<Value>, ApiError> {
    let file = requests::plugins::load(&body)?;
    let pl = host(&s)?;
    let m = pl.manager.clone();
    let f = PathBuf::from(&file);
    let info = blocking(move || m.load(&f))
        .await?
        .inspect_err(|e| pl.remember_if_refused(e))?;
    pl.forget_refused(&info.file);
    let current = pl.manager.generation(&info.name);
    Ok(Json(library_json(&info, current)))
}

/// Unload a plugin library (force: stop its instances first)
#[utoipa::path(post, path = "/api/v1/plugins/unload", request_body = UnloadRequest,
    responses((status = 200, body = LibraryInfo), (status = 400), (status = 404),
        (status = 409), (status = 503)))]
pub(crate) async fn unload(
    State(s): State<ApiState>,
    body: Bytes,
) -> Result<Json<Value>, ApiError> {
    let (name, force) = requests::plugins::unload(&body)?;
    let pl = host(&s)?;
    let m = pl.manager.clone();
    if !force {
        let info = blocking(move || m.unload(&name)).await?.map_err(|e| {
            let in_use = matches!(e, HostError::InUse { .. });
            let mut err = ApiError::from(e);
            if in_use {
                err.error
                    .push_str(" (add \"force\": true to stop them first)");
            }
            err
        })?;
        return Ok(Json(library_json(&info, None)));
    }
    // The manager tells the vehicles (PluginEvent::Unloaded), which stop the instances;
    // answer once they are gone.
    let forced = blocking(move || m.unload_force(&name)).await??;
    let deadline = tokio::time::Instant::now() + FORCED_UNLOAD_WAIT;
    let mut live = forced.live_instances();
    while !live.is_empty() && tokio::time::Instant::now() < deadline {
        tokio::time::sleep(std::time::Duration::from_millis(10)).await;
        live = forced.live_instances();
    }
    let mut v = library_json(&forced.library, None);
    v["stopped_instances"] = json!(
        forced
            .library
            .instances
            .iter()
            .filter(|i| !live.iter().any(|l| l.id == i.id))
            .collect::<Vec<_>>()
    );
    v["still_stopping"] = json!(live);
    Ok(Json(v))
}

/// Reload a plugin library from its file; its instances move to the new build
#[utoipa::path(post, path = "/api/v1/plugins/reload", request_body = ReloadRequest,
    responses((status = 200, body = Reloaded), (status = 400), (status = 404),
        (status = 409), (status = 422), (status = 503)))]
pub(crate) async fn reload(
    State(s): State<ApiState>,
    body: Bytes,
) -> Result<Json<Reloaded>, ApiError> {
    let name = requests::plugins::reload(&body)?;
    let pl = host(&s)?;
    let m = pl.manager.clone();
    let report = blocking(move || m.reload(&name))
        .await?
        .inspect_err(|e| pl.remember_if_refused(e))?;
    Ok(Json(Reloaded {
        library: library_json(&report.library, Some(report.library.generation)),
        previous_version: report.previous_version,
        previous_generation: report.previous_generation,
        stale_instances: report.stale_instances,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn without_a_host_only_the_builtin_provider_is_listed() {
        let v = serde_json::to_value(list(None)).unwrap();
        assert_eq!(v["libraries"], json!([]));
        assert_eq!(v["providers"][0]["source"], "builtin");
        assert_eq!(v["providers"][0]["kinds"][0], "fault-fixture");
    }
}
