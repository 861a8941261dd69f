//! Building the payload plugin cdylibs for tests (cargo does not build cdylib
//! dependencies for tests): a real `cargo build` with the test's own cargo, target
//! directory and profile, then copies of the libraries. Shared by skein's end-to-end tests
//! (`tests/support`) and the plugin host's tests (included there with `#[path]`), so both
//! build alike and take the same file lock.
#![allow(dead_code)] // each test binary uses a different subset

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;
use std::time::Instant;

/// Environment variables that select plugin build variants; cleared for the default
/// build.
const VARIANT_VARS: [&str; 2] = ["SKEIN_EXAMPLE_VERSION", "SKEIN_FIXTURE_MISMATCH"];

/// Serialises builds within this process (variants overwrite the same output file).
static BUILD_LOCK: Mutex<()> = Mutex::new(());

/// Where the running test binary was built: the target directory, the profile's output
/// directory, and the cargo arguments that select the same profile and target.
struct Layout {
    target_dir: PathBuf,
    out_dir: PathBuf,
    args: Vec<String>,
}

fn layout() -> Layout {
    // <target>/[<triple>/]<profile>/deps/<test binary>
    let exe = std::env::current_exe().expect("test executable path");
    let out_dir = exe
        .parent()
        .and_then(Path::parent)
        .expect("test binary under <profile>/deps")
        .to_path_buf();
    let profile = out_dir.file_name().unwrap().to_string_lossy().into_owned();
    let above = out_dir.parent().unwrap().to_path_buf();
    let (target_dir, triple) =
        if above.join("CACHEDIR.TAG").exists() || above.join(".rustc_info.json").exists() {
            (above, None)
        } else {
            let triple = above.file_name().unwrap().to_string_lossy().into_owned();
            (above.parent().unwrap().to_path_buf(), Some(triple))
        };
    let mut args = match profile.as_str() {
        "debug" => vec![],
        "release" => vec!["--release".to_string()],
        other => vec!["--profile".to_string(), other.to_string()],
    };
    if let Some(t) = triple {
        args.extend(["--target".to_string(), t]);
    }
    Layout {
        target_dir,
        out_dir,
        args,
    }
}

/// The library file cargo produces for a package (`libskein_plugin_gimbal.so`).
pub fn lib_file(package: &str) -> String {
    format!("lib{}.so", package.replace('-', "_"))
}

/// The package selection of the plugin build. Cargo unifies dependency features over the
/// packages a command selects, so building the plugins alone would compile their shared
/// dependencies (the MAVLink dialect above all) a second time with other features. The
/// selection therefore mirrors the test run's own:
/// - default (`cargo test -p <this crate>`): this crate plus the plugins;
/// - `SKEIN_PLUGIN_TEST_SELECTION=workspace` (set it when the run is
///   `cargo test --workspace`): the whole workspace with all targets, which after the test
///   build only adds the plugin libraries.
fn selection(packages: &[&str]) -> Vec<String> {
    if std::env::var("SKEIN_PLUGIN_TEST_SELECTION").as_deref() == Ok("workspace") {
        return vec!["--workspace".into(), "--all-targets".into()];
    }
    let mut args = vec!["-p".to_string(), env!("CARGO_PKG_NAME").to_string()];
    for p in packages {
        args.extend(["-p".to_string(), p.to_string()]);
    }
    args
}

