//! `skein bench swarm --peer pymavlink`: the same swarm flown by a plain pymavlink loop
//! (`tests/peers/pymavlink_loop.py`), against a fresh simulator process of the same
//! profile, in the same run, so that skein's CPU per vehicle-second is compared with the
//! baseline a user would write, measured minutes apart on the same machine, not against a
//! number from another day. `--peer floor` flies it with the least any controller could
//! spend instead (see `crate::floor`); [`fly_peer`] picks the baseline by name.

use crate::SwarmBenchArgs;
use crate::round;
use crate::sim_process::SimProcess;
use crate::stack::{candidate_base, f64_at, late_intervals, u64_at};
use serde_json::{Value, json};
use std::path::PathBuf;
use std::process::Stdio;
use std::time::Duration;
use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio::process::Command;

/// The baselines `--peer` accepts.
pub const PEERS: &[&str] = &["pymavlink", "floor"];

/// Flies the swarm of `args` with the baseline `name` (one of [`PEERS`]) and returns its
/// figures (see [`peer_report`]).
///
/// # Errors
/// An unknown baseline, or the baseline failing.
pub(crate) async fn fly_peer(args: &SwarmBenchArgs, name: &str) -> Result<Value, String> {
    match name {
        "pymavlink" => {
            eprintln!("bench: the same swarm with a plain pymavlink loop");
            pymavlink(args, args.peer_script.clone()).await
        }
        "floor" => {
            eprintln!("bench: the same swarm with the floor controller (datagrams only)");
            crate::floor::floor(args).await
        }
        other => Err(format!("--peer {other}: one of {}", PEERS.join(", "))),
    }
}

/// The Python interpreter with pymavlink: `SKEIN_PYTHON`, else the repository's `.venv`
/// (what `tests/run.sh` prepares), else `python3`.
fn python() -> PathBuf {
    if let Some(p) = std::env::var_os("SKEIN_PYTHON") {
        return PathBuf::from(p);
    }
    let venv = workspace().join(".venv/bin/python");
    if venv.is_file() {
        venv
    } else {
        PathBuf::from("python3")
    }
}

