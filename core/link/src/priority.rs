//! The setpoint thread's scheduling priority.
//!
//! When the process runs short of CPU (a companion computer's cores shared with other
//! work, a container's CPU quota), every thread of it waits for the CPU, and the
//! setpoint thread must wait least: PX4 fails safe after `COM_OF_LOSS_T` without a
//! setpoint, whereas everything else skein does can run late. The setpoint thread asks,
//! in this order, for
//!
//! 1. real-time scheduling, `SCHED_FIFO` at the lowest real-time priority (1): it then
//!    runs as soon as it wakes, ahead of every ordinary thread of every process, however
//!    many compete (PX4 runs its own control loops the same way). It mostly sleeps and
//!    spends microseconds per wake-up, so it never takes a core from anyone for long, and
//!    the kernel's real-time throttling (`sched_rt_runtime_us`) bounds it even if it did;
//! 2. failing that, nice [`SETPOINT_NICE`] (about nine times the CPU share of a thread at
//!    nice 0 when both want it: under a heavy load of ordinary threads, 50+ busy loops on
//!    one core, such a thread was still kept off the CPU for over 100 ms);
//! 3. failing both, the process's own priority: it says so once.
//!
//! Both need `CAP_SYS_NICE` (root has it; systemd: `AmbientCapabilities=CAP_SYS_NICE`, or
//! `LimitRTPRIO=1` for the first and `LimitNICE=-10` for the second; Docker:
//! `--cap-add SYS_NICE`). [`setpoint_priority`] reports what it got (`GET
//! /api/v1/health`, `load.setpoint_priority`).

use serde::Serialize;
use std::sync::OnceLock;

/// The nice value the setpoint thread asks for when it cannot have real-time scheduling
/// (-20 highest … 19 lowest).
pub const SETPOINT_NICE: i32 = -10;

/// The scheduling the setpoint thread got.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum Priority {
    /// Real-time `SCHED_FIFO` at this priority (1 = the lowest real-time one).
    Realtime {
        /// `sched_priority`.
        priority: i32,
    },
    /// Ordinary scheduling at this nice value; `realtime_refused` says why real-time
    /// scheduling was not had.
    Nice {
        /// The nice value.
        nice: i32,
        /// The OS's refusal of `SCHED_FIFO`.
        realtime_refused: String,
    },
    /// The process's own priority: why neither could be had.
    Refused {
        /// The OS's refusals.
        reason: String,
    },
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

/// Puts the calling thread under `SCHED_FIFO` at the lowest real-time priority.
///
/// # Errors
/// The OS's refusal (`EPERM` without `CAP_SYS_NICE` or an `RLIMIT_RTPRIO` of at least 1).
pub fn set_current_thread_realtime() -> Result<i32, String> {
    use thread_priority::unix::{
        RealtimeThreadSchedulePolicy, ThreadSchedulePolicy, set_thread_priority_and_policy,
        thread_native_id, thread_schedule_policy_param,
    };
    let policy = ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo);
    set_thread_priority_and_policy(
        thread_native_id(),
        thread_priority::ThreadPriority::Min,
        policy,
    )
    .map_err(|e| format!("SCHED_FIFO: {e:?}"))?;
    let (_, params) =
        thread_schedule_policy_param(thread_native_id()).map_err(|e| format!("{e:?}"))?;
    Ok(params.sched_priority)
}

/// Raises the calling thread as the module docs say: real-time, else nice
/// [`SETPOINT_NICE`], else neither (with the OS's refusals).
fn raise_current_thread() -> Priority {
    match set_current_thread_realtime() {
        Ok(priority) => Priority::Realtime { priority },
        Err(rt) => match set_current_thread_nice(SETPOINT_NICE) {
            Ok(()) => Priority::Nice {
                nice: SETPOINT_NICE,
                realtime_refused: rt,
            },
            Err(e) => Priority::Refused {
                reason: format!("{rt}; {e}"),
            },
        },
    }
}

/// Raises the calling thread (a byte-stream endpoint's writer, which carries the
/// setpoints of its vehicles: `crate::endpoint::stream`) as the setpoint thread is (when
/// it may not, neither may the setpoint thread, and the health endpoint says so).
pub(crate) fn raise_writer_thread() {
    if let Priority::Refused { reason } = raise_current_thread() {
        tracing::debug!("a byte-stream writer thread runs at normal priority ({reason})");
    }
}

/// Raises the calling thread (the setpoint thread, at its start) as the module docs say
/// and records the outcome for [`setpoint_priority`].
pub(crate) fn raise_setpoint_thread() {
    let outcome = raise_current_thread();
    if let Priority::Refused { reason } = &outcome {
        tracing::warn!(
            "the setpoint thread runs at normal priority ({reason}): under CPU shortage its \
             setpoints wait like any other work; give skein CAP_SYS_NICE (or \
             LimitRTPRIO=1 / LimitNICE=-10)"
        );
    }
    let _ = SETPOINT.set(outcome);
}

/// The setpoint thread's scheduling, once it has started (`None` before the first
/// stream).
pub fn setpoint_priority() -> Option<Priority> {
    SETPOINT.get().cloned()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_thread_gets_real_time_scheduling_where_the_process_may_and_a_clear_refusal_if_not() {
        // Root (CAP_SYS_NICE) gets SCHED_FIFO 1; anyone else a refusal naming it. Which one
        // this process may have is the OS's answer to the same question.
        let may = rustix::process::getuid().is_root();
        let got = std::thread::spawn(set_current_thread_realtime)
            .join()
            .unwrap();
        match got {
            Ok(p) => assert_eq!(p, 1),
            Err(e) => {
                assert!(!may, "root refused SCHED_FIFO: {e}");
                assert!(e.contains("SCHED_FIFO"), "{e}");
            }
        }
    }

    #[test]
    fn a_thread_may_always_lower_its_own_priority() {
        // Lowering needs no privilege; this thread ends with the test.
        std::thread::spawn(|| set_current_thread_nice(5))
            .join()
            .unwrap()
            .unwrap();
    }
}
