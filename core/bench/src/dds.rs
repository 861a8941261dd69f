//! `skein bench dds`: what the ROS 2 topics cost and how fast they arrive.
//!
//! 1. starts `skein up --sim N --sim-model generic` (this binary, free ports) **without**
//!    DDS, waits until every vehicle has a position, and measures the process's CPU over
//!    `--seconds`;
//! 2. starts it again **with** `--dds --dds-network 127.0.0.1` on a domain of its own,
//!    and subscribes to every vehicle's `/skein/<vehicle>/pose` from this process (a
//!    RustDDS participant of its own, [`skein_dds::probe::PoseProbe`]); measures the CPU
//!    again over the same time, and every pose's latency (its arrival here minus its
//!    header stamp, set just before the write; same host clock);
//! 3. prints one JSON object: `vehicles`, `seconds`, `publish_rate_hz`,
//!    `cpu_cores_without_dds` and `cpu_cores_with_dds` (CPU seconds per second of the
//!    `skein up` process, simulator included), `dds_cpu_per_vehicle` (their difference
//!    over N, in cores), `poses_received` and `poses_expected` (N × rate × seconds),
//!    `pose_latency_ms` (`p50`, `p99`, `max`).
//!
//! The two runs are separate processes a few seconds apart: rerun on a quiet host when
//! the CPU figures look noisy.

use crate::procfs::cpu_seconds;
use crate::up_process::UpProcess;
use serde_json::{Value, json};
use std::net::{IpAddr, Ipv4Addr};
use std::time::Duration;

/// Arguments of `skein bench dds`.
#[derive(clap::Args, Debug)]
pub struct DdsBenchArgs {
    /// Simulated vehicles.
    #[arg(long, default_value_t = 8)]
    pub vehicles: usize,
    /// Seconds measured in each run.
    #[arg(long, default_value_t = 20.0)]
    pub seconds: f64,
    /// DDS domain of the run with DDS (default: one derived from this process id, 150–199);
    /// with `--distributed`, the secured flight takes the next one (the previous for 232).
    #[arg(long, value_parser = skein_dds::parse_domain_id)]
    pub domain_id: Option<u16>,
    /// Instead: the distributed roles, `--vehicles` agents of one vehicle each and a
    /// coordinator, against `skein up` (see `core/bench/src/distributed.rs`).
    #[arg(long)]
    pub distributed: bool,
}

/// Publish rate of the DDS link in the run (its default).
const PUBLISH_RATE_HZ: f64 = 10.0;

fn start(args: &DdsBenchArgs, dds: Option<u16>) -> Result<UpProcess, String> {
    let n = args.vehicles.to_string();
    let domain = dds.map(|d| d.to_string());
    let mut a = vec![
        "--sim",
        &n,
        "--sim-model",
        "generic",
        "--sim-base-port",
        "0",
    ];
    if let Some(d) = &domain {
        a.extend(["--dds", "--domain-id", d, "--dds-network", "127.0.0.1"]);
    }
    let up = UpProcess::start(&a)?;
    up.wait_vehicles(
        args.vehicles,
        "every vehicle with a position",
        Duration::from_secs(60),
        |v| v["position"].is_object(),
    )?;
    // Let start-up work (discovery, plugin scans) pass before measuring.
    std::thread::sleep(Duration::from_secs(2));
    Ok(up)
}

/// CPU cores used by `up` over `seconds` (CPU seconds per second).
pub(super) fn cores(up: &UpProcess, seconds: f64) -> Result<f64, String> {
    let c0 = cpu_seconds(Some(up.pid())).ok_or("no /proc CPU figures")?;
    std::thread::sleep(Duration::from_secs_f64(seconds));
    let c1 = cpu_seconds(Some(up.pid())).ok_or("no /proc CPU figures")?;
    Ok((c1 - c0) / seconds)
}

pub(super) fn percentile(sorted: &[f64], p: f64) -> Option<f64> {
    let i = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted.get(i).copied()
}

/// Runs the benchmark (see the module docs).
///
/// # Errors
/// A `skein up` run that does not start or whose vehicles do not appear, the probe's
/// participant, or no `/proc`.
pub async fn dds(args: DdsBenchArgs) -> Result<Value, String> {
    if args.vehicles == 0 || args.seconds.is_nan() || args.seconds <= 0.0 {
        return Err("--vehicles and --seconds must be positive".into());
    }
    if args.distributed {
        return super::distributed::distributed(&args).await;
    }
    let domain = args
        .domain_id
        .unwrap_or(150 + (std::process::id() % 50) as u16);
    eprintln!("bench dds: {} vehicles without DDS", args.vehicles);
    let without = {
        let up = start(&args, None)?;
        tokio::task::block_in_place(|| cores(&up, args.seconds))?
    };
    eprintln!(
        "bench dds: {} vehicles with DDS on domain {domain}",
        args.vehicles
    );
    let up = start(&args, Some(domain))?;
    let ids: Vec<String> = (1..=args.vehicles).map(|i| format!("uav-{i}")).collect();
    let probe = skein_dds::probe::PoseProbe::start(
        domain,
        &[IpAddr::V4(Ipv4Addr::LOCALHOST)],
        &ids,
        false,
        None,
    )
    .map_err(|e| e.to_string())?;
    // Discovery first: measure from the first arrival of every vehicle's pose on.
    let deadline = std::time::Instant::now() + Duration::from_secs(30);
    let mut heard = std::collections::BTreeSet::new();
    while heard.len() < ids.len() {
        if std::time::Instant::now() > deadline {
            return Err(format!(
                "poses of only {} vehicles heard in 30 s",
                heard.len()
            ));
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
        heard.extend(probe.take().into_iter().map(|(id, _)| id));
    }
    let with = tokio::task::block_in_place(|| cores(&up, args.seconds))?;
    let arrivals = probe.take();
    let mut latencies: Vec<f64> = arrivals.iter().map(|(_, l)| l * 1e3).collect();
    latencies.sort_by(f64::total_cmp);
    Ok(json!({
        "vehicles": args.vehicles,
        "seconds": args.seconds,
        "publish_rate_hz": PUBLISH_RATE_HZ,
        "cpu_cores_without_dds": without,
        "cpu_cores_with_dds": with,
        "dds_cpu_per_vehicle": (with - without) / args.vehicles as f64,
        "poses_received": latencies.len(),
        "poses_expected": (args.vehicles as f64 * PUBLISH_RATE_HZ * args.seconds).round(),
        "pose_latency_ms": {
            "p50": percentile(&latencies, 0.5),
            "p99": percentile(&latencies, 0.99),
            "max": latencies.last(),
        },
    }))
}
