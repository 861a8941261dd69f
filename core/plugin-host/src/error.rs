//! Errors of the plugin manager.

use std::fmt;
use std::path::PathBuf;

/// Why a plugin library could not be loaded, unloaded or reloaded. Every variant names the
/// file or the plugin, and `Display` says what to do about it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum HostError {
    /// The file could not be read, copied or mapped (`dlopen`'s message included).
    Load {
        /// The library file.
        file: PathBuf,
        /// What failed.
        reason: String,
    },
    /// The file is a shared library but not a usable skein plugin (no
    /// `skein_plugin_entry`, no vtable, invalid name or kinds).
    NotAPlugin {
        /// The library file.
        file: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// Built for another ABI version, vtable size or build stamp: refused before anything
    /// of it was called beyond its entry point.
    Incompatible {
        /// The library file.
        file: PathBuf,
        /// What differs (`"ABI version mismatch: …"`, `"build stamp mismatch: messages:
        /// plugin 2, host 1"`).
        difference: String,
    },
    /// No loaded plugin has this name.
    NotFound {
        /// The name asked for.
        name: String,
    },
    /// A plugin of the same name is loaded already (use reload to replace it).
    AlreadyLoaded {
        /// The plugin name.
        name: String,
        /// The file it was loaded from.
        file: PathBuf,
    },
    /// Instances of the plugin still run (stop their payloads first).
    InUse {
        /// The plugin name.
        name: String,
        /// The live instances, as `vehicle/slot`.
        instances: Vec<String>,
    },
    /// The file is outside the plugin directory and loading from elsewhere is not allowed.
    Forbidden {
        /// The file asked for.
        file: PathBuf,
        /// Why.
        reason: String,
    },
}

impl HostError {
    /// The HTTP status that fits (for the API layer): 404 not found, 409 conflicts, 403
    /// forbidden, 422 for a file that is not a loadable plugin.
    pub fn http_status(&self) -> u16 {
        match self {
            HostError::NotFound { .. } => 404,
            HostError::AlreadyLoaded { .. } | HostError::InUse { .. } => 409,
            HostError::Forbidden { .. } => 403,
            HostError::Load { .. }
            | HostError::NotAPlugin { .. }
            | HostError::Incompatible { .. } => 422,
        }
    }
}

impl fmt::Display for HostError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            HostError::Load { file, reason } => {
                write!(f, "{}: cannot load: {reason}", file.display())
            }
            HostError::NotAPlugin { file, reason } => {
                write!(f, "{}: not a skein plugin: {reason}", file.display())
            }
            HostError::Incompatible { file, difference } => write!(
                f,
                "{}: refused: {difference}; rebuild the plugin against this skein's plugin SDK",
                file.display()
            ),
            HostError::NotFound { name } => write!(f, "no plugin named `{name}` is loaded"),
            HostError::AlreadyLoaded { name, file } => write!(
                f,
                "plugin `{name}` is already loaded from {}; reload it instead",
                file.display()
            ),
            HostError::InUse { name, instances } => write!(
                f,
                "plugin `{name}` still has {} live instance(s) ({}); stop those payloads first",
                instances.len(),
                instances.join(", ")
            ),
            HostError::Forbidden { file, reason } => {
                write!(f, "{}: refused: {reason}", file.display())
            }
        }
    }
}

impl std::error::Error for HostError {}
