//! The simulator in its own process for `skein bench swarm` and `skein bench restart`:
//! `skein sim --profile swarm --stats 127.0.0.1:0`, driven through its stats socket.

use crate::SwarmBenchArgs;
use serde_json::Value;
use std::net::SocketAddr;
use std::process::Stdio;
use std::time::Duration;
use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader, Lines};
use tokio::net::TcpStream;
use tokio::net::tcp::{OwnedReadHalf, OwnedWriteHalf};
use tokio::process::{Child, Command};

/// Longest wait for the simulator's stats socket to answer one command.
const STATS_TIMEOUT: Duration = Duration::from_secs(30);

/// The simulator child process and its stats socket.
pub(crate) struct SimProcess {
    child: Child,
    /// The simulator's process id (for its CPU figures).
    pub(crate) pid: Option<u32>,
    lines: Lines<BufReader<OwnedReadHalf>>,
    write: OwnedWriteHalf,
}

impl SimProcess {
    /// Starts `skein sim` with vehicle i sending to `target_base + i / vehicles_per_port`;
    /// returns once the
    /// simulator is ready and its stats socket is connected.
    pub(crate) async fn start(
        args: &SwarmBenchArgs,
        target_base: u16,
    ) -> Result<SimProcess, String> {
        let exe = crate::skein_exe()?;
        let mut child = Command::new(exe)
            .args(["sim", "--profile", "swarm", "--per-vehicle-targets"])
            .args(["--vehicles", &args.vehicles.to_string()])
            .args(["--listen-base-port", "0"])
            .args(["--target-base-port", &target_base.to_string()])
            .args([
                "--vehicles-per-target-port",
                &args.vehicles_per_port.to_string(),
            ])
            .args(["--spacing-m", &args.spacing_m.to_string()])
            .args(["--seed", &args.seed.to_string()])
            .args(["--stats", "127.0.0.1:0"])
            .env("SKEIN_LOG", "warn")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .kill_on_drop(true)
            .spawn()
            .map_err(|e| format!("cannot start the simulator: {e}"))?;
        let pid = child.id();
        let stdout = child.stdout.take().ok_or("simulator stdout")?;
        let mut out = BufReader::new(stdout).lines();
        let mut stats_addr: Option<SocketAddr> = None;
        let deadline = tokio::time::Instant::now() + Duration::from_secs(60);
        loop {
            let line = tokio::time::timeout_at(deadline, out.next_line())
                .await
                .map_err(|_| "the simulator did not get ready within 60 s".to_string())?
                .map_err(|e| format!("simulator stdout: {e}"))?
                .ok_or("the simulator exited before it was ready")?;
            if let Some(addr) = line.strip_prefix("stats ") {
                stats_addr = addr.trim().parse().ok();
            } else if line.trim() == "ready" {
                break;
            }
        }
        // Keep draining its stdout so that it never writes into a closed pipe.
        tokio::spawn(async move { while let Ok(Some(_)) = out.next_line().await {} });
        let addr = stats_addr.ok_or("the simulator printed no stats address")?;
        let stream = TcpStream::connect(addr)
            .await
            .map_err(|e| format!("simulator stats socket {addr}: {e}"))?;
        let (read, write) = stream.into_split();
        Ok(SimProcess {
            child,
            pid,
            lines: BufReader::new(read).lines(),
            write,
        })
    }

    /// One stats-socket command; its JSON answer (an `{"error"}` answer is an error).
    pub(crate) async fn ask(&mut self, cmd: &str) -> Result<Value, String> {
        self.write
            .write_all(format!("{cmd}\n").as_bytes())
            .await
            .map_err(|e| format!("simulator stats socket: {e}"))?;
        let line = tokio::time::timeout(STATS_TIMEOUT, self.lines.next_line())
            .await
            .map_err(|_| format!("the simulator did not answer `{cmd}` in time"))?
            .map_err(|e| format!("simulator stats socket: {e}"))?
            .ok_or("the simulator closed its stats socket")?;
        let v: Value =
            serde_json::from_str(&line).map_err(|e| format!("simulator answer to `{cmd}`: {e}"))?;
        match v.get("error") {
            Some(e) => Err(format!("simulator refused `{cmd}`: {e}")),
            None => Ok(v),
        }
    }

    pub(crate) async fn stop(mut self) {
        let _ = self.child.start_kill();
        let _ = self.child.wait().await;
    }
}
