//! The child side of process isolation: `skein plugin-host --socket <path> --library
//! <path>` maps one plugin library, validates it like the parent does, hosts one instance
//! and speaks [`crate::protocol`] with the parent. Host services become messages to the
//! parent.

use crate::library::LoadedLibrary;
use crate::services::{Services, host_api};
use crate::wire::{read_frame, service, tag, take_f64, write_frame};
use skein_plugin_sdk::abi::{HostApi, PluginVTable, RawBytes, RawSink, status};
use std::ffi::{OsString, c_void};
use std::os::unix::net::UnixStream;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::{Mutex, OnceLock};
use std::time::Duration;

/// Arguments of `skein plugin-host`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PluginHostArgs {
    /// The parent's Unix socket to connect to.
    pub socket: PathBuf,
    /// The plugin library to map (the parent's private copy).
    pub library: PathBuf,
}

impl PluginHostArgs {
    /// Parses `--socket <path> --library <path>` (in any order; `--x=value` accepted).
    ///
    /// # Errors
    /// A missing or unknown argument, named.
    pub fn parse<I, S>(args: I) -> Result<PluginHostArgs, String>
    where
        I: IntoIterator<Item = S>,
        S: Into<OsString>,
    {
        let (mut socket, mut library) = (None, None);
        let mut it = args.into_iter().map(Into::into);
        while let Some(arg) = it.next() {
            let text = arg.to_string_lossy().into_owned();
            let (key, inline) = match text.split_once('=') {
                Some((k, v)) if k.starts_with("--") => (k.to_string(), Some(OsString::from(v))),
                _ => (text.clone(), None),
            };
            let slot = match key.as_str() {
                "--socket" => &mut socket,
                "--library" => &mut library,
                _ => {
                    return Err(format!(
                        "plugin-host: unknown argument `{text}` (expected --socket PATH --library PATH)"
                    ));
                }
            };
            let value = match inline {
                Some(v) => v,
                None => it
                    .next()
                    .ok_or_else(|| format!("plugin-host: `{key}` needs a value"))?,
            };
            *slot = Some(PathBuf::from(value));
        }
        Ok(PluginHostArgs {
            socket: socket.ok_or("plugin-host: missing --socket PATH")?,
            library: library.ok_or("plugin-host: missing --library PATH")?,
        })
    }
}

/// Host services of the child: calls go to the parent over the socket.
struct ChildServices {
    stream: Mutex<UnixStream>,
    vehicle_id: OnceLock<String>,
}

impl ChildServices {
    fn call(&self, svc: u8, args: &[&[u8]]) -> Result<Vec<u8>, String> {
        let mut s = self
            .stream
            .lock()
            .map_err(|_| "socket lock poisoned".to_string())?;
        let mut parts: Vec<&[u8]> = vec![std::slice::from_ref(&svc)];
        parts.extend_from_slice(args);
        write_frame(&mut *s, tag::HOST_CALL, &parts)
            .map_err(|e| format!("the parent is gone: {e}"))?;
        let (t, body) = read_frame(&mut *s).map_err(|e| format!("the parent is gone: {e}"))?;
        if t != tag::HOST_REPLY {
            return Err(format!("the parent answered a host call with tag {t:#x}"));
        }
        match body.split_first() {
            Some((&st, rest)) if u32::from(st) == status::OK => Ok(rest.to_vec()),
            Some((_, rest)) => Err(String::from_utf8_lossy(rest).into_owned()),
            None => Err("empty host reply".into()),
        }
    }

    fn notify(&self, svc: u8, args: &[&[u8]]) -> Result<(), String> {
        let mut s = self
            .stream
            .lock()
            .map_err(|_| "socket lock poisoned".to_string())?;
        let mut parts: Vec<&[u8]> = vec![std::slice::from_ref(&svc)];
        parts.extend_from_slice(args);
        write_frame(&mut *s, tag::HOST_NOTIFY, &parts)
            .map_err(|e| format!("the parent is gone: {e}"))
    }

    fn send(&self, t: u8, parts: &[&[u8]]) -> std::io::Result<()> {
        let mut s = self
            .stream
            .lock()
            .map_err(|_| std::io::Error::other("socket lock poisoned"))?;
        write_frame(&mut *s, t, parts)
    }
}

