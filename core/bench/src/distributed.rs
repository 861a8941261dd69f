//! `skein bench dds --distributed`: the distributed roles against the single process.
//!
//! 1. `skein up --sim N --sim-model generic` (this binary, free ports): take off, a line
//!    behind a virtual leader, the leader north at 5 m/s; once it has cruised for 2 s,
//!    samples the formation's RMS slot error every 100 ms and the process's CPU over
//!    `--seconds`;
//! 2. the same flight with `skein coordinator` and N `skein agent --sim 1` (one generic
//!    vehicle each, sysids 1 to N) on DDS over loopback, a domain of its own: the same
//!    samples, each agent's CPU and the coordinator's, and the latency of every slot
//!    target from the coordinator's write to its arrival at a subscriber in this process
//!    (a RustDDS participant reading `/skein/swarm/target` as an agent does; its header
//!    stamp against the same host's clock);
//! 3. prints one JSON object: `vehicles`, `seconds`, `single_process` and `distributed`
//!    (`rms_slot_error_m` mean and max; CPU in cores, simulators included, per vehicle),
//!    `target_latency_ms` (`p50`, `p99`, `max`, `samples`), and
//!    `rms_difference_m` (distributed mean minus single-process mean).

use crate::dds::{DdsBenchArgs, percentile};
use crate::procfs::cpu_seconds;
use crate::up_process::UpProcess;
use serde_json::{Value, json};
use std::net::{IpAddr, Ipv4Addr};
use std::time::{Duration, Instant};

/// Takes `c`'s `n` vehicles off and flies them in a line north at 5 m/s; returns once the
/// reference has cruised for 2 s.
fn fly(c: &UpProcess, n: usize) -> Result<(), String> {
    c.wait_vehicles(
        n,
        "every vehicle with a home",
        Duration::from_secs(120),
        |v| v["home"].is_object(),
    )?;
    let r = c.call(
        "POST",
        "/api/v1/swarm/commands",
        Some(json!({"command": "takeoff", "altitude_m": 10.0})),
    )?;
    if r["refused"].as_array().is_some_and(|a| !a.is_empty()) {
        return Err(format!("takeoff refused: {r}"));
    }
    c.wait_vehicles(n, "every vehicle hovering", Duration::from_secs(120), |v| {
        v["state"] == "Hovering"
    })?;
    c.call(
        "PUT",
        "/api/v1/formation",
        Some(json!({"shape": "line", "spacing_m": 6.0, "leader": "virtual", "altitude_m": 12.0})),
    )?;
    wait(c, "the line formed", |f| {
        f["members"].as_array().is_some_and(|m| m.len() == n)
            && f["rms_error_m"].as_f64().is_some_and(|e| e < 0.3)
    })?;
    c.call(
        "POST",
        "/api/v1/formation/leader/goto",
        Some(json!({"north_m": 400.0, "east_m": 0.0, "speed_m_s": 5.0})),
    )?;
    wait(c, "the line cruising at 5 m/s", |f| {
        let v = &f["reference"]["velocity"];
        v["north_m"].as_f64().unwrap_or(0.0) > 4.99
    })?;
    std::thread::sleep(Duration::from_secs(2));
    Ok(())
}

