//! The independent Python peers (`tests/peers/`): the test venv and running its scripts.

use super::workspace;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// The Python interpreter of the test venv (`.venv` at the workspace root) with the
/// peers' requirements installed. Creates or updates it when needed (idempotent: a marker
/// file holds the requirements it was built from), so `cargo test` works on its own too.
pub fn python() -> PathBuf {
    static PYTHON: OnceLock<PathBuf> = OnceLock::new();
    PYTHON
        .get_or_init(|| {
            if let Ok(p) = std::env::var("SKEIN_PYTHON") {
                return PathBuf::from(p);
            }
            let root = workspace();
            let venv = root.join(".venv");
            let py = venv.join("bin/python");
            let reqs = std::fs::read_to_string(root.join("tests/peers/requirements.txt"))
                .expect("tests/peers/requirements.txt");
            let marker = venv.join(".skein-requirements");
            let current = std::fs::read_to_string(&marker).unwrap_or_default();
            if !py.exists() || current != reqs {
                let ok = Command::new("python3")
                    .args(["-m", "venv"])
                    .arg(&venv)
                    .status()
                    .expect("python3 -m venv")
                    .success();
                assert!(ok, "python3 -m venv failed");
                let ok = Command::new(&py)
                    .args(["-m", "pip", "install", "--quiet", "-r"])
                    .arg(root.join("tests/peers/requirements.txt"))
                    .status()
                    .expect("pip install")
                    .success();
                assert!(ok, "pip install of the test requirements failed");
                std::fs::write(&marker, reqs).expect("write marker");
            }
            py
        })
        .clone()
}

/// Runs a peer script `tests/peers/<script>` with `args`; returns (exit code, stdout,
/// stderr). Kills it after `timeout`.
pub fn run_peer(script: &str, args: &[&str], timeout: Duration) -> (Option<i32>, String, String) {
    let script = workspace().join("tests/peers").join(script);
    let mut all = vec![script.to_str().expect("UTF-8 path")];
    all.extend_from_slice(args);
    run_python(&all, timeout)
}

/// Runs the peers' Python ([`python`]) with `args` (a script, or `-m module ...`);
/// returns (exit code, stdout, stderr). Kills it after `timeout`.
pub fn run_python(args: &[&str], timeout: Duration) -> (Option<i32>, String, String) {
    run_python_in(Path::new("."), args, timeout)
}

/// [`run_python`] in the directory `cwd` (for tools that leave caches where they run).
pub fn run_python_in(
    cwd: &Path,
    args: &[&str],
    timeout: Duration,
) -> (Option<i32>, String, String) {
    let mut cmd = Command::new(python());
    cmd.current_dir(cwd).args(args);
    run_to_end(cmd, timeout)
}

/// Runs `cmd` to its end, its output collected; returns (exit code, stdout, stderr).
/// Kills it after `timeout`.
pub fn run_to_end(mut cmd: Command, timeout: Duration) -> (Option<i32>, String, String) {
    let mut child = cmd
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("run {cmd:?}: {e}"));
    let out = child.stdout.take().expect("stdout");
    let err = child.stderr.take().expect("stderr");
    let out_t = std::thread::spawn(move || std::io::read_to_string(out).unwrap_or_default());
    let err_t = std::thread::spawn(move || std::io::read_to_string(err).unwrap_or_default());
    let deadline = Instant::now() + timeout;
    let code = loop {
        if let Some(s) = child.try_wait().expect("try_wait") {
            break s.code();
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    (
        code,
        out_t.join().unwrap_or_default(),
        err_t.join().unwrap_or_default(),
    )
}
