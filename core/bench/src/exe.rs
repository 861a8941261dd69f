//! Where the `skein` executable is: the benchmarks start `skein sim`, `skein up`, `skein
//! agent`, `skein coordinator` and `skein plugin-host` as their own processes.

use std::path::PathBuf;

/// The `skein` executable the benchmarks run: `SKEIN_BIN` if set, else `skein` beside
/// this executable (where `cargo build` puts both, and where `skein bench` finds
/// `skein-bench`).
///
/// # Errors
/// Neither exists (the message says how to get one).
pub fn skein_exe() -> Result<PathBuf, String> {
    if let Some(p) = std::env::var_os("SKEIN_BIN") {
        let p = PathBuf::from(p);
        return if p.is_file() {
            Ok(p)
        } else {
            Err(format!("SKEIN_BIN={} is not a file", p.display()))
        };
    }
    let own = std::env::current_exe().map_err(|e| format!("own executable: {e}"))?;
    let dir = own
        .parent()
        .ok_or_else(|| format!("{} has no directory", own.display()))?;
    // A test harness runs from `target/<profile>/deps`: the binaries are one level up.
    for d in [Some(dir), dir.parent()].into_iter().flatten() {
        let p = d.join("skein");
        if p.is_file() {
            return Ok(p);
        }
    }
    Err(format!(
        "no `skein` executable beside {} (build it with `cargo build --release`, or set \
         SKEIN_BIN)",
        own.display()
    ))
}
