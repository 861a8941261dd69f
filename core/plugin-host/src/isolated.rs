//! The parent side of process isolation: a [`PayloadDriver`] that forwards every call to a
//! `skein plugin-host` child over a Unix socket (see [`crate::protocol`]) and serves the
//! child's host-service calls from the vehicle's `PayloadHost`.
//!
//! An abort or segfault in the plugin kills only the child. The driver notices on its next
//! read (the socket closes), reaps the child, and from then on fails every call with the
//! child's fate, so the payload's supervisor re-creates the driver, which spawns a new
//! child. A call that misses its deadline kills the child the same way.

use crate::inprocess::parse_instance_info;
use crate::registry::{InstanceGuard, StalePolicy};
use crate::services::{HostServices, Services};
use crate::wire::{read_frame, service, tag, take_f64, take_u32, write_frame};
use skein_mavlink::{Encoder, MavMessage, message_id};
use skein_payload::PayloadDriver;
use skein_plugin_sdk::MavlinkInterest;
use skein_plugin_sdk::abi::status;
use std::ffi::OsString;
use std::io;
use std::os::unix::net::{UnixListener, UnixStream};
use std::os::unix::process::ExitStatusExt;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// The command that starts a `skein plugin-host` child: `program` with `args`, to which the
/// host appends `--socket <path> --library <path>`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChildCommand {
    /// The executable.
    pub program: PathBuf,
    /// Arguments before `--socket` (for the `skein` binary: `["plugin-host"]`).
    pub args: Vec<OsString>,
}

impl ChildCommand {
    /// The running executable's `plugin-host` subcommand (`std::env::current_exe()`), what
    /// the `skein` binary uses.
    ///
    /// # Errors
    /// When the running executable cannot be determined.
    pub fn skein_subcommand() -> io::Result<ChildCommand> {
        Ok(ChildCommand {
            program: std::env::current_exe()?,
            args: vec![OsString::from("plugin-host")],
        })
    }

    /// A standalone plugin-host executable taking `--socket` and `--library` directly
    /// (such as this crate's `skein-plugin-host` binary).
    pub fn standalone(program: impl Into<PathBuf>) -> ChildCommand {
        ChildCommand {
            program: program.into(),
            args: Vec::new(),
        }
    }
}

/// How isolated instances are started and timed.
#[derive(Debug, Clone)]
pub(crate) struct IsolationSettings {
    pub child: ChildCommand,
    pub call_timeout: Duration,
    pub spawn_timeout: Duration,
    pub socket_dir: PathBuf,
}

static SOCKET_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Name of a signal, for messages.
fn signal_name(sig: i32) -> &'static str {
    match sig {
        4 => "SIGILL",
        6 => "SIGABRT",
        7 => "SIGBUS",
        8 => "SIGFPE",
        9 => "SIGKILL",
        11 => "SIGSEGV",
        15 => "SIGTERM",
        _ => "a signal",
    }
}

/// Describes how a child ended.
pub(crate) fn describe_exit(status: ExitStatus) -> String {
    match (status.code(), status.signal()) {
        (_, Some(sig)) => format!("killed by signal {sig} ({})", signal_name(sig)),
        (Some(code), None) => format!("exited with code {code}"),
        (None, None) => format!("ended ({status})"),
    }
}

/// Waits for `child` to end, at most `limit`, then kills it. Returns its exit status when
/// known.
fn reap(child: &mut Child, limit: Duration) -> Option<ExitStatus> {
    let deadline = Instant::now() + limit;
    loop {
        match child.try_wait() {
            Ok(Some(st)) => return Some(st),
            Ok(None) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(1)),
            Ok(None) => {
                let _ = child.kill();
                return child.wait().ok();
            }
            Err(_) => return None,
        }
    }
}

/// Removes `path`, then returns `r`.
fn remove_then<T>(path: &Path, r: T) -> T {
    let _ = std::fs::remove_file(path);
    r
}

/// A process-isolated plugin instance.
pub(crate) struct IsolatedDriver {
    child: Child,
    pid: u32,
    stream: UnixStream,
    services: HostServices,
    interest: MavlinkInterest,
    tick_rate_hz: f64,
    call_timeout: Duration,
    policy: StalePolicy,
    /// Why the child is gone, once it is.
    dead: Option<String>,
    guard: InstanceGuard,
}