/// Polls `GET /api/v1/formation` until `ok` (60 s at most).
fn wait(c: &UpProcess, what: &str, ok: impl Fn(&Value) -> bool) -> Result<(), String> {
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        if ok(&c.get("/api/v1/formation")?) {
            return Ok(());
        }
        if Instant::now() > deadline {
            return Err(format!("timed out waiting for {what}"));
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// The RMS slot error every 100 ms for `seconds`, and the CPU seconds of `pids` per
/// second meanwhile, each.
fn sample(c: &UpProcess, seconds: f64, pids: &[u32]) -> Result<(Vec<f64>, Vec<f64>), String> {
    let cpu = |pid: u32| cpu_seconds(Some(pid)).ok_or("no /proc CPU figures");
    let c0: Vec<f64> = pids.iter().map(|p| cpu(*p)).collect::<Result<_, _>>()?;
    let t0 = Instant::now();
    let mut rms = Vec::new();
    while t0.elapsed().as_secs_f64() < seconds {
        let f = c.get("/api/v1/formation")?;
        if let Some(e) = f["rms_error_m"].as_f64() {
            rms.push(e);
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    let dt = t0.elapsed().as_secs_f64();
    let c1: Vec<f64> = pids.iter().map(|p| cpu(*p)).collect::<Result<_, _>>()?;
    let cores = c0.iter().zip(&c1).map(|(a, b)| (b - a) / dt).collect();
    Ok((rms, cores))
}

fn stats(rms: &[f64]) -> Value {
    json!({
        "mean": rms.iter().sum::<f64>() / rms.len().max(1) as f64,
        "max": rms.iter().copied().fold(0.0, f64::max),
        "samples": rms.len(),
    })
}

/// Runs the benchmark (see the module docs).
///
/// # Errors
/// A process that does not start, a flight that does not happen, the probe's participant,
/// or no `/proc`.
pub async fn distributed(args: &DdsBenchArgs) -> Result<Value, String> {
    let n = args.vehicles;
    if n < 2 {
        return Err("--distributed flies a line: --vehicles 2 or more".into());
    }
    eprintln!("bench dds --distributed: {n} vehicles in one skein up");
    let (single_rms, single_cpu) = {
        let nn = n.to_string();
        let up = UpProcess::start(&[
            "--sim",
            &nn,
            "--sim-model",
            "generic",
            "--sim-base-port",
            "0",
        ])?;
        tokio::task::block_in_place(|| {
            fly(&up, n)?;
            sample(&up, args.seconds, &[up.pid()])
        })?
    };
    let domain = args
        .domain_id
        .unwrap_or(150 + (std::process::id() % 50) as u16)
        .to_string();
    eprintln!("bench dds --distributed: a coordinator and {n} agents on domain {domain}");
    let coordinator = UpProcess::start_role(
        &["coordinator", "--http", "127.0.0.1:0"],
        &[
            "--id",
            "bench",
            "--domain-id",
            &domain,
            "--dds-network",
            "127.0.0.1",
        ],
    )?;
    let agents = (1..=n)
        .map(|k| {
            let first = k.to_string();
            UpProcess::start_role(
                &["agent"],
                &[
                    "--sim",
                    "1",
                    "--first-sysid",
                    &first,
                    "--sim-model",
                    "generic",
                    "--sim-base-port",
                    "0",
                    "--domain-id",
                    &domain,
                    "--dds-network",
                    "127.0.0.1",
                ],
            )
        })
        .collect::<Result<Vec<_>, _>>()?;
    let probe = skein_dds::probe::PoseProbe::start(
        domain.parse().map_err(|_| "domain")?,
        &[IpAddr::V4(Ipv4Addr::LOCALHOST)],
        &[],
        true,
    )
    .map_err(|e| e.to_string())?;
    let mut pids: Vec<u32> = agents.iter().map(UpProcess::pid).collect();
    pids.push(coordinator.pid());
    let (dist_rms, cpu) = tokio::task::block_in_place(|| {
        fly(&coordinator, n)?;
        probe.take();
        sample(&coordinator, args.seconds, &pids)
    })?;
    let mut latencies: Vec<f64> = probe.take().iter().map(|(_, l)| l * 1e3).collect();
    latencies.sort_by(f64::total_cmp);
    let agents_cpu: f64 = cpu[..n].iter().sum();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    Ok(json!({
        "bench": "dds-distributed",
        "vehicles": n,
        "seconds": args.seconds,
        "speed_m_s": 5.0,
        "single_process": {
            "rms_slot_error_m": stats(&single_rms),
            "cpu_cores": single_cpu[0],
            "cpu_cores_per_vehicle": single_cpu[0] / n as f64,
        },
        "distributed": {
            "rms_slot_error_m": stats(&dist_rms),
            "agent_cpu_cores_per_vehicle": agents_cpu / n as f64,
            "coordinator_cpu_cores": cpu[n],
        },
        "target_latency_ms": {
            "p50": percentile(&latencies, 0.5),
            "p99": percentile(&latencies, 0.99),
            "max": latencies.last(),
            "samples": latencies.len(),
        },
        "rms_difference_m": mean(&dist_rms) - mean(&single_rms),
    }))
}
