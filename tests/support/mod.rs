//! Shared support for skein's end-to-end tests: run the `skein` binary as a process on
//! free ports, talk to it over HTTP only, poll with deadlines, and find the Python peers.
#![allow(dead_code)] // each test binary uses a different subset

use std::path::{Path, PathBuf};
use std::sync::Mutex;

pub mod bench;
pub mod counter_uas;
pub mod cpu;
pub mod distributed;
pub mod docker;
mod events;
mod failure;
pub mod formation;
pub mod gpsd;
pub mod lens;
pub mod map_tiles;
pub mod netns;
pub mod payloads;
mod plugin_build;
pub mod plugins;
mod polling;
mod ports;
mod process;
mod python;
pub mod ros2;
pub mod rtk;
pub mod rtsp;
mod sim_stats;
mod skein;
pub mod video;

// Each test binary uses a different subset.
#[allow(unused_imports)]
pub use events::EventLog;
#[allow(unused_imports)]
pub use polling::{eventually, steady_for};
#[allow(unused_imports)]
pub use ports::{free_tcp_port, free_udp_range};
#[allow(unused_imports)]
pub use process::Process;
#[allow(unused_imports)]
pub use python::{python, run_peer, run_python, run_python_in};
#[allow(unused_imports)]
pub use sim_stats::{
    assert_no_failsafe_and_no_gap, assert_no_failsafe_and_no_gap_in, sim_stats,
    truth_min_separation, truth_min_separation_across, try_sim_stats,
};
#[allow(unused_imports)]
pub use skein::{Api, Skein, summary};

/// The `skein` binary cargo built for this test run.
pub fn skein_bin() -> &'static str {
    env!("CARGO_BIN_EXE_skein")
}

/// The workspace root.
pub fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .canonicalize()
        .expect("workspace root")
}

/// The flying tests measure setpoint gaps on a 2-core machine: one swarm at a time within
/// a test binary (hold the guard for the whole test).
pub fn one_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());
    ONE_AT_A_TIME
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}