/// Builds `packages` with `env` set (the other variant variables cleared) and copies
/// each library into `dest`; returns the copies.
pub fn build_into(packages: &[&str], env: &[(&str, &str)], dest: &Path) -> Vec<PathBuf> {
    let _lock = BUILD_LOCK.lock().unwrap_or_else(|p| p.into_inner());
    let l = layout();
    // Other test processes on the same target directory build the same outputs: hold a
    // file lock across build and copy.
    let lock_file = std::fs::File::create(l.target_dir.join("skein-plugin-test-build.lock"))
        .expect("create the build lock file");
    lock_file.lock().expect("lock the build lock file");
    let mut cmd = Command::new(env!("CARGO"));
    cmd.current_dir(workspace_root())
        .arg("build")
        .arg("--quiet")
        .arg("--target-dir")
        .arg(&l.target_dir)
        .args(&l.args)
        .args(selection(packages));
    for v in VARIANT_VARS {
        cmd.env_remove(v);
    }
    remove_package_env(&mut cmd);
    for (k, v) in env {
        cmd.env(k, v);
    }
    let started = Instant::now();
    let out = cmd.output().expect("run cargo build");
    assert!(
        out.status.success(),
        "cargo build {packages:?} {env:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    eprintln!(
        "built {packages:?} {env:?} in {:.1} s",
        started.elapsed().as_secs_f64()
    );
    std::fs::create_dir_all(dest).unwrap();
    packages
        .iter()
        .map(|p| {
            let src = l.out_dir.join(lib_file(p));
            let dst = dest.join(lib_file(p));
            // Write a new file and rename it over the old: a loaded library's file is
            // never rewritten in place.
            let tmp = dest.join(format!(".{}.tmp", lib_file(p)));
            std::fs::copy(&src, &tmp).unwrap_or_else(|e| panic!("copy {}: {e}", src.display()));
            std::fs::rename(&tmp, &dst).unwrap();
            dst
        })
        .collect()
}

/// Removes from `cmd`'s environment what cargo set for this test process about its own
/// package (`CARGO_MANIFEST_DIR`, `CARGO_PKG_*`, …): build scripts that track those
/// variables (ring's) would otherwise see a build other than the one a shell's `cargo test`
/// makes, and rebuild ring and everything on it (the skein binary under test included)
/// in every test that builds plugins, and again in the next `cargo test`.
fn remove_package_env(cmd: &mut Command) {
    for (name, _) in std::env::vars_os() {
        let n = name.to_string_lossy();
        if n.starts_with("CARGO_MANIFEST_")
            || n.starts_with("CARGO_PKG_")
            || n.starts_with("CARGO_BIN_")
            || matches!(
                n.as_ref(),
                "CARGO_CRATE_NAME"
                    | "CARGO_PRIMARY_PACKAGE"
                    | "CARGO_TARGET_TMPDIR"
                    | "CARGO_RUSTC_CURRENT_DIR"
                    | "OUT_DIR"
            )
        {
            cmd.env_remove(&name);
        }
    }
}

/// The workspace root (both including crates live two levels below it).
fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .canonicalize()
        .expect("workspace root")
}

/// Writes a plugin crate with `skein plugin new NAME --kind KIND --dir crate_dir` (run
/// with the `skein` binary `skein`) and builds it as a newcomer would (`cargo build` in
/// the crate, its own workspace), with `CARGO_TARGET_DIR` under this test's target
/// directory (`plugin-new/`) so the SDK and its dependencies are compiled once and reused
/// by later runs. Returns the built library.
pub fn build_new_plugin(skein: &str, name: &str, kind: &str, crate_dir: &Path) -> PathBuf {
    let out = Command::new(skein)
        .args(["plugin", "new", name, "--kind", kind, "--dir"])
        .arg(crate_dir)
        .output()
        .expect("run skein plugin new");
    assert!(
        out.status.success(),
        "skein plugin new failed:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let l = layout();
    let target = l.target_dir.join("plugin-new");
    // Concurrent test processes share that target directory: one build at a time.
    std::fs::create_dir_all(&target).unwrap();
    let lock_file = std::fs::File::create(target.join("skein-plugin-new.lock"))
        .expect("create the build lock file");
    lock_file.lock().expect("lock the build lock file");
    let started = Instant::now();
    let out = Command::new(env!("CARGO"))
        .current_dir(crate_dir)
        .args(["build", "--quiet"])
        .env("CARGO_TARGET_DIR", &target)
        .env_remove("RUSTFLAGS")
        .output()
        .expect("run cargo build");
    assert!(
        out.status.success(),
        "cargo build of the new plugin `{name}` failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    eprintln!(
        "built the new plugin `{name}` in {:.1} s",
        started.elapsed().as_secs_f64()
    );
    target.join("debug").join(lib_file(name))
}