/// Accepts the child's connection, watching that it has not died meanwhile.
fn accept(
    listener: &UnixListener,
    child: &mut Child,
    deadline: Instant,
    program: &Path,
) -> Result<UnixStream, String> {
    loop {
        match listener.accept() {
            Ok((stream, _)) => return Ok(stream),
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                if let Ok(Some(st)) = child.try_wait() {
                    return Err(format!(
                        "the plugin host process {} before connecting (is `{}` a skein binary with the plugin-host subcommand?)",
                        describe_exit(st),
                        program.display()
                    ));
                }
                if Instant::now() >= deadline {
                    let _ = child.kill();
                    let _ = child.wait();
                    return Err("the plugin host process did not connect in time; killed".into());
                }
                std::thread::sleep(Duration::from_millis(1));
            }
            Err(e) => {
                return Err(format!(
                    "accepting the plugin host's connection failed: {e}"
                ));
            }
        }
    }
}

impl IsolatedDriver {
    /// Spawns a child for the guard's library and creates the instance in it.
    ///
    /// # Errors
    /// The child cannot be started or does not connect, fails to load the library, or the
    /// plugin refuses the instance.
    pub fn spawn(
        guard: InstanceGuard,
        kind: &str,
        slot: &str,
        config: &serde_json::Value,
        services: HostServices,
        policy: StalePolicy,
        settings: &IsolationSettings,
    ) -> Result<IsolatedDriver, String> {
        let name = guard.entry.name().to_string();
        let socket = settings.socket_dir.join(format!(
            "ph-{}-{}.sock",
            std::process::id(),
            SOCKET_COUNTER.fetch_add(1, Ordering::Relaxed)
        ));
        let _ = std::fs::remove_file(&socket);
        let listener = UnixListener::bind(&socket)
            .map_err(|e| format!("plugin `{name}`: cannot bind {}: {e}", socket.display()))?;
        // The socket file is needed only until the child connects.
        let cleanup = |r| remove_then(&socket, r);
        if let Err(e) = listener.set_nonblocking(true) {
            return cleanup(Err(format!("plugin `{name}`: {e}")));
        }
        let mut child = match Command::new(&settings.child.program)
            .args(&settings.child.args)
            .arg("--socket")
            .arg(&socket)
            .arg("--library")
            .arg(&guard.entry.lib.shadow)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::inherit())
            .spawn()
        {
            Ok(c) => c,
            Err(e) => {
                return cleanup(Err(format!(
                    "plugin `{name}`: cannot start the plugin host `{}`: {e}",
                    settings.child.program.display()
                )));
            }
        };
        let deadline = Instant::now() + settings.spawn_timeout;
        let stream = remove_then(
            &socket,
            accept(&listener, &mut child, deadline, &settings.child.program),
        )
        .map_err(|e| format!("plugin `{name}`: {e}"))?;
        let pid = child.id();
        let mut driver = IsolatedDriver {
            child,
            pid,
            stream,
            services,
            interest: MavlinkInterest::None,
            tick_rate_hz: 0.0,
            call_timeout: settings.call_timeout,
            policy,
            dead: None,
            guard,
        };
        driver.guard.set_pid(Some(pid));
        driver
            .stream
            .set_nonblocking(false)
            .map_err(|e| format!("plugin `{name}`: {e}"))?;
        driver.hello(deadline)?;
        let create = serde_json::json!({
            "kind": kind,
            "config": config,
            "vehicle_id": driver.services.host_vehicle_id(),
            "slot": slot,
        });
        let create = serde_json::to_vec(&create).map_err(|e| e.to_string())?;
        let info = driver.request(
            "create",
            tag::CREATE,
            &[&create],
            deadline.saturating_duration_since(Instant::now()),
        )?;
        driver.interest = parse_instance_info(&info)?;
        Ok(driver)
    }

    fn name(&self) -> String {
        self.guard.entry.name().to_string()
    }

    /// Reads the child's greeting and checks it loaded the same plugin.
    fn hello(&mut self, deadline: Instant) -> Result<(), String> {
        let name = self.name();
        let remaining = deadline
            .saturating_duration_since(Instant::now())
            .max(Duration::from_millis(1));
        let _ = self.stream.set_read_timeout(Some(remaining));
        let (t, body) = match read_frame(&mut self.stream) {
            Ok(f) => f,
            Err(e) => return Err(self.died("start", e)),
        };
        let hello: serde_json::Value = if t == tag::HELLO {
            serde_json::from_slice(&body).unwrap_or_default()
        } else {
            serde_json::Value::Null
        };
        if hello["ok"] != true {
            let why = hello["error"]
                .as_str()
                .unwrap_or("it sent no greeting")
                .to_string();
            self.kill(format!("the plugin host refused to start: {why}"));
            return Err(format!("plugin `{name}` (process-isolated): {why}"));
        }
        let (n, v) = (hello["name"].as_str(), hello["version"].as_str());
        if n != Some(name.as_str()) || v != Some(self.guard.entry.lib.version.as_str()) {
            let why = format!(
                "the plugin host loaded {n:?} {v:?}, expected `{name}` {}",
                self.guard.entry.lib.version
            );
            self.kill(why.clone());
            return Err(format!("plugin `{name}` (process-isolated): {why}"));
        }
        Ok(())
    }

    /// Kills and reaps the child, recording why.
    fn kill(&mut self, why: String) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        self.guard.set_pid(None);
        self.dead = Some(why);
    }

    /// The child's socket failed: reap it and describe its end.
    fn died(&mut self, op: &str, e: io::Error) -> String {
        let fate = match reap(&mut self.child, Duration::from_secs(2)) {
            Some(st) => describe_exit(st),
            None => format!("connection lost ({e})"),
        };
        self.guard.set_pid(None);
        let why = format!("process {} {fate} during `{op}`", self.pid);
        self.dead = Some(why.clone());
        format!("plugin `{}` (process-isolated): {why}", self.name())
    }

    fn timed_out(&mut self, op: &str, timeout: Duration) -> String {
        let why = format!(
            "process {} did not answer `{op}` within {} ms and was killed",
            self.pid,
            timeout.as_millis()
        );
        self.kill(why.clone());
        format!("plugin `{}` (process-isolated): {why}", self.name())
    }

    /// Answers a host-service call: `(status, result)`.
    fn serve(&self, body: &[u8]) -> (u8, Vec<u8>) {
        let Some((&svc, args)) = body.split_first() else {
            return (status::ERROR as u8, b"empty host call".to_vec());
        };
        let s = &self.services;
        let result = catch_unwind(AssertUnwindSafe(|| -> Result<Vec<u8>, String> {
            match svc {
                service::VEHICLE => s.vehicle(),
                service::SWARM => s.swarm(),
                service::SIMULATED => Ok(vec![u8::from(s.simulated())]),
                service::SEND_MAVLINK => s.send_mavlink(args).map(|_| Vec::new()),
                service::PAYLOAD_STATE => s.payload_state(args),
                service::SIM_AIRCRAFT => s.sim_aircraft(),
                service::PAYLOAD_FRAME => s.payload_frame(args),
                service::SET_SIMULATED_LINK => {
                    let (loss, rest) = take_f64(args).map_err(|e| e.to_string())?;
                    let (latency, _) = take_f64(rest).map_err(|e| e.to_string())?;
                    Ok(vec![u8::from(s.set_simulated_link(loss, latency))])
                }
                other => Err(format!("unknown host service {other}")),
            }
        }));
        match result {
            Ok(Ok(b)) => (status::OK as u8, b),
            Ok(Err(e)) => (status::ERROR as u8, e.into_bytes()),
            Err(_) => (status::PANIC as u8, b"host service panicked".to_vec()),
        }
    }

    /// Applies a host-service notification.
    fn notify(&self, body: &[u8]) {
        let Some((&svc, args)) = body.split_first() else {
            return;
        };
        let s = &self.services;
        let result = catch_unwind(AssertUnwindSafe(|| -> Result<(), String> {
            match svc {
                service::EMIT_EVENT => {
                    let (n, rest) = take_u32(args).map_err(|e| e.to_string())?;
                    let n = (n as usize).min(rest.len());
                    s.emit_event(&rest[..n], &rest[n..])
                }
                service::PUBLISH_STATE => s.publish_state(args),
                service::PUBLISH_FRAME => s.publish_frame(args),
                service::LOG => {
                    let (level, msg) = take_u32(args).map_err(|e| e.to_string())?;
                    s.log(level, msg);
                    Ok(())
                }
                other => Err(format!("unknown host notification {other}")),
            }
        }));
        let err = match result {
            Ok(Ok(())) => return,
            Ok(Err(e)) => e,
            Err(_) => "host service panicked".into(),
        };
        tracing::warn!(plugin = %self.name(), "host service notification failed: {err}");
    }

    /// Sends one request and runs the exchange until its answer, within `timeout`.
    fn request(
        &mut self,
        op: &str,
        request_tag: u8,
        parts: &[&[u8]],
        timeout: Duration,
    ) -> Result<Vec<u8>, String> {
        if let Some(why) = &self.dead {
            return Err(format!(
                "plugin `{}` (process-isolated) is not running: {why}; re-create the payload",
                self.name()
            ));
        }
        let deadline = Instant::now() + timeout;
        if let Err(e) = write_frame(&mut self.stream, request_tag, parts) {
            return Err(self.died(op, e));
        }
        loop {
            let remaining = deadline.saturating_duration_since(Instant::now());
            if remaining.is_zero() {
                return Err(self.timed_out(op, timeout));
            }
            if let Err(e) = self.stream.set_read_timeout(Some(remaining)) {
                return Err(self.died(op, e));
            }
            let (t, body) = match read_frame(&mut self.stream) {
                Ok(f) => f,
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                    ) =>
                {
                    return Err(self.timed_out(op, timeout));
                }
                Err(e) => return Err(self.died(op, e)),
            };
            match t {
                tag::DONE_OK | tag::DONE_ERR => {
                    let Ok((hz, rest)) = take_f64(&body) else {
                        self.kill("it sent a malformed answer".into());
                        return Err(format!(
                            "plugin `{}`: malformed answer to `{op}`",
                            self.name()
                        ));
                    };
                    self.tick_rate_hz = if hz.is_finite() && hz > 0.0 { hz } else { 0.0 };
                    if t == tag::DONE_OK {
                        return Ok(rest.to_vec());
                    }
                    let (st, msg) = rest
                        .split_first()
                        .map(|(s, m)| (u32::from(*s), m))
                        .unwrap_or((status::ERROR, &[]));
                    let msg = String::from_utf8_lossy(msg).into_owned();
                    return Err(if st == status::PANIC {
                        format!("plugin `{}` panicked in `{op}`: {msg}", self.name())
                    } else {
                        msg
                    });
                }
                tag::HOST_CALL => {
                    let (st, reply) = self.serve(&body);
                    if let Err(e) = write_frame(&mut self.stream, tag::HOST_REPLY, &[&[st], &reply])
                    {
                        return Err(self.died(op, e));
                    }
                }
                tag::HOST_NOTIFY => self.notify(&body),
                other => {
                    self.kill(format!("it broke the protocol (tag {other:#x})"));
                    return Err(format!(
                        "plugin `{}` (process-isolated): protocol violation (tag {other:#x}) during `{op}`; child killed",
                        self.name()
                    ));
                }
            }
        }
    }

    /// Checks staleness, then runs a request with the call timeout.
    fn call(&mut self, op: &str, request_tag: u8, parts: &[&[u8]]) -> Result<Vec<u8>, String> {
        if let Some(e) = self.guard.stale_error(self.policy) {
            return Err(e);
        }
        self.request(op, request_tag, parts, self.call_timeout)
    }
}

