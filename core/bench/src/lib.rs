//! skein's tooling, apart from the crates that fly aircraft (none of them depends on this
//! one): the benchmarks of `skein bench <what>` (executable `skein-bench`, which `skein
//! bench` runs; each prints one JSON object on stdout, progress on stderr), and
//! [`rehearsal`], formation flight in virtual time (the transition and loss sweeps in
//! `tests/`, `skein bench formation`). The benchmarks start the `skein` executable for the
//! processes they measure ([`skein_exe`]).
//!
//! `skein bench formation [--vehicles 8,32]`: formation flight in virtual time, see
//! [`formation`].
//!
//! `skein bench tracking [--seconds 120 --intruders 3 --seed 1]`: the counter-UAS chain
//! (intruders, cameras, detectors, tracker) against the simulator's truth, see
//! [`tracking`].
//!
//! `skein bench dds [--vehicles 8 --seconds 20]`: CPU of the ROS 2 topics per vehicle and
//! pose latency to a subscriber, see [`dds`]; with `--distributed`, N agents and a
//! coordinator against one process: slot-target latency, CPU per vehicle, formation
//! error, see [`distributed`].
//!
//! `skein bench mission [--vehicles 8 --patrol-s 330]`: a sortie with every reaction
//! rehearsed in virtual time, see [`mission`].
//!
//! `skein bench api [--vehicles 24 --busy-clients 4]`: the API's read latency while the
//! coordinator is busy, see [`api`].
//!
//! `skein bench swarm --vehicles N --rate-hz R --seconds S` (issue 3's benchmark):
//!
//! 1. opens one `udpin` endpoint per vehicle on a free block of N consecutive local UDP
//!    ports and starts skein's real stack on them in this process ([`Swarm::start`]: the
//!    Coordinator, one Vehicle and one Px4Link actor per vehicle, setpoint streams at R Hz,
//!    the reduced `swarm` telemetry profile);
//! 2. starts the simulator **in its own process** (this binary, `skein sim --profile swarm
//!    --per-vehicle-targets --stats 127.0.0.1:0`), vehicle i sending to port base + i with
//!    sysid `i % 250 + 1` beyond 255 vehicles (identity is (endpoint, sysid));
//! 3. waits until every vehicle has joined with a position, sends the swarm `takeoff`
//!    command to a low altitude (retrying vehicles that are not ready yet) and waits until
//!    every vehicle is `Hovering` under offboard control;
//! 4. resets the simulator's counters and measures for S seconds: nothing else runs in
//!    this process meanwhile but skein's stack;
//! 5. prints `vehicles`, `rate_hz`, `seconds`, `setpoints_sent` (skein side),
//!    `setpoints_received` (simulator side), `late_fraction` (intervals between
//!    consecutive setpoints of a vehicle, as received by the simulator, longer than
//!    1.25 × the period, over all intervals), `interval_ms` (`p50`, `p99`, `p999`, `max`,
//!    `mean`), `coordinator_cpu_s` (user + system CPU of this process over the window),
//!    `coordinator_threads_cpu_s` (the same by thread name: `skein-setpoints` is the
//!    setpoint thread, which does little but hand datagrams to the kernel, `tokio-rt-worker`
//!    the runtime's workers: control, telemetry, everything else),
//!    `coordinator_peak_rss_mb` (`VmHWM`), `sim_cpu_s` (the simulator process's user +
//!    system CPU over the window), `offboard_loss_failsafes`, `all_offboard` (every
//!    simulated vehicle in OFFBOARD at the end of the window), and a few diagnostics.
//!
//! Interval percentiles come from the simulator's histogram (0.1 ms buckets below 100 ms):
//! each is the upper edge of its bucket, and a bucket straddling the lateness threshold
//! counts as late, so both err on the pessimistic side by at most 0.1 ms.
//!
//! `setpoints_sent` is the sum of every vehicle's `SetpointStream::counts().sent` over the
//! window, read through the coordinator's metrics (`skein_setpoints_sent`); the window's
//! ends on the two sides are a few milliseconds apart, so sent and received may differ by
//! about one setpoint per vehicle without any loss.
//!
//! CPU figures come from `/proc/<pid>/stat` (Linux; `null` elsewhere) in units of
//! `USER_HZ` = 100 ticks/s, so they are good to 10 ms. Diagnostics: `host_other_cpu_s` is
//! the CPU the rest of the host used during the window (anything large means the run
//! competed with other work for the cores: rerun on a quiet host), and `runtime_probe` is a
//! task ticking at the setpoint period on this process's runtime, whose lateness is the
//! runtime's own scheduling latency. `cpu_ms_per_vehicle_second` is `coordinator_cpu_s`
//! per vehicle and second of the window, `peak_rss_kib_per_vehicle` the peak resident
//! memory per vehicle.
//!
//! With `--peer pymavlink` the same swarm is then flown by a plain pymavlink loop
//! (`tests/peers/pymavlink_loop.py`) against a fresh simulator, in the same run: its
//! figures are under `peer`, and `cpu_ratio_to_peer` is skein's CPU per vehicle-second
//! over the loop's. `setpoint_thread_ratio_to_peer` is skein's setpoint thread alone over
//! the loop's whole CPU: mostly the kernel's cost of the setpoint datagrams, which the loop
//! sends as well, so no change to the rest of skein takes `cpu_ratio_to_peer` below it.
//!
//! With `--peer floor` the baseline is instead the floor of issue 47 (`src/floor.rs`): a
//! minimal controller on a thread of this process that holds the same simulated vehicles
//! (fresh simulator, same `--vehicles-per-port`) with nothing but the datagrams: frames
//! encoded once, one `sendmmsg` per period for every vehicle's setpoint, `recvmmsg` drains
//! of the telemetry without decoding, its CPU the thread's `schedstat` over the window.
//! `cpu_ratio_to_peer` is then skein's CPU per vehicle-second over the least any controller
//! could spend on the same setpoint path (issue 47's `cpu_ratio_to_floor`).

#![warn(missing_docs)]

mod api;
mod cli;
mod dds;
mod distributed;
mod exe;
mod floor;
mod formation;
mod mission;
mod peer;
mod plugins;
mod procfs;
pub mod rehearsal;
mod restart;
mod sim_process;
mod stack;
mod swarm;
mod tracking;
mod up_process;

pub use api::{ApiBenchArgs, api};
pub use cli::{BenchArgs, BenchWhat, PluginsBenchArgs, SwarmBenchArgs, run};
pub use dds::{DdsBenchArgs, dds};
pub use exe::skein_exe;
pub use formation::{FormationBenchArgs, formation};
pub use mission::{MissionBenchArgs, mission};
pub use plugins::{BenchConfig, bench_plugins, plugins};
pub use procfs::{cpu_seconds, host_busy_seconds, peak_rss_mb, thread_cpu_seconds};
pub use restart::{RestartBenchArgs, restart};
pub use swarm::swarm;
pub use tracking::{TrackingBenchArgs, tracking};

/// Rounds to `digits` decimals for the report.
pub(crate) fn round(x: f64, digits: i32) -> f64 {
    let k = 10f64.powi(digits);
    (x * k).round() / k
}
