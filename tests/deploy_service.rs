//! skein as systemd and Docker run it, without a container (`tests/deploy_compose.rs`
//! flies the images):
//!
//! - SIGTERM to `skein agent` with its vehicle in the air: it lands it first (the
//!   simulator's own truth says on the ground and disarmed while the process still runs),
//!   then exits 0; with `shutdown_action = "hold"` PX4 holds (its Hold mode, in the air)
//!   and the agent exits 0 at once. No offboard-loss failsafe either way.
//! - sd_notify (`Type=notify`, `WatchdogSec=`): `READY=1` once the API answers,
//!   `WATCHDOG=1` while the coordinator answers, `STOPPING=1` on SIGTERM, on a datagram
//!   socket the test binds as `NOTIFY_SOCKET`.
//! - `skein health` (the image's `HEALTHCHECK`): 0 against a live API, 1 against none.
//! - The setpoint thread's real-time scheduling as the agent's unit runs it: a non-root
//!   user with only the ambient `CAP_SYS_NICE` (`setpriv`) gets `SCHED_FIFO`; without it,
//!   nothing.
//! - The unit files in `deploy/systemd/`: `systemd-analyze verify` has nothing to say,
//!   and `systemd-analyze security` rates their exposure at most 2.5 ("OK").

mod support;

use serde_json::{Value, json};
use std::os::unix::net::UnixDatagram;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};
use support::{Skein, eventually, try_sim_stats};

/// DDS domain `k` (0 to 3) of this test process's own, apart from the other targets'
/// (`e2e_distributed` 20-97, `e2e_dds` 100-219, `e2e_failover` 220-231).
fn domain(k: u32) -> String {
    ((std::process::id() % 5) * 4 + k).to_string()
}

/// `skein agent --sim 1` on loopback with its stats socket, and `extra` arguments.
fn agent(d: &str, extra: &[&str]) -> Skein {
    let mut args = vec![
        "--sim",
        "1",
        "--sim-base-port",
        "0",
        "--sim-stats",
        "127.0.0.1:0",
        "--domain-id",
        d,
        "--dds-network",
        "127.0.0.1",
        "--http",
        "127.0.0.1:0",
    ];
    args.extend_from_slice(extra);
    Skein::launch_with(&[], &[], "agent", &args)
}

/// The simulator's truth of its one vehicle, `None` once the process is gone.
fn truth(stats: &str) -> Option<Value> {
    try_sim_stats(stats, "stats").map(|s| s["vehicles"][0].clone())
}

/// Takes the agent's vehicle off to 10 m through the agent's own API.
fn take_off(a: &Skein) {
    a.wait_all("connected", 1, Duration::from_secs(60), |v| {
        v["link"]["connected"] == true && v["home"].is_object()
    });
    let (status, body) = a.post(
        "/api/v1/swarm/commands",
        json!({"command": "takeoff", "altitude_m": 10.0}),
    );
    assert_eq!(status, 202, "{body}");
    a.wait_all("hovering", 1, Duration::from_secs(60), |v| {
        v["state"] == "Hovering"
    });
}

