//! skein's own stack in the benchmark's process (`skein bench swarm`, `skein bench
//! restart`): the Coordinator, Vehicle and Px4Link actors on one `udpin` endpoint per
//! vehicle, driven through the coordinator's messages, and the figures read back from it.

use crate::SwarmBenchArgs;
use serde_json::Value;
use skein_link::{Identity, LinkSetup, TelemetryProfile};
use skein_model::fsm::VehicleState;
use skein_model::vehicle::VehicleSnapshot;
use skein_swarm::{
    AdminMsg, Command, CommandMsg, EndpointSpec, FleetMsg, Swarm, SwarmConfig, SwarmServices,
    VehicleSpec,
};
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::time::{Duration, Instant};

pub(crate) const LOCALHOST: IpAddr = IpAddr::V4(Ipv4Addr::LOCALHOST);
/// Longest wait for the coordinator to answer (a swarm command visits every vehicle).
pub(crate) const COORDINATOR_TIMEOUT: Duration = Duration::from_secs(120);

/// A pseudo-random first port for a block of `n` (from the clock and pid; no generator
/// needed), below Linux's ephemeral range (32768…) so the simulator's own ports never
/// collide with it.
pub(crate) fn candidate_base(n: usize, attempt: u32) -> Option<u16> {
    let low = 20_000usize;
    let high = 32_768usize.checked_sub(n)?;
    if high <= low {
        return None;
    }
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.subsec_nanos());
    let mix =
        u64::from(nanos) ^ (u64::from(std::process::id()) << 16) ^ (u64::from(attempt) * 7919);
    u16::try_from(low + (mix as usize % (high - low))).ok()
}

/// The swarm configuration of the benches: setpoints at `rate_hz`, the `swarm` telemetry
/// profile, takeoff to `args.altitude_m`.
pub(crate) fn bench_config(args: &SwarmBenchArgs) -> SwarmConfig {
    let mut config = SwarmConfig {
        stream_rate_hz: args.rate_hz,
        link_setup: LinkSetup {
            telemetry: TelemetryProfile::Swarm,
            params: Vec::new(),
            remote_id: None,
            operator_gnss: None,
            metadata_cache_dir: None,
            log_bandwidth: Default::default(),
        },
        ..SwarmConfig::default()
    };
    config.default_takeoff_altitude_m = args.altitude_m;
    config
}

/// Starts skein's stack with one `udpin` endpoint per `args.vehicles_per_port` vehicles
/// on a free block of consecutive ports, every vehicle of `model` (`None`: generic);
/// returns the swarm and the first port.
pub(crate) async fn start_swarm(
    args: &SwarmBenchArgs,
    config: SwarmConfig,
    services: SwarmServices,
    model: Option<&str>,
) -> Result<(Swarm, u16), String> {
    let n = args.vehicles;
    let per_port = args.vehicles_per_port;
    if !(1..=skein_sim::MAX_SHARED_SYSIDS).contains(&per_port) {
        return Err(format!(
            "--vehicles-per-port {per_port}: 1 to {} (their sysids must differ)",
            skein_sim::MAX_SHARED_SYSIDS
        ));
    }
    let ports = n.div_ceil(per_port);
    let mut last_error = String::new();
    for attempt in 0..20 {
        let base = candidate_base(ports, attempt)
            .ok_or_else(|| format!("{n} vehicles need more local UDP ports than available"))?;
        let endpoints = (0..ports)
            .map(|p| EndpointSpec {
                connection: skein_link::ConnectionAddress::UdpIn(SocketAddr::new(
                    LOCALHOST,
                    base + p as u16,
                )),
                vehicles: (p * per_port..n.min((p + 1) * per_port))
                    .map(|i| VehicleSpec {
                        id: Some(format!("uav-{}", i + 1)),
                        sysid: Some(skein_sim::instance_sysid(i, n)),
                        model: model.map(str::to_string),
                        signing: None,
                    })
                    .collect(),
                // The simulator runs in its own process: nothing in-process to drive.
                simulated: false,
            })
            .collect();
        match Swarm::start(
            config.clone(),
            services.clone(),
            Identity::default(),
            endpoints,
        )
        .await
        {
            Ok(swarm) => return Ok((swarm, base)),
            Err(e) => last_error = e.to_string(), // a port of the block is taken: retry
        }
    }
    Err(format!("no free block of {n} UDP ports: {last_error}"))
}

