//! `skein bench <what>`: the benchmarks live in their own executable, `skein-bench` (crate
//! `skein-bench`, built beside `skein` by `cargo build --release`), so the binary that
//! flies aircraft carries no benchmark code. This subcommand runs it with the same
//! arguments and with `SKEIN_BIN` naming this executable, whose `sim`, `up`, `agent`,
//! `coordinator` and `plugin-host` subcommands the benchmarks start.

use std::ffi::OsString;
use std::path::PathBuf;
use std::process::ExitCode;

/// `skein bench …`: everything after `bench` goes to `skein-bench` (`skein bench --help`
/// lists the benchmarks).
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// The benchmark and its options (see `skein bench --help`).
    #[arg(trailing_var_arg = true, allow_hyphen_values = true, num_args = 0..)]
    args: Vec<OsString>,
}

/// `skein-bench` beside this executable.
fn bench_exe(skein: &std::path::Path) -> Result<PathBuf, String> {
    let p = skein.with_file_name("skein-bench");
    if p.is_file() {
        Ok(p)
    } else {
        Err(format!(
            "`skein bench` runs {}, which is missing: build it with `cargo build --release` \
             (it is a default member of the workspace) or `cargo build -p skein-bench`",
            p.display()
        ))
    }
}

/// Runs `skein-bench` with `args` to its end; its exit status is ours.
///
/// # Errors
/// `skein-bench` is missing or cannot be started.
pub fn run(args: BenchArgs) -> Result<ExitCode, String> {
    let skein = std::env::current_exe().map_err(|e| format!("own executable: {e}"))?;
    let exe = bench_exe(&skein)?;
    let status = std::process::Command::new(&exe)
        .args(&args.args)
        .env("SKEIN_BIN", &skein)
        .status()
        .map_err(|e| format!("cannot start {}: {e}", exe.display()))?;
    Ok(match status.code() {
        Some(0) => ExitCode::SUCCESS,
        Some(c) => ExitCode::from(u8::try_from(c).unwrap_or(1)),
        None => ExitCode::FAILURE,
    })
}
