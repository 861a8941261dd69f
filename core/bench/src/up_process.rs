//! A `skein up` child process of a benchmark: the `skein` executable
//! ([`crate::skein_exe`]), its API on a free port, killed when dropped.

use serde_json::Value;
use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A running `skein up` (see the module docs).
pub struct UpProcess {
    child: Child,
    /// `http://127.0.0.1:PORT`.
    pub base: String,
    agent: ureq::Agent,
}

impl Drop for UpProcess {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl UpProcess {
    /// `skein up --http 127.0.0.1:0 <args>`; returns once it serves its API.
    ///
    /// # Errors
    /// The executable cannot be started, or it ends before printing its dashboard line.
    pub fn start(args: &[&str]) -> Result<UpProcess, String> {
        Self::start_role(&["up", "--http", "127.0.0.1:0"], args)
    }

    /// `skein <role…> <args>` (`["agent"]`, `["coordinator", "--http", "127.0.0.1:0"]`);
    /// returns once it serves its API.
    ///
    /// # Errors
    /// As [`UpProcess::start`].
    pub fn start_role(role: &[&str], args: &[&str]) -> Result<UpProcess, String> {
        let exe = crate::skein_exe()?;
        let mut child = Command::new(exe)
            .args(role)
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .map_err(|e| format!("cannot start skein up: {e}"))?;
        let stdout = child.stdout.take().ok_or("no stdout")?;
        let mut lines = BufReader::new(stdout).lines();
        let base = loop {
            match lines.next() {
                Some(Ok(l)) if l.contains("dashboard at") => {
                    break l
                        .split_whitespace()
                        .find(|w| w.starts_with("http://"))
                        .ok_or("no URL in the dashboard line")?
                        .trim_end_matches('/')
                        .to_string();
                }
                Some(Ok(_)) => {}
                _ => return Err(format!("skein {} ended before serving its API", role[0])),
            }
        };
        // Keep draining stdout so the child never blocks on a full pipe.
        std::thread::spawn(move || for _ in lines {});
        let agent: ureq::Agent = ureq::Agent::config_builder()
            .http_status_as_error(false)
            .timeout_global(Some(Duration::from_secs(10)))
            .build()
            .into();
        Ok(UpProcess { child, base, agent })
    }

    /// The process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// `METHOD path` (`GET`, or `POST` / `PUT` with a JSON body) as JSON.
    ///
    /// # Errors
    /// A bad method, a failed request, or a status of 300 or more.
    pub fn call(&self, method: &str, path: &str, body: Option<Value>) -> Result<Value, String> {
        let url = format!("{}{path}", self.base);
        let r = match (method, body) {
            ("GET", _) => self.agent.get(&url).call(),
            ("POST", Some(b)) => self.agent.post(&url).send_json(b),
            ("PUT", Some(b)) => self.agent.put(&url).send_json(b),
            _ => return Err(format!("bad call {method} {path}")),
        };
        let mut r = r.map_err(|e| format!("{method} {path}: {e}"))?;
        let status = r.status().as_u16();
        let v: Value = r.body_mut().read_json().unwrap_or(Value::Null);
        if status >= 300 {
            return Err(format!("{method} {path}: {status} {v}"));
        }
        Ok(v)
    }

    /// `GET path` as JSON.
    ///
    /// # Errors
    /// As [`UpProcess::call`].
    pub fn get(&self, path: &str) -> Result<Value, String> {
        self.call("GET", path, None)
    }

    /// Waits until `n` vehicles are listed and every one satisfies `ok`.
    ///
    /// # Errors
    /// `limit` passed first (naming `what`), or the API failed.
    pub fn wait_vehicles(
        &self,
        n: usize,
        what: &str,
        limit: Duration,
        ok: impl Fn(&Value) -> bool,
    ) -> Result<(), String> {
        let deadline = Instant::now() + limit;
        loop {
            let vs = self.get("/api/v1/vehicles")?;
            if vs
                .as_array()
                .is_some_and(|a| a.len() == n && a.iter().all(&ok))
            {
                return Ok(());
            }
            if Instant::now() > deadline {
                return Err(format!("timed out waiting for {what}"));
            }
            std::thread::sleep(Duration::from_millis(200));
        }
    }
}