/// The repository this benchmark was built from (the peer script lives there).
fn workspace() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Flies the swarm of `args` with the pymavlink loop (`script`, or the repository's) and
/// returns its figures: `cpu_s` over the window, `cpu_ms_per_vehicle_second`,
/// `late_fraction` as the simulator received its setpoints, `offboard_loss_failsafes`,
/// `all_offboard`.
///
/// # Errors
/// The script or the simulator failing, or the vehicles not hovering in time.
pub(crate) async fn pymavlink(
    args: &SwarmBenchArgs,
    script: Option<PathBuf>,
) -> Result<Value, String> {
    let script = script.unwrap_or_else(|| workspace().join("tests/peers/pymavlink_loop.py"));
    if !script.is_file() {
        return Err(format!(
            "{}: no pymavlink loop there (give --peer-script)",
            script.display()
        ));
    }
    let setup = args
        .setup_timeout_s
        .unwrap_or(60.0 + 0.1 * args.vehicles as f64);
    let mut last = String::new();
    for attempt in 0..5 {
        let base = candidate_base(args.vehicles, 100 + attempt)
            .ok_or("no block of free UDP ports for the pymavlink loop")?;
        match fly(args, &script, base, setup).await {
            Ok(v) => return Ok(v),
            // A port of the block was taken (the script cannot bind it): another block.
            Err(e) if e.contains("Address already in use") => last = e,
            Err(e) => return Err(e),
        }
    }
    Err(last)
}

async fn fly(
    args: &SwarmBenchArgs,
    script: &std::path::Path,
    base: u16,
    setup_s: f64,
) -> Result<Value, String> {
    let mut child = spawn_loop(args, script, base, setup_s)?;
    let pid = child.id();
    let mut lines = BufReader::new(child.stdout.take().ok_or("script stdout")?).lines();
    let mut stdin = child.stdin.take().ok_or("script stdin")?;
    let errors = tokio::spawn(read_all(child.stderr.take().ok_or("script stderr")?));
    // The script has bound its ports once it runs; give it a moment before the simulator
    // starts sending to them by waiting for the simulator's own start.
    // The loop keeps a port per vehicle, whatever skein's run shared.
    let per_vehicle = SwarmBenchArgs {
        vehicles_per_port: 1,
        ..args.clone()
    };
    let mut sim = SimProcess::start(&per_vehicle, base).await?;
    let wait = Duration::from_secs_f64(setup_s + 30.0);
    let ready = tokio::time::timeout(wait, lines.next_line()).await;
    let line = match ready {
        Ok(Ok(Some(l))) => l,
        _ => {
            sim.stop().await;
            let _ = child.start_kill();
            let why = errors.await.unwrap_or_default();
            return Err(format!("the pymavlink loop did not get ready: {why}"));
        }
    };
    if line.trim() != "ready" {
        sim.stop().await;
        return Err(format!("the pymavlink loop said: {line}"));
    }
    sim.ask("reset").await?;
    let sim_cpu0 = sim.pid.and_then(|p| crate::cpu_seconds(Some(p)));
    stdin
        .write_all(b"go\n")
        .await
        .map_err(|e| format!("script stdin: {e}"))?;
    let window = Duration::from_secs_f64(args.seconds + 30.0);
    let report = tokio::time::timeout(window, lines.next_line()).await;
    let summary = sim.ask("summary").await;
    let sim_cpu1 = sim.pid.and_then(|p| crate::cpu_seconds(Some(p)));
    sim.stop().await;
    let _ = child.wait().await;
    let line = match report {
        Ok(Ok(Some(l))) => l,
        _ => return Err("the pymavlink loop did not report".into()),
    };
    let peer: Value =
        serde_json::from_str(&line).map_err(|e| format!("pymavlink loop report {line}: {e}"))?;
    if let Some(e) = peer.get("error") {
        return Err(format!("pymavlink loop: {e}"));
    }
    let sim_cpu_s = match (sim_cpu0, sim_cpu1) {
        (Some(a), Some(b)) => json!(round(b - a, 2)),
        _ => Value::Null,
    };
    Ok(peer_report(
        "pymavlink",
        args,
        pid,
        &peer,
        &summary?,
        sim_cpu_s,
    ))
}

/// Starts the pymavlink loop `script` on the ports from `base`, its stdio piped.
fn spawn_loop(
    args: &SwarmBenchArgs,
    script: &std::path::Path,
    base: u16,
    setup_s: f64,
) -> Result<tokio::process::Child, String> {
    Command::new(python())
        .arg(script)
        .args(["--base-port", &base.to_string()])
        .args(["--vehicles", &args.vehicles.to_string()])
        .args(["--rate-hz", &args.rate_hz.to_string()])
        .args(["--seconds", &args.seconds.to_string()])
        .args(["--altitude-m", &args.altitude_m.to_string()])
        .args(["--timeout", &setup_s.to_string()])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .kill_on_drop(true)
        .spawn()
        .map_err(|e| format!("cannot start {}: {e}", python().display()))
}

/// Everything `stderr` says until it closes.
async fn read_all(stderr: tokio::process::ChildStderr) -> String {
    let mut text = String::new();
    let mut lines = BufReader::new(stderr).lines();
    while let Ok(Some(l)) = lines.next_line().await {
        text.push_str(&l);
        text.push('\n');
    }
    text
}

/// The figures of baseline `name` (process `pid`): from its own report `peer` (`cpu_s`
/// over the window, s; `setpoints_sent`), the simulator's `summary` of the window
/// (lateness over 1.25 periods, intervals in ms, setpoints received, failsafes, modes),
/// and the simulator's CPU meanwhile (`sim_cpu_s`, s).
pub(crate) fn peer_report(
    name: &str,
    args: &SwarmBenchArgs,
    pid: Option<u32>,
    peer: &Value,
    summary: &Value,
    sim_cpu_s: Value,
) -> Value {
    let period_ms = 1e3 / args.rate_hz;
    let threshold = 1.25 * period_ms;
    let intervals = u64_at(&summary["setpoint_intervals"], "count");
    let late = late_intervals(&summary["setpoint_interval_buckets"], threshold);
    let cpu = peer["cpu_s"].as_f64().unwrap_or(f64::NAN);
    let n = args.vehicles as f64;
    json!({
        "peer": name,
        "pid": pid,
        "cpu_s": cpu,
        "cpu_ms_per_vehicle_second": round(cpu * 1e3 / (n * args.seconds), 3),
        "late_fraction": if intervals == 0 { 1.0 } else { late as f64 / intervals as f64 },
        "late_intervals": late,
        "intervals": intervals,
        "interval_ms_p99": f64_at(&summary["setpoint_intervals"], &["p99_ms"]),
        "interval_ms_max": f64_at(&summary["setpoint_intervals"], &["max_ms"]),
        "setpoints_sent": peer["setpoints_sent"],
        "setpoints_received": u64_at(summary, "setpoints_received"),
        "offboard_loss_failsafes": u64_at(summary, "offboard_loss_failsafes"),
        "all_offboard": summary["modes"]["OFFBOARD"].as_u64().unwrap_or(0) == args.vehicles as u64,
        "sim_cpu_s": sim_cpu_s,
    })
}
