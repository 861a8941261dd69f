//! Shared support for skein's end-to-end tests: run the `skein` binary as a process on
//! free ports, talk to it over HTTP only, poll with deadlines, and find the Python peers.
#![allow(dead_code)] // each test binary uses a different subset

use serde_json::{Value, json};
use std::io::{BufRead, BufReader};
use std::net::{SocketAddr, TcpListener, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

pub mod bench;
pub mod counter_uas;
pub mod netns;
pub mod payloads;
mod plugin_build;
mod python;

#[allow(unused_imports)] // each test binary uses a different subset
pub use python::{python, run_peer, run_python, run_python_in};

/// The `skein` binary cargo built for this test run.
pub fn skein_bin() -> &'static str {
    env!("CARGO_BIN_EXE_skein")
}

/// The workspace root.
pub fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .canonicalize()
        .expect("workspace root")
}

/// The flying tests measure setpoint gaps on a 2-core machine: one swarm at a time within
/// a test binary (hold the guard for the whole test).
pub fn one_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());
    ONE_AT_A_TIME
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Asserts that no simulated vehicle took the offboard-loss failsafe and that no setpoint
/// gap in OFFBOARD reached 100 ms since the simulator's last reset (stats socket at
/// `stats_addr`); returns the worst gap, ms.
pub fn assert_no_failsafe_and_no_gap(stats_addr: &str) -> f64 {
    let stats = sim_stats(stats_addr, "stats");
    let mut worst = 0.0f64;
    for v in stats["vehicles"].as_array().unwrap() {
        let sysid = &v["sysid"];
        assert_eq!(
            v["offboard_loss_failsafes"], 0,
            "sysid {sysid} failed safe: {v}"
        );
        let gap = v["setpoint_max_gap_offboard_ms"].as_f64().unwrap();
        assert!(gap < 100.0, "sysid {sysid}: setpoint gap {gap} ms");
        worst = worst.max(gap);
    }
    worst
}

