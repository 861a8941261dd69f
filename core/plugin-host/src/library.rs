//! Opening a plugin library: a private copy, `dlopen`, and the header checks that come
//! before anything else is read or called.

use crate::error::HostError;
use skein_plugin_sdk::abi::{
    ABI_VERSION, ENTRY_SYMBOL, ENTRY_SYMBOL_NUL, EntryFn, PluginVTable, RawBytes, build_stamp,
    stamp_differences,
};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

static SHADOW_COUNTER: AtomicU64 = AtomicU64::new(0);

/// A mapped, validated plugin library.
///
/// The library is mapped from a private copy (the *shadow*), never from the file in the
/// plugin directory: glibc's `dlopen` returns the already-mapped library when given a path
/// it has seen, which would make a reload load the old code, and overwriting a mapped file
/// in place (`cp new.so plugin_dir/`) would corrupt the running code. The shadow is deleted
/// when the library is dropped; the mapping itself is never closed (see `Drop`).
pub(crate) struct LoadedLibrary {
    /// `None` only during drop.
    lib: Option<libloading::Library>,
    vtable: *const PluginVTable,
    /// Plugin name.
    pub name: String,
    /// Plugin version.
    pub version: String,
    /// Payload kinds.
    pub kinds: Vec<String>,
    /// The plugin's build stamp (equal to the host's).
    pub build_stamp: String,
    /// The file it was loaded from.
    pub source: PathBuf,
    /// The private copy that is mapped.
    pub shadow: PathBuf,
    /// Whether `shadow` is ours to delete.
    owns_shadow: bool,
}

/// Checks the frozen header of `vtable` (ABI version and vtable size) against ours;
/// nothing else of a vtable is read before it matches.
///
/// # Safety
/// `vtable` is non-null and points to a plugin's vtable of any ABI version, valid while
/// its library is mapped.
unsafe fn check_header(vtable: *const PluginVTable, file: &Path) -> Result<(), HostError> {
    // SAFETY: the first two u32 of every skein vtable, of any ABI version, are
    // `abi_version` and `struct_size` (frozen by the ABI rules).
    let (abi_version, struct_size) = unsafe {
        (
            vtable.cast::<u32>().read(),
            vtable.cast::<u32>().add(1).read(),
        )
    };
    if abi_version != ABI_VERSION {
        return Err(HostError::Incompatible {
            file: file.to_path_buf(),
            difference: format!(
                "ABI version mismatch: the plugin was built for ABI {abi_version}, this skein speaks ABI {ABI_VERSION}"
            ),
        });
    }
    let host_size = std::mem::size_of::<PluginVTable>() as u32;
    if struct_size != host_size {
        return Err(HostError::Incompatible {
            file: file.to_path_buf(),
            difference: format!(
                "vtable size mismatch: the plugin's is {struct_size} bytes, this skein's is {host_size} bytes"
            ),
        });
    }
    Ok(())
}

/// Refuses a plugin whose build stamp differs from ours, naming what differs.
fn check_stamp(stamp: &str, file: &Path) -> Result<(), HostError> {
    let ours = build_stamp();
    if stamp == ours {
        return Ok(());
    }
    let diffs = stamp_differences(stamp, &ours);
    Err(HostError::Incompatible {
        file: file.to_path_buf(),
        difference: format!(
            "build stamp mismatch: {} (plugin stamp `{stamp}`, host stamp `{ours}`)",
            if diffs.is_empty() {
                "formatting differs".to_string()
            } else {
                diffs.join("; ")
            }
        ),
    })
}

/// The plugin's name, version and payload kinds, checked: a name without spaces or
/// slashes, 1 to 64 non-empty kinds.
fn describe(vt: &PluginVTable, file: &Path) -> Result<(String, String, Vec<String>), HostError> {
    let not_a_plugin = |reason: String| HostError::NotAPlugin {
        file: file.to_path_buf(),
        reason,
    };
    let name = utf8(vt.name, "name", file)?;
    if name.is_empty() || name.chars().any(|c| c.is_whitespace() || c == '/') {
        return Err(not_a_plugin(format!(
            "its name {name:?} is empty or contains spaces or slashes"
        )));
    }
    let version = utf8(vt.version, "version", file)?;
    if vt.kinds_len == 0 || vt.kinds_len > 64 || vt.kinds.is_null() {
        return Err(not_a_plugin(format!(
            "it declares {} payload kinds (1 to 64 expected)",
            vt.kinds_len
        )));
    }
    // SAFETY: the vtable has our layout (checked by the caller); `kinds` points to
    // `kinds_len` RawBytes living as long as the library (checked non-null and bounded
    // above).
    let raw_kinds = unsafe { std::slice::from_raw_parts(vt.kinds, vt.kinds_len) };
    let kinds = raw_kinds
        .iter()
        .map(|k| utf8(*k, "payload kind", file))
        .collect::<Result<Vec<_>, _>>()?;
    if kinds.iter().any(|k| k.is_empty()) {
        return Err(not_a_plugin("it declares an empty payload kind".into()));
    }
    Ok((name, version, kinds))
}

