//! `skein bench restart`: restart latency of a payload actor under hovering vehicles,
//! with the largest gap in the offboard setpoint stream (see [`restart`]).

use crate::SwarmBenchArgs;
use crate::round;
use crate::sim_process::*;
use crate::stack::*;
use serde_json::{Value, json};
use skein_swarm::{AdminMsg, Swarm, SwarmServices};
use std::time::{Duration, Instant};

/// `skein bench restart`.
#[derive(clap::Args, Debug, Clone)]
pub struct RestartBenchArgs {
    /// Panics to inject (spread round-robin over the vehicles' payloads).
    #[arg(long, default_value_t = 1000)]
    pub panics: usize,
    /// Hovering vehicles, each with one payload actor (the built-in fault fixture).
    #[arg(long, default_value_t = 4)]
    pub vehicles: usize,
    /// Offboard setpoint rate per vehicle, Hz.
    #[arg(long, default_value_t = 50.0)]
    pub rate_hz: f64,
    /// One panic every this many milliseconds (at most: the next waits for the previous
    /// restart), so that the setpoint streams are watched over panics × period.
    #[arg(long, default_value_t = 10)]
    pub period_ms: u64,
    /// Simulator seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

/// Slot of the payload whose actor `skein bench restart` panics.
const RESTART_BENCH_SLOT: &str = "fixture";

/// `skein bench restart` (issue 4's benchmark):
///
/// 1. starts skein's stack in this process with N vehicles of a model carrying one payload
///    (the built-in `fault-fixture`, a payload-like actor under each Vehicle actor), a
///    payload restart policy without backoff or budget (so that every panic is restarted
///    at once), and fault injection on; the simulator runs in its own process;
/// 2. takes every vehicle off and waits until it hovers under offboard control at R Hz;
/// 3. resets the simulator's counters, then injects `panics` panics one after the other
///    through the coordinator (the path of `POST /api/v1/faults`), round-robin over the
///    vehicles, one every `period_ms` at most, each time waiting for the
///    `actor_restarted` event of that payload;
/// 4. prints `restart_latency_us` (`n`, `p50`, `p99`, `max`, `mean`: the supervisor's own
///    measure, from the failure being noticed to the replacement answering its first
///    message), `inject_to_running_us` (the same seen from outside: from the fault request
///    to the restart event), `restarts`, `largest_setpoint_gap_ms` (the longest interval
///    between two setpoints of any vehicle as the simulator received them during the
///    panics), `offboard_loss_failsafes` and `all_offboard` at the end.
///
/// # Errors
/// Invalid arguments, the swarm or simulator not starting, a restart not seen within 5 s.
pub async fn restart(args: RestartBenchArgs) -> Result<Value, String> {
    use skein_model::supervision::RestartPolicy;
    use skein_payload::{Isolation, PayloadSpec};
    use skein_swarm::supervision::PolicyConfig;
    if args.vehicles == 0 || args.panics == 0 {
        return Err("--vehicles and --panics must be at least 1".into());
    }
    if !(args.rate_hz.is_finite() && args.rate_hz > 2.0) {
        return Err(format!(
            "--rate-hz {}: PX4 needs more than 2 Hz",
            args.rate_hz
        ));
    }
    let swarm_args = SwarmBenchArgs {
        vehicles: args.vehicles,
        rate_hz: args.rate_hz,
        seconds: 0.0,
        altitude_m: 2.0,
        spacing_m: 5.0,
        setup_timeout_s: None,
        seed: args.seed,
        peer: None,
        peer_script: None,
        vehicles_per_port: 1,
    };
    let mut config = bench_config(&swarm_args);
    let mut model = skein_swarm::VehicleModel::generic();
    model.name = "restart-bench".into();
    model.payloads = vec![PayloadSpec {
        slot: RESTART_BENCH_SLOT.into(),
        kind: skein_swarm::payload::FAULT_FIXTURE.into(),
        plugin: None,
        isolation: Isolation::InProcess,
        config: json!({}),
    }];
    config.models.insert(model.name.clone(), model);
    config.supervision.payload = PolicyConfig {
        policy: RestartPolicy::OnFailure,
        max_restarts: u32::MAX,
        window_s: 1.0,
        backoff_initial_ms: 0,
        backoff_max_ms: 0,
    };
    config.fault_injection = true;
    let started = Instant::now();
    let (swarm, base) = start_swarm(
        &swarm_args,
        config,
        SwarmServices::default(),
        Some("restart-bench"),
    )
    .await?;
    let mut sim = match SimProcess::start(&swarm_args, base).await {
        Ok(s) => s,
        Err(e) => {
            swarm.stop().await;
            return Err(e);
        }
    };
    let setup_deadline = started + Duration::from_secs(60 + args.vehicles as u64 / 10);
    let result = panic_payloads(&swarm, &mut sim, &args, &swarm_args, setup_deadline).await;
    sim.stop().await;
    swarm.stop().await;
    result
}

async fn panic_payloads(
    swarm: &Swarm,
    sim: &mut SimProcess,
    args: &RestartBenchArgs,
    swarm_args: &SwarmBenchArgs,
    setup_deadline: Instant,
) -> Result<Value, String> {
    use skein_model::supervision::FaultKind;
    use skein_swarm::events::SwarmEvent;
    let n = args.vehicles;
    let hovering = take_off_all(swarm, swarm_args, setup_deadline).await?;
    if hovering < n {
        return Err(format!("only {hovering} of {n} vehicles hover"));
    }
    eprintln!(
        "bench: {n} vehicles hovering; injecting {} panics",
        args.panics
    );
    let mut events = swarm.events.subscribe();
    sim.ask("reset").await?;
    let mut latency_us: Vec<f64> = Vec::with_capacity(args.panics);
    let mut outside_us: Vec<f64> = Vec::with_capacity(args.panics);
    let t0 = Instant::now();
    let mut next = tokio::time::Instant::now();
    for i in 0..args.panics {
        tokio::time::sleep_until(next).await;
        next += Duration::from_millis(args.period_ms);
        let path = format!("coordinator/uav-{}/payload/{RESTART_BENCH_SLOT}", i % n + 1);
        let asked = Instant::now();
        let target = path.clone();
        match swarm
            .coordinator
            .call(
                move |r| AdminMsg::InjectFault(target, FaultKind::Panic, r).into(),
                Some(COORDINATOR_TIMEOUT),
            )
            .await
        {
            Ok(ractor::rpc::CallResult::Success(Ok(()))) => {}
            Ok(ractor::rpc::CallResult::Success(Err(e))) => {
                return Err(format!("panic {i}: {path}: {e:?}"));
            }
            Ok(_) => return Err(format!("panic {i}: the coordinator did not answer")),
            Err(e) => return Err(format!("the coordinator is not running: {e}")),
        }
        let deadline = tokio::time::Instant::now() + Duration::from_secs(5);
        loop {
            match tokio::time::timeout_at(deadline, events.recv()).await {
                Ok(Ok(SwarmEvent::ActorRestarted {
                    path: p,
                    latency_us: l,
                    ..
                })) if p == path => {
                    outside_us.push(asked.elapsed().as_secs_f64() * 1e6);
                    latency_us.push(l as f64);
                    break;
                }
                Ok(Ok(_)) | Ok(Err(tokio::sync::broadcast::error::RecvError::Lagged(_))) => {}
                Ok(Err(tokio::sync::broadcast::error::RecvError::Closed)) => {
                    return Err("the swarm's event bus closed".into());
                }
                Err(_) => return Err(format!("panic {i}: {path} was not restarted within 5 s")),
            }
        }
        if (i + 1) % 250 == 0 {
            eprintln!("bench: {} panics restarted", i + 1);
        }
    }
    let window_s = t0.elapsed().as_secs_f64();
    let summary = sim.ask("summary").await?;
    let in_offboard = summary["modes"]["OFFBOARD"].as_u64().unwrap_or(0);
    Ok(json!({
        "bench": "restart",
        "vehicles": n,
        "rate_hz": args.rate_hz,
        "period_ms": args.period_ms,
        "panics": args.panics,
        "restarts": latency_us.len(),
        "restart_latency_us": crate::plugins::summary(latency_us),
        "inject_to_running_us": crate::plugins::summary(outside_us),
        "largest_setpoint_gap_ms": f64_at(&summary["setpoint_intervals"], &["max_ms"]),
        "setpoint_interval_p99_ms": f64_at(&summary["setpoint_intervals"], &["p99_ms"]),
        "offboard_loss_failsafes": u64_at(&summary, "offboard_loss_failsafes"),
        "all_offboard": in_offboard == n as u64,
        "seconds": round(window_s, 2),
    }))
}