impl Services for ChildServices {
    fn vehicle_id(&self) -> Result<Vec<u8>, String> {
        Ok(self
            .vehicle_id
            .get()
            .cloned()
            .unwrap_or_default()
            .into_bytes())
    }
    fn vehicle(&self) -> Result<Vec<u8>, String> {
        self.call(service::VEHICLE, &[])
    }
    fn swarm(&self) -> Result<Vec<u8>, String> {
        self.call(service::SWARM, &[])
    }
    fn simulated(&self) -> bool {
        self.call(service::SIMULATED, &[])
            .is_ok_and(|b| b.first() == Some(&1))
    }
    fn send_mavlink(&self, frame: &[u8]) -> Result<(), String> {
        self.call(service::SEND_MAVLINK, &[frame]).map(|_| ())
    }
    fn emit_event(&self, kind: &[u8], data_json: &[u8]) -> Result<(), String> {
        let n = (kind.len() as u32).to_le_bytes();
        self.notify(service::EMIT_EVENT, &[&n, kind, data_json])
    }
    fn publish_state(&self, state_json: &[u8]) -> Result<(), String> {
        self.notify(service::PUBLISH_STATE, &[state_json])
    }
    fn payload_state(&self, slot: &[u8]) -> Result<Vec<u8>, String> {
        self.call(service::PAYLOAD_STATE, &[slot])
    }
    fn publish_frame(&self, jpeg: &[u8]) -> Result<(), String> {
        self.notify(service::PUBLISH_FRAME, &[jpeg])
    }
    fn set_simulated_link(&self, loss_fraction: f64, latency_ms: f64) -> bool {
        self.call(
            service::SET_SIMULATED_LINK,
            &[&loss_fraction.to_le_bytes(), &latency_ms.to_le_bytes()],
        )
        .is_ok_and(|b| b.first() == Some(&1))
    }
    fn log(&self, level: u32, message: &[u8]) {
        let _ = self.notify(service::LOG, &[&level.to_le_bytes(), message]);
    }
    fn sim_aircraft(&self) -> Result<Vec<u8>, String> {
        self.call(service::SIM_AIRCRAFT, &[])
    }
    fn payload_frame(&self, slot: &[u8]) -> Result<Vec<u8>, String> {
        self.call(service::PAYLOAD_FRAME, &[slot])
    }
}

/// Exits when the parent process goes away (the child is re-parented), so a child stuck
/// in a hung plugin call does not outlive skein.
fn watch_parent() {
    let parent = std::os::unix::process::parent_id();
    std::thread::spawn(move || {
        loop {
            std::thread::sleep(Duration::from_millis(200));
            if std::os::unix::process::parent_id() != parent {
                std::process::exit(0);
            }
        }
    });
}

/// The hosted instance.
struct Hosted<'a> {
    vt: &'a PluginVTable,
    api: &'a HostApi,
    name: &'a str,
    instance: *mut c_void,
}

impl Hosted<'_> {
    /// Runs one vtable call; `Ok(bytes)` or `Err((status, message))`.
    fn run(
        &mut self,
        op: &str,
        f: impl FnOnce(&PluginVTable, *mut c_void, RawSink) -> u32,
    ) -> Result<Vec<u8>, (u32, Vec<u8>)> {
        if self.instance.is_null() {
            return Err((
                status::ERROR,
                format!("`{op}` before `create`").into_bytes(),
            ));
        }
        let mut out = Vec::new();
        let st = f(self.vt, self.instance, RawSink::for_vec(&mut out));
        if st == status::OK {
            Ok(out)
        } else {
            Err((st, out))
        }
    }

    fn tick_rate(&mut self) -> f64 {
        if self.instance.is_null() {
            return 0.0;
        }
        let mut hz = 0.0;
        let mut err = Vec::new();
        // SAFETY: live instance created by this vtable, used by this thread only; `hz` and
        // `err` valid for the call.
        let st =
            unsafe { (self.vt.tick_rate_hz)(self.instance, &mut hz, RawSink::for_vec(&mut err)) };
        if st == status::OK { hz } else { 0.0 }
    }

    fn create(&mut self, body: &[u8], services: &ChildServices) -> Result<Vec<u8>, (u32, Vec<u8>)> {
        let req: serde_json::Value = serde_json::from_slice(body).map_err(|e| {
            (
                status::ERROR,
                format!("bad create request: {e}").into_bytes(),
            )
        })?;
        if !self.instance.is_null() {
            return Err((status::ERROR, b"the instance exists already".to_vec()));
        }
        let _ = services
            .vehicle_id
            .set(req["vehicle_id"].as_str().unwrap_or_default().to_string());
        let kind = req["kind"].as_str().unwrap_or_default().to_string();
        let config = serde_json::to_vec(&req["config"]).unwrap_or_default();
        let mut out = Vec::new();
        let mut instance = std::ptr::null_mut();
        // SAFETY: the vtable was validated; `kind`, `config` outlive the call; `api` lives
        // (boxed in `plugin_host_main`) until after the instance is destroyed.
        let st = unsafe {
            (self.vt.create)(
                RawBytes::from_slice(kind.as_bytes()),
                RawBytes::from_slice(&config),
                self.api,
                &mut instance,
                RawSink::for_vec(&mut out),
            )
        };
        if st != status::OK {
            return Err((st, out));
        }
        self.instance = instance;
        Ok(out)
    }

    fn destroy(&mut self) {
        if self.instance.is_null() {
            return;
        }
        let mut err = Vec::new();
        // SAFETY: live instance, destroyed exactly once (nulled right after).
        let st = unsafe { (self.vt.destroy)(self.instance, RawSink::for_vec(&mut err)) };
        self.instance = std::ptr::null_mut();
        if st != status::OK {
            eprintln!(
                "skein plugin-host: destroying `{}`: {}",
                self.name,
                String::from_utf8_lossy(&err)
            );
        }
    }
}