// SAFETY: `vtable` points into the mapped library, immutable for as long as `lib` is
// loaded (we keep it loaded until drop); the ABI requires every vtable function to be
// callable from any thread (instances are `Send`, distinct instances may run concurrently).
unsafe impl Send for LoadedLibrary {}
// SAFETY: as above: shared access only reads the immutable vtable.
unsafe impl Sync for LoadedLibrary {}

fn utf8(bytes: RawBytes, what: &str, file: &Path) -> Result<String, HostError> {
    // SAFETY: only called on fields of a vtable whose header matched ours, so the field
    // layout is ours: the ABI guarantees `ptr`/`len` describe bytes that live as long as the
    // library is mapped.
    let slice = unsafe { bytes.as_slice() };
    String::from_utf8(slice.to_vec()).map_err(|_| HostError::NotAPlugin {
        file: file.to_path_buf(),
        reason: format!("its {what} is not UTF-8"),
    })
}

impl LoadedLibrary {
    /// Copies `source` into `shadow_dir`, maps the copy and validates it.
    ///
    /// # Errors
    /// The file cannot be read or mapped, is not a skein plugin, or was built for another
    /// ABI version, vtable size or build stamp (the error names the file and the
    /// difference).
    pub fn open(source: &Path, shadow_dir: &Path) -> Result<LoadedLibrary, HostError> {
        let stem = source
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "plugin".into());
        let shadow = shadow_dir.join(format!(
            "{stem}.{}.{}.so",
            std::process::id(),
            SHADOW_COUNTER.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::copy(source, &shadow).map_err(|e| HostError::Load {
            file: source.to_path_buf(),
            reason: format!("cannot copy it to {}: {e}", shadow.display()),
        })?;
        let opened = Self::map(source, &shadow, true);
        if opened.is_err() {
            let _ = std::fs::remove_file(&shadow);
        }
        opened
    }

    /// Maps `path` itself (no copy; it is never deleted) and validates it. Used by the
    /// `skein plugin-host` child, which is handed the parent's shadow copy.
    ///
    /// # Errors
    /// As [`LoadedLibrary::open`].
    pub fn open_in_place(path: &Path) -> Result<LoadedLibrary, HostError> {
        Self::map(path, path, false)
    }

    fn map(source: &Path, shadow: &Path, owns_shadow: bool) -> Result<LoadedLibrary, HostError> {
        let file = source.to_path_buf();
        // SAFETY: mapping a library runs its initialisers. A plugin directory is trusted
        // code by configuration (as is any shared library skein links); the loader refuses
        // anything outside it unless configured otherwise. A cdylib built with the SDK runs
        // only its std's own initialiser (argument capture).
        let lib = unsafe { libloading::Library::new(shadow) }.map_err(|e| HostError::Load {
            file: file.clone(),
            reason: e.to_string(),
        })?;
        // SAFETY: `EntryFn` is the documented type of the entry symbol; a library that
        // exports the name with another type is not a skein plugin, which the header check
        // right after the call catches before anything else is read.
        let entry: libloading::Symbol<EntryFn> =
            unsafe { lib.get(ENTRY_SYMBOL_NUL) }.map_err(|_| HostError::NotAPlugin {
                file: file.clone(),
                reason: format!("it does not export `{ENTRY_SYMBOL}`"),
            })?;
        // SAFETY: the entry point takes no arguments and, per the ABI, catches its own
        // panics and returns a pointer valid while the library is mapped (or null).
        let vtable = unsafe { entry() };
        if vtable.is_null() {
            return Err(HostError::NotAPlugin {
                file,
                reason: "its entry point returned no vtable (the plugin failed to describe itself)"
                    .into(),
            });
        }
        // SAFETY: non-null, returned by the plugin's entry point and valid while `lib` is
        // mapped (the ABI's contract).
        unsafe { check_header(vtable, &file) }?;
        // SAFETY: ABI version and size match ours, so `vtable` points to a `PluginVTable`
        // with our layout, valid while `lib` is mapped.
        let vt = unsafe { &*vtable };
        let stamp = utf8(vt.build_stamp, "build stamp", &file)?;
        check_stamp(&stamp, &file)?;
        let (name, version, kinds) = describe(vt, &file)?;
        Ok(LoadedLibrary {
            lib: Some(lib),
            vtable,
            name,
            version,
            kinds,
            build_stamp: stamp,
            source: file,
            shadow: shadow.to_path_buf(),
            owns_shadow,
        })
    }

    /// The validated vtable.
    pub fn vtable(&self) -> &PluginVTable {
        // SAFETY: validated at open; valid while `self.lib` is mapped, which is at least as
        // long as `&self`.
        unsafe { &*self.vtable }
    }
}

impl Drop for LoadedLibrary {
    fn drop(&mut self) {
        // Retire, never unmap. A Rust cdylib has its own std, which registers thread-local
        // destructors (pthread keys) in the host's threads as soon as plugin code uses
        // thread-locals (the panic machinery, `thread::current`, the author's own): glibc
        // runs them at thread exit even after `dlclose`, which would jump into unmapped
        // code and crash skein. So the mapping is deliberately leaked (a few MB per retired
        // build, until skein exits); only the private copy on disk is removed (the mapping
        // survives the unlink).
        if let Some(lib) = self.lib.take() {
            std::mem::forget(lib);
        }
        if self.owns_shadow {
            let _ = std::fs::remove_file(&self.shadow);
        }
    }
}
