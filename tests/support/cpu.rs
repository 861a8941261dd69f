//! Starving a process of CPU on purpose, for the overload tests: the process pinned to
//! one CPU with busy loops pinned beside it, as when other work on a companion computer
//! takes the cores (a vision pipeline, a compiler). The scheduler shares the CPU between
//! runnable threads by weight, so the process's ordinary threads get a share that shrinks
//! with the number of loops, while a thread of higher priority (skein's setpoint thread)
//! still runs when it needs to.
//!
//! A cgroup CPU quota was tried and left: once a quota per period is shorter than the
//! scheduler's time slice, whichever thread ran last keeps the CPU for several periods
//! whatever the priorities inside the group, and pauses of the setpoint stream of
//! 100–160 ms came from the kernel, not from skein.

use std::process::{Child, Command, Stdio};

/// Busy loops pinned to CPU 0 beside the starved process; killed on drop, and by the
/// kernel when the thread that started them dies.
pub struct Starvation {
    hogs: Vec<Child>,
}

impl Starvation {
    /// Pins `pid` (every thread) to CPU 0 and starts enough busy loops there that its
    /// `busy_threads` ordinary threads, all runnable, get about `share` of that CPU.
    pub fn starve(pid: u32, share: f64, busy_threads: usize) -> Starvation {
        pin(pid, "0");
        let share = share.clamp(0.01, 1.0);
        let n = ((busy_threads as f64) * (1.0 / share - 1.0))
            .ceil()
            .max(1.0) as usize;
        Starvation {
            hogs: (0..n)
                .map(|_| {
                    // The parent-death signal kills the loop with the test that started it,
                    // even when a timeout SIGKILLs the test binary before `Drop` runs:
                    // orphaned loops would starve every later test on this machine.
                    Command::new("setpriv")
                        .args(["--pdeathsig", "KILL", "taskset", "-c", "0"])
                        .args(["sh", "-c", "while :; do :; done"])
                        .stdout(Stdio::null())
                        .stderr(Stdio::null())
                        .spawn()
                        .expect("setpriv and taskset (util-linux) start a busy loop")
                })
                .collect(),
        }
    }

    /// What starves it, for messages.
    pub fn describe(&self) -> String {
        format!("CPU 0 shared with {} busy loops", self.hogs.len())
    }
}

impl Drop for Starvation {
    fn drop(&mut self) {
        for h in &mut self.hogs {
            let _ = h.kill();
            let _ = h.wait();
        }
    }
}

/// Pins every thread of `pid` (and those it starts later) to `cpus` (`taskset` list).
pub fn pin(pid: u32, cpus: &str) {
    let status = Command::new("taskset")
        .args(["-a", "-p", "-c", cpus, &pid.to_string()])
        .stdout(Stdio::null())
        .status()
        .expect("taskset");
    assert!(status.success(), "taskset -a -p -c {cpus} {pid}");
}

/// CPU time `pid` has used so far (user + system), seconds, from `/proc/PID/stat`.
pub fn cpu_seconds(pid: u32) -> f64 {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).expect("/proc/PID/stat");
    // The fields after the command (which may hold spaces) start after its ')'.
    let fields: Vec<&str> = stat[stat.rfind(')').expect("stat") + 2..]
        .split_whitespace()
        .collect();
    let ticks: f64 = fields[11].parse::<f64>().unwrap() + fields[12].parse::<f64>().unwrap();
    // USER_HZ is 100 on Linux's supported architectures.
    ticks / 100.0
}

/// Gives every thread of `pid` the nice value `nice` (best effort: a negative one needs
/// privilege; returns whether it was applied).
pub fn renice(pid: u32, nice: i32) -> bool {
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return false;
    };
    let tids: Vec<String> = tasks
        .flatten()
        .map(|t| t.file_name().to_string_lossy().into_owned())
        .collect();
    Command::new("renice")
        .args(["-n", &nice.to_string(), "-p"])
        .args(&tids)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}