/// Polls `f` every 50 ms until it returns `Some`, or panics after `timeout` with `what`
/// and the last thing `describe` said.
pub fn eventually<T>(what: &str, timeout: Duration, mut f: impl FnMut() -> Result<T, String>) -> T {
    let deadline = Instant::now() + timeout;
    loop {
        match f() {
            Ok(v) => return v,
            Err(last) => {
                if Instant::now() > deadline {
                    panic!("timed out after {timeout:?} waiting for {what}; last: {last}");
                }
            }
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Polls `f` every 100 ms until it has returned `Ok` on every poll for `hold` in a row,
/// and returns those values, oldest first; an `Err` starts the run again. Panics after
/// `timeout` with `what` and the last `Err`.
pub fn steady_for<T>(
    what: &str,
    hold: Duration,
    timeout: Duration,
    mut f: impl FnMut() -> Result<T, String>,
) -> Vec<T> {
    let deadline = Instant::now() + timeout;
    let mut run: Option<(Instant, Vec<T>)> = None;
    let mut last = String::from("never polled");
    loop {
        let now = Instant::now();
        match f() {
            Ok(v) => {
                let (since, values) = run.get_or_insert_with(|| (now, Vec::new()));
                values.push(v);
                if now.duration_since(*since) >= hold {
                    return run.map(|(_, values)| values).unwrap_or_default();
                }
            }
            Err(e) => {
                run = None;
                last = e;
            }
        }
        if Instant::now() > deadline {
            panic!(
                "timed out after {timeout:?} waiting for {what} ({hold:?} in a row); last: {last}"
            );
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// A running `skein` process; killed on drop.
pub struct Process {
    child: Child,
    /// Every stdout line so far.
    pub stdout: Arc<Mutex<Vec<String>>>,
    /// Every stderr line so far (kept for failure messages).
    pub stderr: Arc<Mutex<Vec<String>>>,
    /// Set when stderr reached its end (the reader has every line).
    stderr_closed: Arc<std::sync::atomic::AtomicBool>,
    lines: mpsc::Receiver<String>,
}

impl Process {
    /// Starts `skein <args>`.
    pub fn start(args: &[&str]) -> Process {
        Process::start_in(None, args)
    }

    /// Starts `skein <args>` in network namespace `netns` (`ip netns exec`, which execs
    /// skein itself: the child's pid is skein's), or here with `None`.
    pub fn start_in(netns: Option<&str>, args: &[&str]) -> Process {
        let mut cmd = match netns {
            Some(ns) => {
                let mut c = Command::new("ip");
                c.args(["netns", "exec", ns, skein_bin()]);
                c
            }
            None => Command::new(skein_bin()),
        };
        let mut child = cmd
            .args(args)
            .env("SKEIN_LOG", "info")
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start skein");
        let stdout = Arc::new(Mutex::new(Vec::new()));
        let stderr = Arc::new(Mutex::new(Vec::new()));
        let (tx, rx) = mpsc::channel();
        let out = child.stdout.take().expect("stdout");
        let so = stdout.clone();
        std::thread::spawn(move || {
            for line in BufReader::new(out).lines().map_while(Result::ok) {
                so.lock().unwrap().push(line.clone());
                let _ = tx.send(line);
            }
        });
        let err = child.stderr.take().expect("stderr");
        let se = stderr.clone();
        let stderr_closed = Arc::new(std::sync::atomic::AtomicBool::new(false));
        let closed = stderr_closed.clone();
        std::thread::spawn(move || {
            for line in BufReader::new(err).lines().map_while(Result::ok) {
                se.lock().unwrap().push(line);
            }
            closed.store(true, std::sync::atomic::Ordering::Release);
        });
        Process {
            child,
            stdout,
            stderr,
            stderr_closed,
            lines: rx,
        }
    }

    /// Waits for a stdout line containing `needle` and returns it.
    pub fn wait_line(&mut self, needle: &str, timeout: Duration) -> String {
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(l) if l.contains(needle) => return l,
                Ok(_) => continue,
                Err(_) => panic!(
                    "no stdout line with `{needle}` within {timeout:?}; exit: {:?}\nstderr:\n{}",
                    self.child.try_wait(),
                    self.stderr_text()
                ),
            }
        }
    }

    /// Waits for the process to exit and returns its status code. Its stderr is read to
    /// the end first (up to 5 s more, in case a child of it still holds the pipe), so
    /// that [`Process::stderr_text`] has everything it wrote.
    pub fn wait_exit(&mut self, timeout: Duration) -> Option<i32> {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(s) = self.child.try_wait().expect("try_wait") {
                let drained = Instant::now() + Duration::from_secs(5);
                while !self
                    .stderr_closed
                    .load(std::sync::atomic::Ordering::Acquire)
                    && Instant::now() < drained
                {
                    std::thread::sleep(Duration::from_millis(5));
                }
                return s.code();
            }
            assert!(
                Instant::now() < deadline,
                "process did not exit within {timeout:?}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Everything on stderr so far.
    pub fn stderr_text(&self) -> String {
        self.stderr.lock().unwrap().join("\n")
    }

    /// The process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }
}

impl Drop for Process {
    /// Kills the process; when a test is failing, prints its last warnings and errors, so
    /// that a CI log tells what the process saw.
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        if std::thread::panicking() {
            let lines = self.stderr.lock().unwrap_or_else(|e| e.into_inner());
            let notable: Vec<&String> = lines
                .iter()
                .filter(|l| l.contains("WARN") || l.contains("ERROR"))
                .collect();
            let from = notable.len().saturating_sub(30);
            eprintln!(
                "--- last {} warnings and errors of the process under test ---",
                notable.len() - from
            );
            for l in &notable[from..] {
                eprintln!("{l}");
            }
        }
    }
}

/// A running `skein up` with its dashboard URL.
pub struct Skein {
    /// The process.
    pub process: Process,
    /// `http://127.0.0.1:PORT`
    pub base: String,
    agent: ureq::Agent,
}

impl Skein {
    /// `skein up <args> --http 127.0.0.1:0` and waits for the dashboard line.
    pub fn up(args: &[&str]) -> Skein {
        Skein::launch("up", args)
    }

    /// `skein coordinator <args> --http 127.0.0.1:0` (a candidate of the election, no
    /// vehicles) and waits for the dashboard line.
    pub fn coordinator(args: &[&str]) -> Skein {
        Skein::launch("coordinator", args)
    }

    /// `skein <subcommand> --http 127.0.0.1:0 <args>` and waits for the dashboard line.
    fn launch(subcommand: &str, args: &[&str]) -> Skein {
        let mut all = vec!["--http", "127.0.0.1:0"];
        all.extend_from_slice(args);
        Skein::launch_in(None, subcommand, &all)
    }

    /// `skein <subcommand> <args>` in network namespace `netns` (`args` give `--http`),
    /// and waits for the dashboard line.
    pub fn launch_in(netns: Option<&str>, subcommand: &str, args: &[&str]) -> Skein {
        let mut all = vec![subcommand];
        all.extend_from_slice(args);
        let mut process = Process::start_in(netns, &all);
        let line = process.wait_line("dashboard at", Duration::from_secs(60));
        let url = line
            .split_whitespace()
            .find(|w| w.starts_with("http://"))
            .expect("url in the dashboard line")
            .trim_end_matches('/')
            .to_string();
        let agent: ureq::Agent = ureq::Agent::config_builder()
            .http_status_as_error(false)
            .timeout_global(Some(Duration::from_secs(20)))
            .build()
            .into();
        Skein {
            process,
            base: url,
            agent,
        }
    }

    /// `skein up --sim n` on free ports.
    pub fn sim(n: usize) -> Skein {
        let n = n.to_string();
        Skein::up(&["--sim", &n, "--sim-base-port", "0"])
    }

    fn read(mut r: ureq::http::Response<ureq::Body>) -> (u16, Value) {
        let status = r.status().as_u16();
        let text = r.body_mut().read_to_string().unwrap_or_default();
        let v = serde_json::from_str(&text).unwrap_or(Value::String(text));
        (status, v)
    }

    /// `GET path` → (status, JSON). A GET is idempotent: a connection cut by an API
    /// restart (a pooled keep-alive connection the old server closed) is retried on a
    /// new one, as browsers do.
    pub fn get(&self, path: &str) -> (u16, Value) {
        let url = format!("{}{path}", self.base);
        let mut last = None;
        for _ in 0..3 {
            match self.agent.get(&url).call() {
                Ok(r) => return Self::read(r),
                Err(e) => last = Some(e),
            }
        }
        panic!("GET {url}: {last:?}")
    }

    /// `POST path` with a JSON body.
    pub fn post(&self, path: &str, body: Value) -> (u16, Value) {
        Self::read(
            self.agent
                .post(format!("{}{path}", self.base))
                .send_json(body)
                .expect("POST"),
        )
    }

    /// `PUT path` with a JSON body.
    pub fn put(&self, path: &str, body: Value) -> (u16, Value) {
        Self::read(
            self.agent
                .put(format!("{}{path}", self.base))
                .send_json(body)
                .expect("PUT"),
        )
    }

    /// `DELETE path`.
    pub fn delete(&self, path: &str) -> (u16, Value) {
        Self::read(
            self.agent
                .delete(format!("{}{path}", self.base))
                .call()
                .expect("DELETE"),
        )
    }

    /// `method path` with a raw body.
    pub fn raw(&self, method: &str, path: &str, body: &str) -> (u16, Value) {
        let url = format!("{}{path}", self.base);
        let r = match method {
            "POST" => self
                .agent
                .post(url)
                .header("content-type", "application/json")
                .send(body),
            "PUT" => self
                .agent
                .put(url)
                .header("content-type", "application/json")
                .send(body),
            other => panic!("unsupported method {other}"),
        };
        Self::read(r.expect("request"))
    }

    /// The vehicles, sorted by id.
    pub fn vehicles(&self) -> Vec<Value> {
        let (status, v) = self.get("/api/v1/vehicles");
        assert_eq!(status, 200, "{v}");
        v.as_array().cloned().unwrap_or_default()
    }

    /// Waits until `pred` holds for every one of exactly `n` vehicles.
    pub fn wait_all(
        &self,
        what: &str,
        n: usize,
        timeout: Duration,
        pred: impl Fn(&Value) -> bool,
    ) -> Vec<Value> {
        eventually(what, timeout, || {
            let vs = self.vehicles();
            if vs.len() == n && vs.iter().all(&pred) {
                Ok(vs)
            } else {
                Err(summary(&vs))
            }
        })
    }
}

/// A one-line picture of the vehicles for failure messages.
pub fn summary(vs: &[Value]) -> String {
    vs.iter()
        .map(|v| {
            format!(
                "{}:{}/{}/armed={}/alt={:.1}",
                v["id"].as_str().unwrap_or("?"),
                v["state"].as_str().unwrap_or("?"),
                v["px4_mode"].as_str().unwrap_or("?"),
                v["armed"],
                v["position"]["relative_alt_m"].as_f64().unwrap_or(f64::NAN)
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// A free TCP port on 127.0.0.1 (released before returning: a small race is possible).
pub fn free_tcp_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("free port")
}

/// `n` consecutive free UDP ports on 127.0.0.1 (checked by binding each).
pub fn free_udp_range(n: u16) -> u16 {
    for _ in 0..200 {
        let probe = UdpSocket::bind("127.0.0.1:0").expect("bind");
        let base = probe.local_addr().expect("addr").port();
        drop(probe);
        if base.checked_add(n).is_none() || base < 20_000 {
            continue;
        }
        let socks: Vec<_> = (0..n)
            .map(|i| UdpSocket::bind(SocketAddr::from(([127, 0, 0, 1], base + i))))
            .collect();
        if socks.iter().all(Result::is_ok) {
            return base;
        }
    }
    panic!("no {n} consecutive free UDP ports");
}

/// One command to a simulator stats socket (`stats`, `reset`, …) → its JSON answer.
pub fn sim_stats(addr: &str, command: &str) -> Value {
    use std::io::Write;
    let mut s = std::net::TcpStream::connect(addr).expect("connect to the stats socket");
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    s.write_all(format!("{command}\n").as_bytes()).unwrap();
    let mut line = String::new();
    BufReader::new(s)
        .read_line(&mut line)
        .expect("stats answer");
    serde_json::from_str(&line).expect("stats JSON")
}

impl Skein {
    /// `POST path` that returns `None` when the connection is cut (the API server itself
    /// may be what the request restarts).
    pub fn try_post(&self, path: &str, body: Value) -> Option<(u16, Value)> {
        self.agent
            .post(format!("{}{path}", self.base))
            .send_json(body)
            .ok()
            .map(Self::read)
    }

    /// The supervision record at `path` (`restarts`, `status`, `last_failure` …).
    pub fn supervised(&self, path: &str) -> Option<Value> {
        fn find(node: &Value, path: &str) -> Option<Value> {
            if node["path"] == path {
                return Some(node.clone());
            }
            node["children"]
                .as_array()?
                .iter()
                .find_map(|c| find(c, path))
        }
        let (status, tree) = self.get("/api/v1/supervision");
        assert_eq!(status, 200, "{tree}");
        find(&tree, path)
    }

    /// Kills the process with SIGKILL (no goodbye: no last lease, no clean shutdown) and
    /// waits for it to exit.
    pub fn kill_hard(&mut self) {
        let status = std::process::Command::new("kill")
            .args(["-KILL", &self.process.pid().to_string()])
            .status()
            .expect("kill");
        assert!(status.success());
        let _ = self.process.wait_exit(Duration::from_secs(10));
    }

    /// The `host:port` of the simulator stats socket (`--sim-stats`), from stdout.
    pub fn sim_stats_addr(&self) -> String {
        let out = self.process.stdout.lock().unwrap();
        out.iter()
            .find_map(|l| l.strip_prefix("skein: simulator stats at "))
            .expect("skein printed its simulator stats address (--sim-stats)")
            .to_string()
    }
}

/// Listens to `ws://…/api/v1/stream` in a thread and keeps every event (not the
/// periodic `vehicles` frames).
pub struct EventLog {
    events: Arc<Mutex<Vec<Value>>>,
}

impl EventLog {
    /// Connects to the stream of `base` (`http://127.0.0.1:PORT`).
    pub fn connect(base: &str) -> EventLog {
        let url = format!("{}/api/v1/stream", base.replacen("http://", "ws://", 1));
        let events = Arc::new(Mutex::new(Vec::new()));
        let store = events.clone();
        let (ready_tx, ready_rx) = mpsc::channel();
        std::thread::spawn(move || {
            let rt = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .unwrap();
            rt.block_on(async move {
                use futures_util::StreamExt;
                let (mut ws, _) = tokio_tungstenite::connect_async(&url).await.expect("ws");
                let _ = ready_tx.send(());
                while let Some(Ok(msg)) = ws.next().await {
                    if let Ok(text) = msg.to_text()
                        && let Ok(v) = serde_json::from_str::<Value>(text)
                        && v["type"] != "vehicles"
                    {
                        store.lock().unwrap().push(v);
                    }
                }
            });
        });
        ready_rx
            .recv_timeout(Duration::from_secs(10))
            .expect("stream connected");
        EventLog { events }
    }

    /// Events of `kind` so far.
    pub fn of_type(&self, kind: &str) -> Vec<Value> {
        self.events
            .lock()
            .unwrap()
            .iter()
            .filter(|e| e["type"] == kind)
            .cloned()
            .collect()
    }
}

impl Skein {
    /// `skein up --sim n` with its simulator on free ports and its stats socket on
    /// (`sim_stats_addr`), plus `extra` arguments.
    pub fn up_sim(n: usize, extra: &[&str]) -> Skein {
        let n = n.to_string();
        let mut args = vec![
            "--sim",
            &n,
            "--sim-base-port",
            "0",
            "--sim-stats",
            "127.0.0.1:0",
        ];
        args.extend_from_slice(extra);
        Skein::up(&args)
    }

    /// `GET /api/v1/formation`.
    pub fn formation(&self) -> Value {
        self.get("/api/v1/formation").1
    }

    /// Waits until every one of `n` members is within `tol` metres of its slot.
    pub fn settled(&self, n: usize, tol: f64, within: Duration) {
        eventually(&format!("{n} members within {tol} m"), within, || {
            let f = self.formation();
            let members = f["members"].as_array().cloned().unwrap_or_default();
            if members.len() == n
                && members
                    .iter()
                    .all(|m| m["error_m"].as_f64().unwrap_or(99.0) < tol)
            {
                Ok(())
            } else {
                Err(format!("{f}"))
            }
        });
    }

    /// Waits until `n` vehicles are connected with a position and a home (a vehicle
    /// without home refuses takeoff), takes the swarm off to `altitude_m` and waits until
    /// all `n` hover.
    pub fn take_off(&self, n: usize, altitude_m: f64) {
        self.wait_all(
            "connected with positions and homes",
            n,
            Duration::from_secs(60),
            |v| {
                v["link"]["connected"] == true && v["position"].is_object() && v["home"].is_object()
            },
        );
        let (status, body) = self.post(
            "/api/v1/swarm/commands",
            json!({"command": "takeoff", "altitude_m": altitude_m}),
        );
        assert_eq!(status, 202, "{body}");
        assert_eq!(body["refused"], json!([]), "{body}");
        self.wait_all("hovering", n, Duration::from_secs(90), |v| {
            v["state"] == "Hovering"
        });
    }

    /// Restarts of the supervised actor at `path` so far.
    pub fn restarts(&self, path: &str) -> u64 {
        self.supervised(path)
            .unwrap_or_else(|| panic!("{path} not in the supervision tree"))["restarts"]
            .as_u64()
            .unwrap_or_else(|| panic!("{path}: no restart count"))
    }

    /// `GET path` → (status, content type, raw body): snapshots and other binary bodies.
    pub fn get_bytes(&self, path: &str) -> (u16, String, Vec<u8>) {
        let url = format!("{}{path}", self.base);
        let mut r = self.agent.get(&url).call().expect("GET");
        let status = r.status().as_u16();
        let ctype = r
            .headers()
            .get("content-type")
            .and_then(|v| v.to_str().ok())
            .unwrap_or_default()
            .to_string();
        let body = r
            .body_mut()
            .with_config()
            .limit(64 * 1024 * 1024)
            .read_to_vec()
            .expect("read the body");
        (status, ctype, body)
    }
}

/// Building the payload plugin cdylibs for end-to-end tests, the way
/// `core/plugin-host/tests/plugins/support.rs` does: a real `cargo build` with the test's
/// own cargo, target directory and profile, honouring `SKEIN_PLUGIN_TEST_SELECTION`
/// (`workspace` when the run is `cargo test --workspace`, so no dependency is compiled
/// twice with other features), then copies of the libraries.
pub mod plugins {
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
}

/// Ground-truth horizontal+vertical distances between every pair of simulated vehicles,
/// from their geodetic positions (flat earth over a few hundred metres).
pub fn truth_min_separation(stats_addr: &str) -> f64 {
    let s = sim_stats(stats_addr, "stats");
    let pos: Vec<(f64, f64, f64)> = s["vehicles"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|v| v["killed"] != true && v["truth"]["landed_state"] != "OnGround")
        .map(|v| {
            let p = &v["truth"]["position"];
            (
                p["lat_deg"].as_f64().unwrap(),
                p["lon_deg"].as_f64().unwrap(),
                p["alt_amsl_m"].as_f64().unwrap(),
            )
        })
        .collect();
    let mut best = f64::INFINITY;
    for (i, a) in pos.iter().enumerate() {
        for b in &pos[i + 1..] {
            let n = (b.0 - a.0).to_radians() * 6_371_000.0;
            let e = (b.1 - a.1).to_radians() * 6_371_000.0 * a.0.to_radians().cos();
            let d = (n * n + e * e + (b.2 - a.2).powi(2)).sqrt();
            best = best.min(d);
        }
    }
    best
}
