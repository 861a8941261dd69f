//! A running `skein up` driven over its HTTP API only: requests, waits on vehicle
//! states, the usual flights. The API half ([`Api`]) also drives a skein this test did not
//! start itself (one in a container).

use super::{Process, eventually};
use serde_json::{Value, json};
use std::time::Duration;

/// A running `skein up` with its dashboard URL; its API's methods through [`Api`].
pub struct Skein {
    /// The process.
    pub process: Process,
    api: Api,
}

impl std::ops::Deref for Skein {
    type Target = Api;

    fn deref(&self) -> &Api {
        &self.api
    }
}

/// A skein's HTTP API at `base`.
pub struct Api {
    /// `http://127.0.0.1:PORT`
    pub base: String,
    agent: ureq::Agent,
}

impl Api {
    /// The API at `base` (`http://HOST:PORT`, no trailing slash).
    pub fn new(base: &str) -> Api {
        let agent: ureq::Agent = ureq::Agent::config_builder()
            .http_status_as_error(false)
            .timeout_global(Some(Duration::from_secs(20)))
            .build()
            .into();
        Api {
            base: base.trim_end_matches('/').to_string(),
            agent,
        }
    }
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
        Skein::attach(Process::start_in(netns, &all))
    }

    /// `<prefix…> skein <subcommand> <args>` with `env` (see [`Process::start_with`]; `args`
    /// give `--http`), and waits for the dashboard line.
    pub fn launch_with(
        prefix: &[&str],
        env: &[(&str, &str)],
        subcommand: &str,
        args: &[&str],
    ) -> Skein {
        let mut all = vec![subcommand];
        all.extend_from_slice(args);
        Skein::attach(Process::start_with(prefix, env, &all))
    }

    /// `command` (a skein binary other than this run's, e.g. under an emulator, and its
    /// arguments with `--http`), and waits for the dashboard line.
    pub fn launch_command(command: &[&str]) -> Skein {
        Skein::attach(Process::start_command(command, &[]))
    }

    /// Waits for the dashboard line of a started `process`.
    fn attach(mut process: Process) -> Skein {
        let line = process.wait_line("dashboard at", Duration::from_secs(60));
        let url = line
            .split_whitespace()
            .find(|w| w.starts_with("http://"))
            .expect("url in the dashboard line");
        Skein {
            process,
            api: Api::new(url),
        }
    }

    /// `skein up --sim n` on free ports.
    pub fn sim(n: usize) -> Skein {
        let n = n.to_string();
        Skein::up(&["--sim", &n, "--sim-base-port", "0"])
    }
}

impl Api {
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

    /// `GET path` → (status, JSON), or `None` when nothing answers (a process that is
    /// starting or has ended).
    pub fn try_get(&self, path: &str) -> Option<(u16, Value)> {
        self.agent
            .get(format!("{}{path}", self.base))
            .call()
            .ok()
            .map(Self::read)
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

impl Api {
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
}

impl Skein {
    /// Kills the process with SIGKILL (no goodbye: no last lease, no clean shutdown) and
    /// waits for it to exit.
    pub fn kill_hard(&mut self) {
        self.process.signal("KILL");
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
}

impl Api {
    /// Records on demand as `name` (`POST /api/v1/recording/start`, 201) until the
    /// recording reports `elapsed_s` of at least `seconds` (within `within`), then stops
    /// it (`POST /api/v1/recording/stop`, 200); returns the stop's body (`path`, ...).
    pub fn record_for(&self, name: &str, seconds: f64, within: Duration) -> Value {
        let (status, body) = self.post("/api/v1/recording/start", json!({"name": name}));
        assert_eq!(status, 201, "{body}");
        eventually(&format!("{seconds} s recorded"), within, || {
            let r = self.get("/api/v1/recording").1;
            match r["recording"]["elapsed_s"].as_f64() {
                Some(t) if t >= seconds => Ok(()),
                _ => Err(r.to_string()),
            }
        });
        let (status, body) = self.post("/api/v1/recording/stop", json!({}));
        assert_eq!(status, 200, "{body}");
        body
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

    /// The value of `skein_dds_samples{what="<what>"}` in `/metrics` (panics naming it
    /// when it is not there).
    pub fn dds_samples(&self, what: &str) -> u64 {
        self.metric(&format!("skein_dds_samples{{what=\"{what}\"}}"))
    }

    /// The value of the integer series `series` (a name with its labels, as `/metrics`
    /// writes it: `skein_dds_security_refusals{reason="identity"}`) in `/metrics` (panics
    /// naming it when it is not there).
    pub fn metric(&self, series: &str) -> u64 {
        let (_, _, body) = self.get_bytes("/metrics");
        let text = String::from_utf8_lossy(&body).to_string();
        let needle = format!("{series} ");
        text.lines()
            .find_map(|l| l.strip_prefix(&needle))
            .and_then(|v| v.trim().parse().ok())
            .unwrap_or_else(|| panic!("no {needle} in /metrics:\n{text}"))
    }

    /// [`crate::support::assert_no_failsafe_and_no_gap`] on the simulator's stats socket
    /// `stats_addr`, a failure showing skein's side too: the largest pause of each stream
    /// as skein sent it (`skein_setpoint_max_gap_ms`), the setpoint thread's scheduling
    /// and the load (`GET /api/v1/health`), so that a gap on the wire tells whether skein's
    /// setpoint thread was late.
    pub fn assert_no_failsafe_and_no_gap(&self, stats_addr: &str) -> f64 {
        let (_, _, body) = self.get_bytes("/metrics");
        let sent: Vec<String> = String::from_utf8_lossy(&body)
            .lines()
            .filter(|l| l.starts_with("skein_setpoint_max_gap_ms{"))
            .map(str::to_string)
            .collect();
        let (_, health) = self.get("/api/v1/health");
        crate::support::assert_no_failsafe_and_no_gap_in(
            stats_addr,
            &format!("as sent: {sent:?}; load: {}", health["load"]),
        )
    }

    /// `GET path` → (status, content type, the body as it arrives): streamed bodies
    /// (MJPEG), read within the agent's 20 s.
    pub fn get_stream(&self, path: &str) -> (u16, String, impl std::io::Read + use<>) {
        let url = format!("{}{path}", self.base);
        let r = self.agent.get(&url).call().expect("GET");
        let status = r.status().as_u16();
        let ctype = r
            .headers()
            .get("content-type")
            .and_then(|v| v.to_str().ok())
            .unwrap_or_default()
            .to_string();
        (status, ctype, r.into_body().into_reader())
    }

    /// `GET path` → (status, content type, raw body): snapshots and other binary bodies
    /// (at most 64 MiB).
    pub fn get_bytes(&self, path: &str) -> (u16, String, Vec<u8>) {
        use std::io::Read;
        let (status, ctype, body) = self.get_stream(path);
        let mut bytes = Vec::new();
        body.take(64 * 1024 * 1024)
            .read_to_end(&mut bytes)
            .expect("read the body");
        (status, ctype, bytes)
    }
}
