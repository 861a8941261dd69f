//! `skein bench swarm`: setpoint timing and CPU of a large swarm against the simulator
//! in its own process (see the module docs of [`super`] and [`swarm`]).

use crate::SwarmBenchArgs;
use crate::procfs::*;
use crate::round;
use crate::sim_process::*;
use crate::stack::*;
use serde_json::{Value, json};
use skein_swarm::{Swarm, SwarmServices};
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// A task on this process's runtime ticking at the setpoint period for `window`; returns
/// its tick intervals, ms. Its lateness is the runtime's own scheduling latency (timer
/// and worker availability), to tell it apart from the link's.
async fn probe(period: Duration, window: Duration) -> Vec<f64> {
    let mut ticker = tokio::time::interval(period);
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let end = Instant::now() + window;
    let mut last: Option<Instant> = None;
    let mut intervals =
        Vec::with_capacity((window.as_secs_f64() / period.as_secs_f64()) as usize + 1);
    while Instant::now() < end {
        ticker.tick().await;
        let now = Instant::now();
        if let Some(l) = last {
            intervals.push(now.duration_since(l).as_secs_f64() * 1e3);
        }
        last = Some(now);
    }
    intervals
}

fn probe_report(mut intervals: Vec<f64>, late_threshold_ms: f64) -> Value {
    if intervals.is_empty() {
        return Value::Null;
    }
    intervals.sort_by(f64::total_cmp);
    let q = |p: f64| {
        round(
            intervals[((intervals.len() - 1) as f64 * p).round() as usize],
            3,
        )
    };
    let late = intervals.iter().filter(|x| **x > late_threshold_ms).count();
    json!({
        "intervals": intervals.len(),
        "late_fraction": late as f64 / intervals.len() as f64,
        "p50_ms": q(0.5),
        "p99_ms": q(0.99),
        "max_ms": q(1.0),
    })
}

/// `a / b` to three decimals; `null` when either is missing or `b` is not positive.
fn ratio(a: Option<f64>, b: Option<f64>) -> Value {
    match (a, b) {
        (Some(a), Some(b)) if b > 0.0 => json!(round(a / b, 3)),
        _ => Value::Null,
    }
}

/// `skein bench swarm` (see module docs); returns the report.
pub async fn swarm(args: SwarmBenchArgs) -> Result<Value, String> {
    let n = args.vehicles;
    if n == 0 {
        return Err("--vehicles must be at least 1".into());
    }
    if !(args.rate_hz.is_finite() && args.rate_hz > 2.0) {
        return Err(format!(
            "--rate-hz {}: PX4 needs more than 2 Hz",
            args.rate_hz
        ));
    }
    if !(args.seconds.is_finite() && args.seconds > 0.0) {
        return Err(format!("--seconds {} must be positive", args.seconds));
    }
    let started = Instant::now();
    let setup_timeout =
        Duration::from_secs_f64(args.setup_timeout_s.unwrap_or(60.0 + 0.1 * n as f64));
    let (swarm, base) =
        start_swarm(&args, bench_config(&args), SwarmServices::default(), None).await?;
    eprintln!(
        "bench: skein listening on udp 127.0.0.1:{base}..{}",
        usize::from(base) + n.div_ceil(args.vehicles_per_port) - 1
    );
    let mut sim = match SimProcess::start(&args, base).await {
        Ok(s) => s,
        Err(e) => {
            swarm.stop().await;
            return Err(e);
        }
    };
    let result = measure(&swarm, &mut sim, &args, started + setup_timeout).await;
    sim.stop().await;
    swarm.stop().await;
    let mut report = result?;
    report["setup_s"] = json!(round(report["setup_s"].as_f64().unwrap_or(0.0), 1));
    if let Some(name) = args.peer.as_deref() {
        let peer = crate::peer::fly_peer(&args, name).await?;
        let ours = report["cpu_ms_per_vehicle_second"].as_f64();
        let theirs = peer["cpu_ms_per_vehicle_second"].as_f64();
        report["cpu_ratio_to_peer"] = ratio(ours, theirs);
        // The setpoint thread is mostly the kernel sending the datagrams the baseline
        // sends too: the part of the ratio no change to the rest of skein can remove.
        let setpoints = report["coordinator_threads_cpu_s"]["skein-setpoints"].as_f64();
        report["setpoint_thread_ratio_to_peer"] = ratio(setpoints, peer["cpu_s"].as_f64());
        report["peer"] = peer;
    }
    Ok(report)
}

/// What is read at each end of the measurement window.
struct Readings {
    /// Setpoints skein sent.
    sent: u64,
    /// skein's send errors.
    errors: u64,
    /// skein's CPU seconds.
    cpu: Option<f64>,
    /// skein's CPU seconds per thread name.
    threads: BTreeMap<String, f64>,
    /// The simulator process's CPU seconds.
    sim_cpu: Option<f64>,
    /// The host's busy CPU seconds.
    host: Option<f64>,
}

impl Readings {
    async fn take(swarm: &Swarm, sim: &SimProcess) -> Result<Readings, String> {
        Ok(Readings {
            sent: skein_setpoints_sent(swarm).await?,
            errors: skein_send_errors(swarm),
            cpu: cpu_seconds(None),
            threads: thread_cpu_seconds(None),
            sim_cpu: sim.pid.and_then(|p| cpu_seconds(Some(p))),
            host: host_busy_seconds(),
        })
    }
}

