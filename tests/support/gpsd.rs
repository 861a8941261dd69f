//! A GNSS receiver nobody here wrote: Debian's gpsd, fed by its own gpsfake (package
//! `gpsd-clients`; tests/run.sh installs it) from an NMEA log the test writes, replayed
//! in a loop on a pseudo-terminal (one sentence every 0.5 s) and served on a free TCP
//! port. gpsfake runs its gpsd as a child (`gpsd -b -N -S PORT -F SOCKET`) that outlives
//! gpsfake when only gpsfake is killed, so both run in a process group of their own and
//! the group is killed (on drop, or by [`FakeGps::stop`]).
//!
//! Found on Debian 12 (gpsd 3.22): gpsfake runs as root without an option (gpsd, told
//! `-N`, stays in the foreground and drops no privilege it needs for the pty); it wants
//! a pty, and says so if it has none (then it falls back to UDP, which gpsd reads too).

use super::{eventually, free_tcp_port};
use std::net::TcpStream;
use std::os::unix::process::CommandExt;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// gpsfake and its gpsd, serving the log's fix.
pub struct FakeGps {
    /// gpsd's port on 127.0.0.1.
    pub port: u16,
    child: Option<Child>,
    _dir: tempfile::TempDir,
}

impl FakeGps {
    /// Writes `sentences` (whole NMEA sentences, checksums included) as a log and starts
    /// gpsfake on it; returns once its gpsd accepts connections.
    pub fn start(sentences: &[String]) -> FakeGps {
        let dir = tempfile::tempdir().unwrap();
        let log = dir.path().join("operator.nmea");
        let text: String = sentences.iter().map(|s| format!("{s}\r\n")).collect();
        std::fs::write(&log, text).unwrap();
        let port = free_tcp_port();
        let child = Command::new(gpsfake())
            .args(["-q", "-c", "0.5", "-P", &port.to_string()])
            .arg(&log)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .process_group(0)
            .spawn()
            .expect("start gpsfake");
        let gps = FakeGps {
            port,
            child: Some(child),
            _dir: dir,
        };
        eventually("gpsd listening", Duration::from_secs(20), || {
            TcpStream::connect(("127.0.0.1", port))
                .map(drop)
                .map_err(|e| e.to_string())
        });
        gps
    }

    /// Kills gpsfake and its gpsd: the receiver is gone.
    pub fn stop(&mut self) {
        let Some(mut child) = self.child.take() else {
            return;
        };
        // The group's id is gpsfake's pid (`process_group(0)`).
        let _ = Command::new("kill")
            .args(["-KILL", "--", &format!("-{}", child.id())])
            .status();
        let _ = child.wait();
    }
}

impl Drop for FakeGps {
    fn drop(&mut self) {
        self.stop();
    }
}

/// gpsfake (tests/run.sh installs Debian's `gpsd` and `gpsd-clients`).
fn gpsfake() -> &'static str {
    let found = Command::new("gpsfake")
        .arg("-h")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok();
    assert!(
        found,
        "gpsfake not found: install Debian's gpsd and gpsd-clients (tests/run.sh does)"
    );
    "gpsfake"
}