pub(crate) async fn list_vehicles(swarm: &Swarm) -> Result<Vec<VehicleSnapshot>, String> {
    match swarm
        .coordinator
        .call(
            |r| FleetMsg::ListVehicles(r).into(),
            Some(COORDINATOR_TIMEOUT),
        )
        .await
    {
        Ok(ractor::rpc::CallResult::Success(v)) => Ok(v),
        Ok(_) => Err("the coordinator did not answer in time".into()),
        Err(e) => Err(format!("the coordinator is not running: {e}")),
    }
}

/// Sends `cmd` to every vehicle (`None`) or to the listed ones; returns the ids that
/// refused it.
pub(crate) async fn command(
    swarm: &Swarm,
    cmd: &Command,
    only: Option<&[String]>,
) -> Result<Vec<String>, String> {
    let Some(ids) = only else {
        let c = cmd.clone();
        return match swarm
            .coordinator
            .call(
                move |r| CommandMsg::SwarmCommand(c, r).into(),
                Some(COORDINATOR_TIMEOUT),
            )
            .await
        {
            Ok(ractor::rpc::CallResult::Success(o)) => {
                Ok(o.refused.into_iter().map(|r| r.id).collect())
            }
            Ok(_) => Err("the coordinator did not answer the swarm command in time".into()),
            Err(e) => Err(format!("the coordinator is not running: {e}")),
        };
    };
    let mut refused = Vec::new();
    for id in ids {
        let (c, i) = (cmd.clone(), id.clone());
        match swarm
            .coordinator
            .call(
                move |r| CommandMsg::VehicleCommand(i, c, r).into(),
                Some(COORDINATOR_TIMEOUT),
            )
            .await
        {
            Ok(ractor::rpc::CallResult::Success(Ok(_))) => {}
            Ok(_) => refused.push(id.clone()),
            Err(e) => return Err(format!("the coordinator is not running: {e}")),
        }
    }
    Ok(refused)
}

/// Waits until every vehicle has joined with a position, takes them all off and waits
/// until every one hovers (or the deadline passes). Returns how many hover.
pub(crate) async fn take_off_all(
    swarm: &Swarm,
    args: &SwarmBenchArgs,
    deadline: Instant,
) -> Result<usize, String> {
    let n = args.vehicles;
    let takeoff = Command::Takeoff(skein_model::command::Takeoff {
        altitude_m: Some(args.altitude_m),
    });
    let ready = |v: &VehicleSnapshot| {
        v.state == VehicleState::Landed && v.position.is_some() && v.link.connected
    };
    // Everyone joined, with a position.
    let mut last_report = Instant::now();
    loop {
        let vs = list_vehicles(swarm).await?;
        let n_ready = vs.iter().filter(|v| ready(v)).count();
        if n_ready == n {
            break;
        }
        if Instant::now() > deadline {
            return Err(format!(
                "only {n_ready} of {n} vehicles joined with a position in time ({} joined)",
                vs.len()
            ));
        }
        if last_report.elapsed() > Duration::from_secs(5) {
            eprintln!("bench: {n_ready}/{n} vehicles ready ({} joined)", vs.len());
            last_report = Instant::now();
        }
        tokio::time::sleep(Duration::from_millis(250)).await;
    }
    eprintln!(
        "bench: {n} vehicles ready; taking off to {} m",
        args.altitude_m
    );
    let mut retry = command(swarm, &takeoff, None).await?;
    loop {
        tokio::time::sleep(Duration::from_millis(500)).await;
        let vs = list_vehicles(swarm).await?;
        let hovering = vs
            .iter()
            .filter(|v| v.state == VehicleState::Hovering)
            .count();
        if hovering == n {
            return Ok(n);
        }
        if Instant::now() > deadline {
            eprintln!("bench: setup deadline: {hovering}/{n} hovering; measuring anyway");
            return Ok(hovering);
        }
        if last_report.elapsed() > Duration::from_secs(5) {
            eprintln!("bench: {hovering}/{n} hovering");
            last_report = Instant::now();
        }
        // Vehicles that refused, or fell back to the ground (a takeoff that failed), try
        // again.
        retry.extend(
            vs.iter()
                .filter(|v| ready(v) || v.state == VehicleState::Armed)
                .map(|v| v.id.clone()),
        );
        retry.sort();
        retry.dedup();
        if !retry.is_empty() {
            retry = command(swarm, &takeoff, Some(&retry)).await?;
        }
    }
}

