//! A `skein` process of a test: started on the binary cargo built, its output kept for
//! failure messages, killed on drop.

use super::skein_bin;
use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

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
        match netns {
            Some(ns) => Process::start_with(&["ip", "netns", "exec", ns], &[], args),
            None => Process::start_with(&[], &[], args),
        }
    }

    /// Starts `<prefix…> skein <args>` with `env` added to the environment. The prefix is a
    /// command that execs the rest (`ip netns exec NS`, `prlimit …`, `setpriv …`), so
    /// that the child's pid is skein's.
    pub fn start_with(prefix: &[&str], env: &[(&str, &str)], args: &[&str]) -> Process {
        let mut command: Vec<&str> = prefix.to_vec();
        command.push(skein_bin());
        command.extend_from_slice(args);
        Process::start_command(&command, env)
    }

    /// Starts `command` (a program and its arguments: another build of skein, one under
    /// an emulator) with `env` added to the environment.
    pub fn start_command(command: &[&str], env: &[(&str, &str)]) -> Process {
        super::failure::keep_panic_messages();
        let (program, args) = command.split_first().expect("a program");
        let mut child = Command::new(program)
            .args(args)
            .envs(env.iter().copied())
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

    /// Waits for a stdout line containing `needle` and returns it. Fails at `timeout`, or
    /// a moment after the process exited (a child of it may keep its stdout open, so the
    /// end of the pipe does not tell).
    pub fn wait_line(&mut self, needle: &str, timeout: Duration) -> String {
        let mut deadline = Instant::now() + timeout;
        let mut exited = false;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self
                .lines
                .recv_timeout(left.min(Duration::from_millis(250)))
            {
                Ok(l) if l.contains(needle) => return l,
                Ok(_) => continue,
                Err(mpsc::RecvTimeoutError::Timeout) if !left.is_zero() => {
                    if !exited && self.child.try_wait().is_ok_and(|s| s.is_some()) {
                        // What it wrote before it exited is still read for a moment.
                        exited = true;
                        deadline = deadline.min(Instant::now() + Duration::from_secs(2));
                    }
                }
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

    /// Sends SIGTERM (what systemd and `docker stop` send), without waiting.
    pub fn terminate(&self) {
        self.signal("TERM");
    }

    /// Sends the signal named `name` (`TERM`, `KILL`, `USR1`), without waiting.
    pub fn signal(&self, name: &str) {
        let status = Command::new("kill")
            .args([&format!("-{name}"), &self.pid().to_string()])
            .status()
            .expect("kill");
        assert!(status.success(), "kill -{name} {}", self.pid());
    }

    /// Everything on stdout so far.
    pub fn stdout_text(&self) -> String {
        self.stdout.lock().unwrap().join("\n")
    }
}

impl Drop for Process {
    /// Kills the process; when a test is failing, prints its last warnings and errors (runs
    /// of one message collapsed), so that a CI log tells what the process saw, and the
    /// failure's message again after them.
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        if std::thread::panicking() {
            let lines = self.stderr.lock().unwrap_or_else(|e| e.into_inner());
            let notable = super::failure::collapsed(
                lines
                    .iter()
                    .filter(|l| l.contains("WARN") || l.contains("ERROR")),
            );
            let from = notable.len().saturating_sub(30);
            eprintln!(
                "--- last {} warnings and errors of the process under test ---",
                notable.len() - from
            );
            for l in &notable[from..] {
                eprintln!("{l}");
            }
            super::failure::repeat_failure();
        }
    }
}