/// SIGTERM, then polls the simulator's truth until the process has exited; returns the
/// exit status and every truth seen, oldest first.
fn terminate_watching(a: &mut Skein, stats: &str, within: Duration) -> (Option<i32>, Vec<Value>) {
    a.process.terminate();
    let deadline = Instant::now() + within;
    let mut seen = Vec::new();
    while let Some(t) = truth(stats) {
        seen.push(t);
        assert!(
            Instant::now() < deadline,
            "still running {within:?} after SIGTERM; last truth {}",
            seen.last().unwrap()
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    (a.process.wait_exit(Duration::from_secs(10)), seen)
}

#[test]
fn an_agent_told_to_stop_lands_its_vehicle_then_exits_0() {
    let _one = support::one_at_a_time();
    let mut a = agent(&domain(0), &[]);
    let stats = a.sim_stats_addr();
    take_off(&a);
    let started = Instant::now();
    let (code, seen) = terminate_watching(&mut a, &stats, Duration::from_secs(90));
    let took = started.elapsed().as_secs_f64();
    let out = a.process.stdout_text();
    assert_eq!(code, Some(0), "exit status; stdout:\n{out}");
    assert!(out.contains("shutdown: land first: uav-1"), "{out}");
    assert!(out.contains("shutdown: uav-1 landed after"), "{out}");
    let last = seen.last().expect("the simulator answered after SIGTERM");
    assert_eq!(last["truth"]["landed_state"], "OnGround", "{last}");
    assert_eq!(last["truth"]["armed"], false, "{last}");
    assert_eq!(last["offboard_loss_failsafes"], 0, "{last}");
    // It flew, under skein's command, until it landed: AUTO.LAND, never a failsafe.
    assert!(
        seen.iter()
            .any(|t| t["truth"]["mode_name"] == "LAND" && t["truth"]["landed_state"] != "OnGround"),
        "never seen landing: {:?}",
        seen.iter()
            .map(|t| &t["truth"]["mode_name"])
            .collect::<Vec<_>>()
    );
    eprintln!(
        "{}",
        json!({"sigterm_to_exit_s": took, "truth_polls": seen.len()})
    );
}

#[test]
fn an_agent_told_to_stop_with_shutdown_action_hold_leaves_px4_holding() {
    let _one = support::one_at_a_time();
    let mut a = agent(&domain(1), &["--shutdown-action", "hold"]);
    let stats = a.sim_stats_addr();
    take_off(&a);
    let started = Instant::now();
    let (code, seen) = terminate_watching(&mut a, &stats, Duration::from_secs(30));
    let took = started.elapsed().as_secs_f64();
    let out = a.process.stdout_text();
    assert_eq!(code, Some(0), "exit status; stdout:\n{out}");
    assert!(out.contains("shutdown: uav-1 holds (PX4 Hold)"), "{out}");
    let last = seen.last().expect("the simulator answered after SIGTERM");
    assert_eq!(last["truth"]["mode_name"], "HOLD", "{last}");
    assert_eq!(last["truth"]["landed_state"], "InAir", "{last}");
    assert_eq!(last["offboard_loss_failsafes"], 0, "{last}");
    assert!(took < 15.0, "took {took:.1} s to hold and exit");
}

/// Every datagram on `socket` until `until` says it has enough (or `within` passes).
fn notifications(
    socket: &UnixDatagram,
    within: Duration,
    mut until: impl FnMut(&[String]) -> bool,
) -> Vec<String> {
    let deadline = Instant::now() + within;
    let mut got = Vec::new();
    let mut buf = [0u8; 4096];
    while !until(&got) {
        assert!(
            Instant::now() < deadline,
            "no such notifications within {within:?}: {got:?}"
        );
        if let Ok(n) = socket.recv(&mut buf) {
            got.push(String::from_utf8_lossy(&buf[..n]).into_owned());
        }
    }
    got
}

#[test]
fn sd_notify_says_ready_pings_the_watchdog_and_says_stopping() {
    let dir = std::env::temp_dir().join(format!("skein-notify-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("notify.sock");
    let socket = UnixDatagram::bind(&path).unwrap();
    socket
        .set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    let path_s = path.to_string_lossy().into_owned();
    let d = domain(2);
    let mut c = Skein::launch_with(
        &[],
        // A 1 s watchdog, as `WatchdogSec=1s` gives it: pings at least every 0.5 s.
        &[("NOTIFY_SOCKET", &path_s), ("WATCHDOG_USEC", "1000000")],
        "coordinator",
        &[
            "--http",
            "127.0.0.1:0",
            "--id",
            "notified",
            "--domain-id",
            &d,
            "--dds-network",
            "127.0.0.1",
        ],
    );
    let got = notifications(&socket, Duration::from_secs(30), |g| {
        g.iter().any(|m| m.lines().any(|l| l == "READY=1"))
    });
    let ready = got.iter().find(|m| m.contains("READY=1")).unwrap();
    assert!(ready.contains("STATUS=dashboard at http://"), "{ready}");
    // Ready means serving.
    assert_eq!(c.get("/api/v1/health").0, 200);
    let since = Instant::now();
    let pings = notifications(&socket, Duration::from_secs(10), |g| {
        g.iter()
            .filter(|m| m.lines().any(|l| l == "WATCHDOG=1"))
            .count()
            >= 4
    });
    let span = since.elapsed().as_secs_f64();
    assert!(span < 4.0, "4 watchdog pings took {span:.1} s: {pings:?}");
    c.process.terminate();
    let bye = notifications(&socket, Duration::from_secs(10), |g| {
        g.iter().any(|m| m.lines().any(|l| l == "STOPPING=1"))
    });
    assert_eq!(c.process.wait_exit(Duration::from_secs(20)), Some(0));
    eprintln!(
        "{}",
        json!({"ready": ready, "watchdog_pings_span_s": span,
               "stopping": bye.iter().find(|m| m.contains("STOPPING")).unwrap()})
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `skein health <args>` → (exit status, stdout).
fn health(args: &[&str]) -> (Option<i32>, String) {
    let out = Command::new(support::skein_bin())
        .arg("health")
        .args(args)
        .env_remove("SKEIN_HEALTH_URL")
        .output()
        .expect("run skein health");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
    )
}

#[test]
fn skein_health_exits_0_for_a_live_api_and_1_for_none() {
    let s = Skein::up(&["--sim", "1", "--sim-base-port", "0"]);
    let (code, out) = health(&["--url", &s.base]);
    assert_eq!(code, Some(0), "{out}");
    assert!(out.starts_with("skein health: ok (1 vehicles"), "{out}");
    let closed = format!("http://127.0.0.1:{}", support::free_tcp_port());
    let (code, out) = health(&["--url", &closed, "--timeout-s", "2"]);
    assert_eq!(code, Some(1), "{out}");
    assert!(out.starts_with("skein health: unhealthy"), "{out}");
}

/// The setpoint thread's scheduling (`load.setpoint_priority` of the health) of an agent
/// run as `nobody` by `setpriv` with the capabilities `caps` (`+sys_nice`, or none).
fn setpoint_priority_as_nobody(caps: Option<&str>, d: &str) -> Value {
    let mut prefix = vec![
        "setpriv",
        "--reuid=65534",
        "--regid=65534",
        "--clear-groups",
    ];
    let (inh, amb, bnd);
    match caps {
        Some(c) => {
            inh = format!("--inh-caps=-all,{c}");
            amb = format!("--ambient-caps=-all,{c}");
            bnd = format!("--bounding-set=-all,{c}");
            prefix.extend([inh.as_str(), amb.as_str(), bnd.as_str()]);
        }
        None => prefix.extend(["--inh-caps=-all", "--bounding-set=-all"]),
    }
    prefix.push("--");
    // An empty plugin directory `nobody` can read (the default, beside the binary, may be
    // in a checkout only root can enter).
    let plugins = support::plugins::scratch(&format!("nobody-{}", caps.is_some()));
    let plugins = plugins.to_str().expect("a UTF-8 path");
    let a = Skein::launch_with(
        &prefix,
        &[],
        "agent",
        &[
            "--sim",
            "1",
            "--sim-base-port",
            "0",
            "--domain-id",
            d,
            "--dds-network",
            "127.0.0.1",
            "--http",
            "127.0.0.1:0",
            "--plugin-dir",
            plugins,
        ],
    );
    eventually(
        "the setpoint thread's scheduling",
        Duration::from_secs(30),
        || {
            let (_, h) = a.get("/api/v1/health");
            let p = h["load"]["setpoint_priority"].clone();
            if p.is_object() {
                Ok(p)
            } else {
                Err(h.to_string())
            }
        },
    )
}

#[test]
fn the_agents_unit_capability_gives_the_setpoint_thread_real_time_scheduling() {
    let d = domain(3);
    let with = setpoint_priority_as_nobody(Some("+sys_nice"), &d);
    assert_eq!(with, json!({"kind": "realtime", "priority": 1}));
    let without = setpoint_priority_as_nobody(None, &d);
    assert_eq!(without["kind"], "refused", "{without}");
}

/// A root for `systemd-analyze --root`: systemd's own units (what ours refer to), ours in
/// /etc/systemd/system, and the binary where ExecStart= names it.
fn unit_root(dir: &Path) -> Vec<String> {
    let _ = std::fs::remove_dir_all(dir);
    let system = dir.join("etc/systemd/system");
    std::fs::create_dir_all(&system).unwrap();
    std::fs::create_dir_all(dir.join("usr/local/bin")).unwrap();
    std::fs::create_dir_all(dir.join("usr/lib/systemd")).unwrap();
    let copy = Command::new("cp")
        .args(["-a", "/usr/lib/systemd/system"])
        .arg(dir.join("usr/lib/systemd/"))
        .status()
        .unwrap();
    assert!(copy.success(), "copy systemd's units");
    std::fs::copy(support::skein_bin(), dir.join("usr/local/bin/skein")).unwrap();
    let units = support::workspace().join("deploy/systemd");
    let mut names = Vec::new();
    for e in std::fs::read_dir(&units).unwrap() {
        let path = e.unwrap().path();
        if path.extension().is_some_and(|x| x == "service") {
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            std::fs::copy(&path, system.join(&name)).unwrap();
            names.push(format!("/etc/systemd/system/{name}"));
        }
    }
    names.sort();
    assert_eq!(
        names,
        [
            "/etc/systemd/system/skein-agent.service",
            "/etc/systemd/system/skein-coordinator.service"
        ]
    );
    names
}

#[test]
fn the_unit_files_verify_clean_and_are_hardened() {
    let dir = std::env::temp_dir().join(format!("skein-units-{}", std::process::id()));
    let units = unit_root(&dir);
    let root = format!("--root={}", dir.display());
    let out = Command::new("systemd-analyze")
        .arg("verify")
        .arg(&root)
        .args(&units)
        .output()
        .expect("systemd-analyze (Debian's systemd package; tests/run.sh installs it)");
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    // Unknown keys and bad values are only warnings: nothing may be said.
    assert!(
        out.status.success() && said.trim().is_empty(),
        "systemd-analyze verify: {:?}\n{said}",
        out.status
    );
    let out = Command::new("systemd-analyze")
        .args(["security", "--offline=yes", "--threshold=25"])
        .arg(&root)
        .args(&units)
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&out.stdout);
    let overall: Vec<&str> = said.lines().filter(|l| l.contains("Overall")).collect();
    assert!(
        out.status.success() && overall.len() == 2,
        "exposure above 2.5: {overall:?}\n{said}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    eprintln!("{}", json!({"exposure": overall}));
    let _ = std::fs::remove_dir_all(&dir);
}
