//! The RTSP camera of the video tests: `tests/peers/rtsp_server.py` (Debian's ffmpeg
//! encoding H.264, served over RTSP), a [`Process`] started on a port and killed on drop
//! (its ffmpeg dies with it: the script sets the parent-death signal).

use super::Process;
use std::time::Duration;

/// A running RTSP camera.
pub struct RtspCamera {
    process: Process,
    /// The TCP port it serves on (127.0.0.1).
    pub port: u16,
}

impl RtspCamera {
    /// Starts the camera on `port` (0: a free one) with the script's `args`
    /// (`--size 320x240 --rate 10 --image F --corrupt-every N --garbage-after N`).
    pub fn start(port: u16, args: &[&str]) -> RtspCamera {
        let script = super::workspace().join("tests/peers/rtsp_server.py");
        let port = port.to_string();
        let mut command = vec!["python3", script.to_str().unwrap(), "--port", &port];
        command.extend_from_slice(args);
        let mut process = Process::start_command(&command, &[]);
        let line = process.wait_line("RTSP_PORT ", Duration::from_secs(30));
        let port = line["RTSP_PORT ".len()..]
            .trim()
            .parse()
            .expect("a port number");
        RtspCamera { process, port }
    }

    /// `rtsp://127.0.0.1:PORT/main`.
    pub fn url(&self) -> String {
        format!("rtsp://127.0.0.1:{}/main", self.port)
    }

    /// Stops the camera (SIGTERM: it stops its ffmpeg, then exits) and waits until it is
    /// gone, its port free for a restart; returns the port.
    pub fn stop(mut self) -> u16 {
        self.process.terminate();
        self.process.wait_exit(Duration::from_secs(10));
        self.port
    }
}