/// Frames skein's endpoints could not send (socket full, no address yet).
pub(crate) fn skein_send_errors(swarm: &Swarm) -> u64 {
    swarm
        .endpoints
        .iter()
        .map(|ep| {
            let c = ep.send_counts();
            c.send_errors + c.no_route
        })
        .sum()
}

/// Setpoints sent by every vehicle's stream (`SetpointStream::counts().sent`), summed from
/// the coordinator's `skein_setpoints_sent{vehicle=…}` metrics.
pub(crate) async fn skein_setpoints_sent(swarm: &Swarm) -> Result<u64, String> {
    let text = match swarm
        .coordinator
        .call(
            |r| AdminMsg::RenderMetrics(r).into(),
            Some(COORDINATOR_TIMEOUT),
        )
        .await
    {
        Ok(ractor::rpc::CallResult::Success(t)) => t,
        Ok(_) => return Err("the coordinator did not render its metrics in time".into()),
        Err(e) => return Err(format!("the coordinator is not running: {e}")),
    };
    Ok(sum_metric(&text, "skein_setpoints_sent"))
}

/// Sum of every sample of `name` (any labels) in Prometheus text exposition.
pub(crate) fn sum_metric(text: &str, name: &str) -> u64 {
    text.lines()
        .filter(|l| {
            l.strip_prefix(name)
                .is_some_and(|rest| rest.starts_with('{') || rest.starts_with(' '))
        })
        .filter_map(|l| l.rsplit(' ').next()?.parse::<f64>().ok())
        .map(|v| v.max(0.0) as u64)
        .sum()
}

pub(crate) fn f64_at(v: &Value, path: &[&str]) -> f64 {
    path.iter()
        .fold(v, |v, k| &v[*k])
        .as_f64()
        .unwrap_or(f64::NAN)
}

pub(crate) fn u64_at(v: &Value, key: &str) -> u64 {
    v[key].as_u64().unwrap_or(0)
}

/// Intervals longer than `threshold_ms` in the simulator's bucket list (a bucket whose
/// upper edge is above the threshold counts whole: pessimistic by one bucket).
pub(crate) fn late_intervals(buckets: &Value, threshold_ms: f64) -> u64 {
    buckets
        .as_array()
        .map(|bs| {
            bs.iter()
                .filter(|b| b["hi_ms"].as_f64().unwrap_or(0.0) > threshold_ms)
                .map(|b| b["count"].as_u64().unwrap_or(0))
                .sum()
        })
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn late_intervals_count_buckets_above_the_threshold() {
        let buckets = json!([
            {"lo_ms": 19.9, "hi_ms": 20.0, "count": 90},
            {"lo_ms": 24.9, "hi_ms": 25.0, "count": 3},
            {"lo_ms": 25.0, "hi_ms": 25.1, "count": 2},
            {"lo_ms": 1000.0, "hi_ms": 1500.0, "count": 1},
        ]);
        assert_eq!(late_intervals(&buckets, 25.0), 3);
        assert_eq!(late_intervals(&json!(null), 25.0), 0);
    }

    #[test]
    fn metric_samples_are_summed_over_labels() {
        let text = "# HELP skein_setpoints_sent Offboard setpoints sent, per vehicle.\n\
                    # TYPE skein_setpoints_sent gauge\n\
                    skein_setpoints_sent{vehicle=\"uav-1\"} 120\n\
                    skein_setpoints_sent{vehicle=\"uav-2\"} 80\n\
                    skein_setpoints_sent_other 5\n";
        assert_eq!(sum_metric(text, "skein_setpoints_sent"), 200);
    }

    #[test]
    fn port_blocks_stay_below_the_ephemeral_range() {
        for attempt in 0..50 {
            let base = candidate_base(1000, attempt).expect("room for 1000");
            assert!(
                base >= 20_000 && usize::from(base) + 1000 <= 32_768,
                "{base}"
            );
        }
        assert!(candidate_base(20_000, 0).is_none());
    }
}
