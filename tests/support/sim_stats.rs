//! The simulator's stats socket: its counters and ground truth, what the tests check
//! skein against (never skein's own metrics).

use serde_json::Value;
use std::io::{BufRead, BufReader};
use std::time::Duration;

/// One command to a simulator stats socket (`stats`, `reset`, …) → its JSON answer.
pub fn sim_stats(addr: &str, command: &str) -> Value {
    use std::io::Write;
    let mut s = std::net::TcpStream::connect(addr).expect("connect to the stats socket");
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    s.write_all(format!("{command}\n").as_bytes()).unwrap();
    let mut line = String::new();
    BufReader::new(s)
        .read_line(&mut line)
        .expect("stats answer");
    serde_json::from_str(&line).expect("stats JSON")
}

/// As [`sim_stats`], or `None` when the socket does not answer (its process has ended).
pub fn try_sim_stats(addr: &str, command: &str) -> Option<Value> {
    use std::io::Write;
    let mut s = std::net::TcpStream::connect(addr).ok()?;
    s.set_read_timeout(Some(Duration::from_secs(10))).ok()?;
    s.write_all(format!("{command}\n").as_bytes()).ok()?;
    let mut line = String::new();
    BufReader::new(s).read_line(&mut line).ok()?;
    serde_json::from_str(&line).ok()
}

/// Asserts that no simulated vehicle took the offboard-loss failsafe and that no setpoint
/// gap in OFFBOARD reached 100 ms since the simulator's last reset (stats socket at
/// `stats_addr`); returns the worst gap, ms.
pub fn assert_no_failsafe_and_no_gap(stats_addr: &str) -> f64 {
    assert_no_failsafe_and_no_gap_in(stats_addr, "")
}

/// [`assert_no_failsafe_and_no_gap`], with `context` (what the test knows of skein's side)
/// in the failure message.
pub fn assert_no_failsafe_and_no_gap_in(stats_addr: &str, context: &str) -> f64 {
    let stats = sim_stats(stats_addr, "stats");
    let mut worst = 0.0f64;
    for v in stats["vehicles"].as_array().unwrap() {
        let sysid = &v["sysid"];
        assert_eq!(
            v["offboard_loss_failsafes"], 0,
            "sysid {sysid} failed safe ({context}): {v}"
        );
        let gap = v["setpoint_max_gap_offboard_ms"].as_f64().unwrap();
        assert!(
            gap < 100.0,
            "sysid {sysid}: setpoint gap {gap} ms ({context}): {v}"
        );
        worst = worst.max(gap);
    }
    worst
}

/// Ground-truth horizontal+vertical distances between every pair of simulated vehicles,
/// from their geodetic positions (flat earth over a few hundred metres).
pub fn truth_min_separation(stats_addr: &str) -> f64 {
    truth_min_separation_across(&[stats_addr])
}

/// [`truth_min_separation`] over the airborne vehicles of several simulators (one per
/// agent of a distributed swarm): their stats sockets `stats_addrs`.
pub fn truth_min_separation_across(stats_addrs: &[&str]) -> f64 {
    let mut pos: Vec<(f64, f64, f64)> = Vec::new();
    for addr in stats_addrs {
        let s = sim_stats(addr, "stats");
        pos.extend(
            s["vehicles"]
                .as_array()
                .unwrap()
                .iter()
                .filter(|v| v["killed"] != true && v["truth"]["landed_state"] != "OnGround")
                .map(|v| {
                    let p = &v["truth"]["position"];
                    (
                        p["lat_deg"].as_f64().unwrap(),
                        p["lon_deg"].as_f64().unwrap(),
                        p["alt_amsl_m"].as_f64().unwrap(),
                    )
                }),
        );
    }
    let mut best = f64::INFINITY;
    for (i, a) in pos.iter().enumerate() {
        for b in &pos[i + 1..] {
            let n = (b.0 - a.0).to_radians() * 6_371_000.0;
            let e = (b.1 - a.1).to_radians() * 6_371_000.0 * a.0.to_radians().cos();
            let d = (n * n + e * e + (b.2 - a.2).powi(2)).sqrt();
            best = best.min(d);
        }
    }
    best
}
