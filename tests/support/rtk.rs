//! An NTRIP caster nobody here wrote: RTKLIB's `str2str` (Debian's `rtklib`) serving a
//! mountpoint, fed over TCP by a base station that streams pyrtcm-checked RTCM3
//! (`tests/peers/rtcm_base.py`). Both are killed on drop. And a plainer base station
//! sending RTCM3 datagrams to a UDP port ([`UdpBase`]).

use super::python::python;
use super::{Process, eventually, free_tcp_port, free_udp_range, workspace};
use skein_model::geo::GeoPoint;
use std::net::UdpSocket;
use std::sync::mpsc::{self, RecvTimeoutError};
use std::thread::JoinHandle;
use std::time::Duration;

/// A base station sending RTCM3 datagrams to a free UDP port of 127.0.0.1 once a second
/// (an epoch: its position, message 1005, and an MSM4 frame, 1074, written by
/// `skein_rtk::testing`), from a thread, until dropped.
pub struct UdpBase {
    /// The port the datagrams go to (skein's `udp://127.0.0.1:PORT` source).
    pub port: u16,
    /// Dropped to stop the thread at once (not after its second's wait).
    stop: Option<mpsc::Sender<()>>,
    thread: Option<JoinHandle<()>>,
}

impl UdpBase {
    /// Starts sending, the base at `base` (lat, lon degrees, ellipsoid height m).
    pub fn start(base: (f64, f64, f64)) -> UdpBase {
        let port = free_udp_range(1);
        let (stop, stopped) = mpsc::channel::<()>();
        let epoch = [
            skein_rtk::testing::frame_1005(7, GeoPoint::new(base.0, base.1, base.2)),
            skein_rtk::testing::frame_of(1074, 200),
        ];
        let thread = std::thread::spawn(move || {
            let sock = UdpSocket::bind("127.0.0.1:0").expect("a UDP socket");
            loop {
                for f in &epoch {
                    // Nobody listening yet is fine: the next epoch comes in a second.
                    let _ = sock.send_to(f, ("127.0.0.1", port));
                }
                if stopped.recv_timeout(Duration::from_secs(1)) != Err(RecvTimeoutError::Timeout) {
                    return;
                }
            }
        });
        UdpBase {
            port,
            stop: Some(stop),
            thread: Some(thread),
        }
    }

    /// skein's source for it.
    pub fn source(&self) -> String {
        format!("udp://127.0.0.1:{}", self.port)
    }
}

impl Drop for UdpBase {
    fn drop(&mut self) {
        self.stop.take();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The caster's user, password and mountpoint.
pub const USER: &str = "crew";
/// The caster's password.
pub const PASSWORD: &str = "s3cret";
/// The caster's mountpoint.
pub const MOUNTPOINT: &str = "SKEIN";

/// `str2str` as an NTRIP caster and the base station feeding it.
pub struct Caster {
    /// The caster's NTRIP port.
    pub port: u16,
    feed_port: u16,
    base: (f64, f64, f64),
    corrupt_every: u32,
    caster: Option<Process>,
    feed: Option<Process>,
}

impl Caster {
    /// Starts the caster and a base station at `base` (lat, lon degrees, ellipsoid height
    /// m) sending one epoch a second, every `corrupt_every`-th observation frame with a
    /// bad CRC (0: none).
    pub fn start(base: (f64, f64, f64), corrupt_every: u32) -> Caster {
        let mut c = Caster {
            port: free_tcp_port(),
            feed_port: free_tcp_port(),
            base,
            corrupt_every,
            caster: None,
            feed: None,
        };
        c.start_caster();
        c.start_feed();
        c
    }

    /// The `ntrip://` source of the mountpoint, with the credentials.
    pub fn source(&self) -> String {
        format!(
            "ntrip://{USER}:{PASSWORD}@127.0.0.1:{}/{MOUNTPOINT}",
            self.port
        )
    }

    /// Starts `str2str`: RTCM3 in from a TCP server port, out as an NTRIP caster.
    pub fn start_caster(&mut self) {
        let input = format!("tcpsvr://:{}", self.feed_port);
        let output = format!("ntripc://{USER}:{PASSWORD}@:{}/{MOUNTPOINT}", self.port);
        let p = Process::start_command(&[str2str(), "-in", &input, "-out", &output], &[]);
        // str2str says so on stderr.
        eventually("str2str serving", Duration::from_secs(10), || {
            let said = p.stderr.lock().unwrap().join("\n");
            if said.contains("stream server start") && !said.contains("start error") {
                Ok(())
            } else {
                Err(said)
            }
        });
        self.caster = Some(p);
    }

    /// Starts the base station (connects to the caster's input).
    pub fn start_feed(&mut self) {
        let script = workspace().join("tests/peers/rtcm_base.py");
        let py = python();
        let (port, lat, lon, alt, corrupt) = (
            self.feed_port.to_string(),
            self.base.0.to_string(),
            self.base.1.to_string(),
            self.base.2.to_string(),
            self.corrupt_every.to_string(),
        );
        let mut p = Process::start_command(
            &[
                py.to_str().unwrap(),
                script.to_str().unwrap(),
                "--port",
                &port,
                "--lat",
                &lat,
                "--lon",
                &lon,
                "--alt",
                &alt,
                "--corrupt-every",
                &corrupt,
            ],
            &[],
        );
        p.wait_line("connected", Duration::from_secs(15));
        self.feed = Some(p);
    }

    /// Stops the base station: the caster stays up and sends nothing.
    pub fn stop_feed(&mut self) {
        self.feed = None;
    }

    /// Stops the caster itself.
    pub fn stop_caster(&mut self) {
        self.caster = None;
    }
}

/// RTKLIB's `str2str` (tests/run.sh installs Debian's `rtklib`).
fn str2str() -> &'static str {
    let found = std::process::Command::new("str2str")
        .arg("-h")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok();
    assert!(
        found,
        "str2str not found: install Debian's rtklib (tests/run.sh does)"
    );
    "str2str"
}
