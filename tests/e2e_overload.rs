//! Overload: skein starved of CPU on purpose degrades and recovers; it never turns the
//! shortage into an outage.
//!
//! The simulator runs in its own process (it is the independent judge of the setpoint
//! stream: PX4's offboard-loss failsafe and the gaps it sees). skein is pinned to one CPU
//! shared with busy loops, so that its ordinary threads get half the CPU they were using
//! to fly the formation. While starved it must shed optional work (the health
//! endpoint says so), kill or restart nothing, lose no vehicle and keep the setpoint
//! stream going; once the hogs are gone, every vehicle is back on its slot with zero
//! restarts.

mod support;

use serde_json::{Value, json};
use std::time::{Duration, Instant};
use support::cpu::{Starvation, cpu_seconds, pin, renice};
use support::{
    Process, Skein, assert_no_failsafe_and_no_gap_in, eventually, free_udp_range, one_at_a_time,
    sim_stats, steady_for,
};

/// Vehicles.
const VEHICLES: u16 = 24;
/// While starved skein gets this fraction of the CPU it used in formation flight.
const CPU_SHARE_OF_NEED: f64 = 0.5;
/// How long its need is measured.
const MEASURED: Duration = Duration::from_secs(5);
/// How long skein is starved.
const STARVED: Duration = Duration::from_secs(20);

fn health(skein: &Skein) -> Value {
    let (status, h) = skein.get("/api/v1/health");
    assert_eq!(status, 200, "{h}");
    h
}

/// Every supervised actor's restarts and failures, as (path, restarts, failures).
fn restarts(skein: &Skein) -> Vec<(String, u64, u64)> {
    fn walk(node: &Value, out: &mut Vec<(String, u64, u64)>) {
        out.push((
            node["path"].as_str().unwrap_or("?").to_string(),
            node["restarts"].as_u64().unwrap_or(0),
            node["failures"].as_u64().unwrap_or(0),
        ));
        for c in node["children"].as_array().into_iter().flatten() {
            walk(c, out);
        }
    }
    let (status, tree) = skein.get("/api/v1/supervision");
    assert_eq!(status, 200, "{tree}");
    let mut out = Vec::new();
    walk(&tree, &mut out);
    out
}