impl PayloadDriver for IsolatedDriver {
    fn served_by(&self) -> Option<skein_payload::ServedBy> {
        Some(self.guard.served_by())
    }

    fn tick_rate_hz(&self) -> f64 {
        self.tick_rate_hz
    }

    fn tick(&mut self, dt_s: f64) -> Result<(), String> {
        self.call("tick", tag::TICK, &[&dt_s.to_le_bytes()])
            .map(|_| ())
    }

    fn handle(&mut self, command: serde_json::Value) -> Result<serde_json::Value, String> {
        let bytes = serde_json::to_vec(&command).map_err(|e| e.to_string())?;
        let reply = self.call("handle", tag::HANDLE, &[&bytes])?;
        serde_json::from_slice(&reply)
            .map_err(|e| format!("plugin `{}` replied with invalid JSON: {e}", self.name()))
    }

    fn on_mavlink(&mut self, compid: u8, msg: &MavMessage) -> Result<(), String> {
        if !self.interest.wants(message_id(msg)) {
            return Ok(());
        }
        let frame = Encoder::new(0, compid).encode(msg);
        self.call("on_mavlink", tag::MAVLINK, &[&[compid], frame.as_bytes()])
            .map(|_| ())
    }
}

impl Drop for IsolatedDriver {
    fn drop(&mut self) {
        if self.dead.is_none() {
            let limit = self.call_timeout.min(Duration::from_secs(2));
            if let Err(e) = self.request("destroy", tag::DESTROY, &[], limit) {
                tracing::warn!(plugin = %self.name(), "destroying the isolated instance: {e}");
            }
            if self.dead.is_none() {
                reap(&mut self.child, Duration::from_secs(1));
            }
        }
        self.guard.set_pid(None);
    }
}
