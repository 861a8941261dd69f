//! The setpoint thread's scheduling priority.
//!
//! When the process runs short of CPU (a companion computer's cores shared with other
//! work, a container's CPU quota), every thread of it waits for the CPU, and the
//! setpoint thread must wait least: PX4 fails safe after `COM_OF_LOSS_T` without a
//! setpoint, whereas everything else skein does can run late. Linux schedules threads
//! by weight within a process's group; the setpoint thread asks for nice
//! [`SETPOINT_NICE`] (about nine times the CPU share of a thread at nice 0 when both
//! want it), which needs `CAP_SYS_NICE` or an `RLIMIT_NICE` that allows it (systemd:
//! `LimitNICE=-10` or `AmbientCapabilities=CAP_SYS_NICE`). Without them it stays at the
//! process's priority, says so once, and [`setpoint_priority`] reports it.

use std::sync::OnceLock;

/// The nice value the setpoint thread asks for (-20 highest … 19 lowest).
pub const SETPOINT_NICE: i32 = -10;

/// Whether the setpoint thread got its priority.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub enum Priority {
    /// It runs at this nice value.
    Raised(i32),
    /// It runs at the process's priority: why it could not be raised.
    Refused(String),
}

static SETPOINT: OnceLock<Priority> = OnceLock::new();

/// Sets the calling thread's nice value (Linux: per thread).
///
/// # Errors
/// The OS's refusal (`EACCES`/`EPERM` without the privilege to raise priority).
pub fn set_current_thread_nice(nice: i32) -> Result<(), String> {
    let tid = rustix::thread::gettid();
    rustix::process::setpriority_process(Some(tid), nice)
        .map_err(|e| format!("setpriority(nice {nice}): {e}"))
}

/// Raises the calling thread (the setpoint thread, at its start) to [`SETPOINT_NICE`] and
/// records the outcome for [`setpoint_priority`].
pub(crate) fn raise_setpoint_thread() {
    let outcome = match set_current_thread_nice(SETPOINT_NICE) {
        Ok(()) => Priority::Raised(SETPOINT_NICE),
        Err(e) => {
            tracing::warn!(
                "the setpoint thread runs at normal priority ({e}): under CPU shortage its \
                 setpoints wait like any other work; give skein CAP_SYS_NICE or LimitNICE=-10"
            );
            Priority::Refused(e)
        }
    };
    let _ = SETPOINT.set(outcome);
}

/// The setpoint thread's priority, once it has started (`None` before the first stream).
pub fn setpoint_priority() -> Option<Priority> {
    SETPOINT.get().cloned()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_thread_may_always_lower_its_own_priority() {
        // Lowering needs no privilege; this thread ends with the test.
        std::thread::spawn(|| set_current_thread_nice(5))
            .join()
            .unwrap()
            .unwrap();
    }
}