/// Runs the `skein plugin-host` child until the parent sends `DESTROY` or goes away.
/// Exit codes: 0 done, 2 bad arguments (see [`PluginHostArgs::parse`]), 3 cannot reach
/// the parent, 4 the library was refused, 5 protocol error.
pub fn plugin_host_main(args: PluginHostArgs) -> ExitCode {
    let stream = match UnixStream::connect(&args.socket) {
        Ok(s) => s,
        Err(e) => {
            eprintln!(
                "skein plugin-host: cannot connect to {}: {e}",
                args.socket.display()
            );
            return ExitCode::from(3);
        }
    };
    let mut reader = match stream.try_clone() {
        Ok(r) => r,
        Err(e) => {
            eprintln!("skein plugin-host: {e}");
            return ExitCode::from(3);
        }
    };
    watch_parent();
    let services = Box::new(ChildServices {
        stream: Mutex::new(stream),
        vehicle_id: OnceLock::new(),
    });
    let lib = match LoadedLibrary::open_in_place(&args.library) {
        Ok(l) => l,
        Err(e) => {
            let hello = serde_json::json!({"ok": false, "error": e.to_string()});
            let _ = services.send(tag::HELLO, &[hello.to_string().as_bytes()]);
            eprintln!("skein plugin-host: {e}");
            return ExitCode::from(4);
        }
    };
    let hello = serde_json::json!({
        "ok": true, "pid": std::process::id(), "name": lib.name, "version": lib.version,
    });
    if services
        .send(tag::HELLO, &[hello.to_string().as_bytes()])
        .is_err()
    {
        return ExitCode::from(3);
    }
    let api = Box::new(host_api(services.as_ref()));
    let mut hosted = Hosted {
        vt: lib.vtable(),
        api: api.as_ref(),
        name: &lib.name,
        instance: std::ptr::null_mut(),
    };
    let code = loop {
        let (t, body) = match read_frame(&mut reader) {
            Ok(f) => f,
            // The parent went away: nothing left to serve.
            Err(_) => break ExitCode::SUCCESS,
        };
        let result = match t {
            tag::CREATE => hosted.create(&body, &services),
            tag::TICK => match take_f64(&body) {
                // SAFETY: live instance, this thread only; the sink is valid for the call.
                Ok((dt, _)) => hosted.run("tick", |vt, i, out| unsafe { (vt.tick)(i, dt, out) }),
                Err(e) => Err((status::ERROR, e.to_string().into_bytes())),
            },
            // SAFETY: live instance, this thread only; `body` outlives the call.
            tag::HANDLE => hosted.run("handle", |vt, i, out| unsafe {
                (vt.handle)(i, RawBytes::from_slice(&body), out)
            }),
            tag::MAVLINK => match body.split_first() {
                // SAFETY: live instance, this thread only; `frame` outlives the call.
                Some((&compid, frame)) => hosted.run("on_mavlink", |vt, i, out| unsafe {
                    (vt.on_mavlink)(i, compid, RawBytes::from_slice(frame), out)
                }),
                None => Err((status::ERROR, b"empty MAVLINK request".to_vec())),
            },
            tag::DESTROY => {
                hosted.destroy();
                let _ = services.send(tag::DONE_OK, &[&0f64.to_le_bytes()]);
                break ExitCode::SUCCESS;
            }
            other => {
                eprintln!("skein plugin-host: unexpected tag {other:#x}");
                break ExitCode::from(5);
            }
        };
        let hz = hosted.tick_rate();
        let sent = match result {
            Ok(bytes) => services.send(tag::DONE_OK, &[&hz.to_le_bytes(), &bytes]),
            Err((st, msg)) => {
                let st = if st == status::PANIC { 2u8 } else { 1u8 };
                services.send(tag::DONE_ERR, &[&hz.to_le_bytes(), &[st], &msg])
            }
        };
        if sent.is_err() {
            break ExitCode::SUCCESS;
        }
    };
    hosted.destroy();
    // Keep the table alive until the instance is gone.
    drop(api);
    code
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arguments_parse_in_any_order_and_errors_name_the_argument() {
        let a = PluginHostArgs::parse(["--library", "/p/lib.so", "--socket=/s.sock"]).unwrap();
        assert_eq!(
            a,
            PluginHostArgs {
                socket: "/s.sock".into(),
                library: "/p/lib.so".into()
            }
        );
        assert_eq!(
            PluginHostArgs::parse(["--socket", "/s"]).unwrap_err(),
            "plugin-host: missing --library PATH"
        );
        assert_eq!(
            PluginHostArgs::parse(["--socket"]).unwrap_err(),
            "plugin-host: `--socket` needs a value"
        );
        assert!(
            PluginHostArgs::parse(["--sock", "x"])
                .unwrap_err()
                .contains("unknown argument `--sock`")
        );
    }
}