#[test]
fn starved_of_cpu_skein_sheds_work_kills_nothing_and_recovers_every_slot() {
    let _serial = one_at_a_time();
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    assert!(cpus >= 2, "the test needs a second CPU for the simulator");
    // skein first, on CPU 0 alone: it binds its vehicles' ports before the simulator
    // takes ephemeral ones.
    let base = free_udp_range(VEHICLES);
    let dir = std::env::temp_dir().join(format!("skein-overload-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cfg = dir.join("skein.toml");
    let vehicles: String = (0..VEHICLES)
        .map(|i| {
            format!(
                "[[vehicles]]\nconnection = \"udpin:127.0.0.1:{}\"\n",
                base + i
            )
        })
        .collect();
    // PX4's own telemetry rates (about 400 messages a second a vehicle): a companion
    // computer that left them alone.
    std::fs::write(&cfg, vehicles).unwrap();
    let skein = Skein::up(&["--config", cfg.to_str().unwrap()]);
    pin(skein.process.pid(), "0");
    // The simulator on the other CPUs, with its stats socket.
    let mut sim = Process::start(&[
        "sim",
        "--vehicles",
        &VEHICLES.to_string(),
        "--per-vehicle-targets",
        "--target-base-port",
        &base.to_string(),
        "--listen-base-port",
        "0",
        "--spacing-m",
        "6",
        "--stats",
        "127.0.0.1:0",
    ]);
    let stats = sim
        .wait_line("stats ", Duration::from_secs(30))
        .trim_start_matches("stats ")
        .trim()
        .to_string();
    pin(sim.pid(), &format!("1-{}", cpus - 1));
    // The judge must not be the one running late (best effort: needs privilege).
    renice(sim.pid(), -5);
    let n = usize::from(VEHICLES);
    skein.take_off(n, 10.0);
    let (status, body) = skein.put(
        "/api/v1/formation",
        json!({"shape": "grid", "spacing_m": 7.0, "leader": "virtual", "altitude_m": 10.0}),
    );
    assert_eq!(status, 200, "{body}");
    skein.settled(n, 0.5, Duration::from_secs(90));
    // The setpoint thread's scheduling: real-time where the process may have it (root
    // here, as in CI), which keeps it ahead of the busy loops below.
    let priority = health(&skein)["load"]["setpoint_priority"].clone();
    let root = std::fs::read_to_string("/proc/self/status").is_ok_and(|s| {
        s.lines()
            .any(|l| l.starts_with("Uid:") && l.split_whitespace().nth(1) == Some("0"))
    });
    if root {
        assert_eq!(
            priority,
            json!({"kind": "realtime", "priority": 1}),
            "{priority}"
        );
    } else {
        assert!(priority["kind"].is_string(), "{priority}");
    }
    let before = restarts(&skein);
    assert!(
        before.iter().all(|(_, r, f)| *r == 0 && *f == 0),
        "{before:?}"
    );
    // What it needs flying the formation, then half of that.
    let pid = skein.process.pid();
    let (t0, c0) = (Instant::now(), cpu_seconds(pid));
    steady_for(
        "the formation settled",
        MEASURED,
        Duration::from_secs(60),
        || {
            let f = skein.formation();
            let members = f["members"].as_array().cloned().unwrap_or_default();
            let ok = members.len() == n
                && members
                    .iter()
                    .all(|m| m["error_m"].as_f64().unwrap_or(99.0) < 0.5);
            if ok { Ok(()) } else { Err(f.to_string()) }
        },
    );
    let need = (cpu_seconds(pid) - c0) / t0.elapsed().as_secs_f64();
    sim_stats(&stats, "reset");

    // Starve it.
    // Its two runtime workers do the work that may run late.
    let starvation = Starvation::starve(pid, need * CPU_SHARE_OF_NEED, 2);
    let started = Instant::now();
    let mut shed_seen = false;
    let mut worst_lag_ms = 0.0f64;
    while started.elapsed() < STARVED {
        let h = health(&skein);
        shed_seen |= h["load"]["level"] == "shedding";
        worst_lag_ms = worst_lag_ms.max(h["load"]["lag_ms"].as_f64().unwrap_or(0.0));
        // The vehicles are slow to report, not gone: none is Lost or fails safe.
        for v in skein.vehicles() {
            assert!(
                v["state"] == "InFormation",
                "{} left the formation while starved: {v}",
                v["id"]
            );
        }
        std::thread::sleep(Duration::from_millis(500));
    }
    let starved = health(&skein);
    let how = starvation.describe();
    drop(starvation);
    assert!(
        shed_seen,
        "skein never shed work: it was not starved by {how} (needing {need:.3} of a CPU, \
         worst lag {worst_lag_ms} ms): {starved}"
    );
    let load = &starved["load"];
    assert!(
        load["shed"]["snapshots"].as_u64().unwrap_or(0) > 0,
        "nothing shed: {load}"
    );

    // Recovered: back to normal, every member on its slot, nothing restarted.
    eventually("the load back to normal", Duration::from_secs(30), || {
        let h = health(&skein);
        if h["load"]["level"] == "normal" {
            Ok(())
        } else {
            Err(h.to_string())
        }
    });
    skein.settled(n, 0.5, Duration::from_secs(60));
    let after = restarts(&skein);
    let restarted: Vec<_> = after.iter().filter(|(_, r, f)| *r > 0 || *f > 0).collect();
    assert!(
        restarted.is_empty(),
        "actors killed or restarted while merely slow: {restarted:?} (load {load})"
    );
    let (_, metrics) = skein.get("/metrics");
    let metrics = metrics.as_str().unwrap_or_default().to_string();
    assert!(
        !metrics
            .lines()
            .any(|l| l.starts_with("skein_actor_hangs_total") && !l.ends_with(" 0")),
        "{metrics}"
    );
    assert!(
        metrics.contains("skein_shed{work=\"snapshots\"}"),
        "{metrics}"
    );
    let skein_gap = metrics
        .lines()
        .filter(|l| l.starts_with("skein_setpoint_max_gap_ms{"))
        .filter_map(|l| l.rsplit(' ').next()?.parse::<f64>().ok())
        .fold(0.0, f64::max);
    eprintln!(
        "needing {need:.3} of a CPU, starved by {how}; skein {:.2} CPU-s, simulator {:.2} \
         CPU-s; largest pause of a stream as sent {skein_gap} ms",
        cpu_seconds(pid),
        cpu_seconds(sim.pid())
    );
    // The simulator, the independent judge: no failsafe, no gap of 100 ms.
    let worst_gap = assert_no_failsafe_and_no_gap_in(
        &stats,
        &format!(
            "skein's largest pause as sent {skein_gap} ms; starved by {how}, needing \
             {need:.3} of a CPU, worst lag {worst_lag_ms} ms; load {load}"
        ),
    );
    eprintln!(
        "needing {need:.3} of a CPU, starved {STARVED:?} by {how}: worst lag {worst_lag_ms} \
         ms, worst setpoint gap {worst_gap} ms, load {load}"
    );
}
