//! CPU and memory of processes, from Linux's `/proc` (`None` elsewhere): what the
//! benchmarks report as `*_cpu_s` and `*_peak_rss_mb`.

use std::collections::BTreeMap;

/// Clock ticks per second of `/proc/<pid>/stat` (`USER_HZ`, 100 on Linux).
const USER_HZ: f64 = 100.0;

/// User + system CPU seconds of process `pid` (this process for `None`), from
/// `/proc/<pid>/stat`; `None` where that does not exist.
pub fn cpu_seconds(pid: Option<u32>) -> Option<f64> {
    let path = pid.map_or_else(|| "/proc/self/stat".into(), |p| format!("/proc/{p}/stat"));
    let stat = std::fs::read_to_string(path).ok()?;
    // Fields after the command name (which may contain spaces) start at field 3.
    let rest = stat.get(stat.rfind(')')? + 1..)?;
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let utime: u64 = fields.get(11)?.parse().ok()?;
    let stime: u64 = fields.get(12)?.parse().ok()?;
    Some((utime + stime) as f64 / USER_HZ)
}

/// CPU seconds each thread name of process `pid` (this process for `None`) has used, summed
/// over the threads that share the name (`tokio-rt-worker`), from each thread's
/// `/proc/<pid>/task/<tid>/schedstat` (time on a CPU, in nanoseconds: exact, unlike the
/// tick-sampled user/system split of `stat`, which a thread woken in step with the
/// kernel's tick gets wrong by half). Threads that ended are not counted; empty where
/// `/proc` does not exist.
pub fn thread_cpu_seconds(pid: Option<u32>) -> BTreeMap<String, f64> {
    let dir = pid.map_or_else(|| "/proc/self/task".into(), |p| format!("/proc/{p}/task"));
    let mut by_name = BTreeMap::new();
    let Ok(tasks) = std::fs::read_dir(dir) else {
        return by_name;
    };
    for task in tasks.flatten() {
        let path = task.path();
        let (Ok(name), Ok(schedstat)) = (
            std::fs::read_to_string(path.join("comm")),
            std::fs::read_to_string(path.join("schedstat")),
        ) else {
            continue; // the thread ended meanwhile
        };
        let Some(ns) = schedstat
            .split_whitespace()
            .next()
            .and_then(|f| f.parse::<u64>().ok())
        else {
            continue;
        };
        *by_name.entry(name.trim().to_owned()).or_insert(0.0) += ns as f64 / 1e9;
    }
    by_name
}

/// Busy CPU seconds of the whole host since boot (every core: user, nice, system, irq,
/// softirq, steal), from `/proc/stat`.
pub fn host_busy_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/stat").ok()?;
    let line = stat.lines().find(|l| l.starts_with("cpu "))?;
    let v: Vec<u64> = line
        .split_whitespace()
        .skip(1)
        .filter_map(|x| x.parse().ok())
        .collect();
    // user nice system idle iowait irq softirq steal
    let busy = v.first()? + v.get(1)? + v.get(2)? + v.get(5)? + v.get(6)? + v.get(7)?;
    Some(busy as f64 / USER_HZ)
}

/// Peak resident set size of this process, MB (`VmHWM` in `/proc/self/status`).
pub fn peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn own_cpu_and_memory_are_readable_on_linux() {
        if !cfg!(target_os = "linux") {
            return;
        }
        let cpu = cpu_seconds(None).expect("/proc/self/stat");
        assert!(cpu >= 0.0);
        assert!(peak_rss_mb().expect("VmHWM") > 0.0);
        assert!(cpu_seconds(Some(std::process::id())).is_some());
        // This thread is one of them, and has run.
        let threads = thread_cpu_seconds(None);
        assert!(threads.values().sum::<f64>() > 0.0, "{threads:?}");
    }
}
