//! Building the payload plugin cdylibs for end-to-end tests, the way
//! `core/plugin-host/tests/plugins/support.rs` does: a real `cargo build` with the test's
//! own cargo, target directory and profile, honouring `SKEIN_PLUGIN_TEST_SELECTION`
//! (`workspace` when the run is `cargo test --workspace`, so no dependency is compiled
//! twice with other features), then copies of the libraries.

#[allow(unused_imports)] // each test binary uses a different subset
pub use super::plugin_build::{build_into, build_new_plugin, lib_file};
use std::path::{Path, PathBuf};

/// A fresh directory private to this test process (`name` tells what it holds);
/// directories of earlier runs whose process is gone are removed.
pub fn scratch(name: &str) -> PathBuf {
    let prefix = "skein-e2e-plugins-";
    if let Ok(dir) = std::fs::read_dir(std::env::temp_dir()) {
        for e in dir.flatten() {
            let n = e.file_name().to_string_lossy().into_owned();
            if let Some(pid) = n
                .strip_prefix(prefix)
                .and_then(|rest| rest.split('-').next())
                && !Path::new(&format!("/proc/{pid}")).exists()
            {
                let _ = std::fs::remove_dir_all(e.path());
            }
        }
    }
    let dir = std::env::temp_dir().join(format!("{prefix}{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}