/// CPU the rest of the host used between `r0` and `r1`: other work competing for the
/// cores makes the figures of this run unrepresentative.
fn host_other_cpu_s(r0: &Readings, r1: &Readings) -> Value {
    match (r0.host, r1.host, r0.cpu, r1.cpu, r0.sim_cpu, r1.sim_cpu) {
        (Some(h0), Some(h1), Some(c0), Some(c1), Some(s0), Some(s1)) => {
            json!(round(((h1 - h0) - (c1 - c0) - (s1 - s0)).max(0.0), 2))
        }
        _ => Value::Null,
    }
}

async fn measure(
    swarm: &Swarm,
    sim: &mut SimProcess,
    args: &SwarmBenchArgs,
    deadline: Instant,
) -> Result<Value, String> {
    let n = args.vehicles;
    let setup_start = Instant::now();
    let hovering = take_off_all(swarm, args, deadline).await?;
    let setup_s = setup_start.elapsed().as_secs_f64();
    eprintln!(
        "bench: {hovering}/{n} hovering after {setup_s:.1} s; measuring for {} s",
        args.seconds
    );

    // The window.
    let r0 = Readings::take(swarm, sim).await?;
    sim.ask("reset").await?;
    let t0 = Instant::now();
    let probe = tokio::spawn(probe(
        Duration::from_secs_f64(1.0 / args.rate_hz),
        Duration::from_secs_f64(args.seconds),
    ));
    tokio::time::sleep(Duration::from_secs_f64(args.seconds)).await;
    let summary = sim.ask("summary").await?;
    let probe = probe.await.unwrap_or_default();
    let window_s = t0.elapsed().as_secs_f64();
    let r1 = Readings::take(swarm, sim).await?;
    let other = host_other_cpu_s(&r0, &r1);
    let (cpu0, cpu1) = (r0.cpu, r1.cpu);
    let (sent0, sent1) = (r0.sent, r1.sent);
    let (errors0, errors1) = (r0.errors, r1.errors);
    let (sim_cpu0, sim_cpu1) = (r0.sim_cpu, r1.sim_cpu);
    let (threads0, threads1) = (r0.threads, r1.threads);

    let period_ms = 1e3 / args.rate_hz;
    let late_threshold_ms = 1.25 * period_ms;
    let intervals = u64_at(&summary["setpoint_intervals"], "count");
    let late = late_intervals(&summary["setpoint_interval_buckets"], late_threshold_ms);
    let late_fraction = if intervals == 0 {
        1.0
    } else {
        late as f64 / intervals as f64
    };
    let setpoints_received = u64_at(&summary, "setpoints_received");
    let setpoints_sent = sent1.saturating_sub(sent0);
    let in_offboard = summary["modes"]["OFFBOARD"].as_u64().unwrap_or(0);
    let cpu = |a: Option<f64>, b: Option<f64>| match (a, b) {
        (Some(a), Some(b)) => json!(round(b - a, 2)),
        _ => Value::Null,
    };
    let iv = &summary["setpoint_intervals"];
    Ok(json!({
        "vehicles": n,
        "vehicles_per_port": args.vehicles_per_port,
        "rate_hz": args.rate_hz,
        "seconds": round(window_s, 2),
        "setpoints_sent": setpoints_sent,
        "setpoints_received": setpoints_received,
        "late_fraction": late_fraction,
        "late_threshold_ms": late_threshold_ms,
        "intervals": intervals,
        "late_intervals": late,
        "interval_ms": {
            "p50": f64_at(iv, &["p50_ms"]),
            "p99": f64_at(iv, &["p99_ms"]),
            "p999": f64_at(iv, &["p999_ms"]),
            "max": f64_at(iv, &["max_ms"]),
            "mean": round(f64_at(iv, &["mean_ms"]), 3),
        },
        "coordinator_cpu_s": cpu(cpu0, cpu1),
        "coordinator_threads_cpu_s": threads1
            .iter()
            .map(|(name, s1)| {
                let used = s1 - threads0.get(name).copied().unwrap_or(0.0);
                (name.clone(), json!(round(used, 3)))
            })
            .collect::<serde_json::Map<_, _>>(),
        "cpu_ms_per_vehicle_second": match (cpu0, cpu1) {
            (Some(a), Some(b)) => json!(round((b - a) * 1e3 / (n as f64 * window_s), 3)),
            _ => Value::Null,
        },
        "coordinator_peak_rss_mb": peak_rss_mb().map(|m| round(m, 1)),
        "peak_rss_kib_per_vehicle": peak_rss_mb().map(|m| round(m * 1024.0 / n as f64, 1)),
        "sim_cpu_s": cpu(sim_cpu0, sim_cpu1),
        "offboard_loss_failsafes": u64_at(&summary, "offboard_loss_failsafes"),
        "all_offboard": in_offboard == n as u64,
        "in_offboard": in_offboard,
        "hovering_at_start": hovering,
        "skein_send_errors": errors1 - errors0,
        "sim_send_drops": u64_at(&summary, "send_drops"),
        "sim_datagrams_sent": u64_at(&summary, "datagrams_sent"),
        "sim_datagrams_received": u64_at(&summary, "datagrams_received"),
        "setup_s": setup_s,
        "runtime_probe": probe_report(probe, late_threshold_ms),
        "host_other_cpu_s": other,
    }))
}
