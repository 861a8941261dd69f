//! `skein bench api [--vehicles 24 --busy-clients 4 --seconds 10]`: how long the API's
//! reads take while the coordinator is busy (issue 48, "reads from snapshots").
//!
//! 1. starts `skein up --sim N` (generic vehicles, the API on a free loopback port) and
//!    flies them as [`crate::distributed`] does: takeoff, a line behind a virtual leader,
//!    cruising at 5 m/s (the formation tick works for every member);
//! 2. **quiet**: for `--seconds`, one client reads the dashboard's polled routes in turn
//!    (`/api/v1/vehicles`, `/api/v1/vehicles/uav-1`, `/api/v1/formation`, `/api/v1/health`,
//!    `/api/v1/supervision`, `/api/v1/tracks`), one request after the other, timing each
//!    from send to the last byte;
//! 3. **busy**: the same, while `--busy-clients` clients keep the coordinator's mailbox
//!    full with what still goes through it: `GET /metrics` (rendered by the coordinator
//!    from its state) and `PUT /api/v1/formation`, the line at 6 then 6.5 m spacing and
//!    back (a formation change, checked and planned for every member by the coordinator);
//! 4. prints one JSON object: `vehicles`, `seconds`, `busy_clients`, and for `quiet` and
//!    `busy` each: `read_latency_ms` (`p50`, `p99`, `max`, `samples`, over every route),
//!    `by_route` (each route's `p50` and `p99`), `busy_requests_per_s` (the busy
//!    clients' answered requests) and `coordinator_cpu_cores` (the `skein up` process,
//!    simulator included).

use crate::procfs::cpu_seconds;
use crate::round;
use crate::up_process::UpProcess;
use serde_json::{Value, json};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// `skein bench api`.
#[derive(clap::Args, Debug, Clone)]
pub struct ApiBenchArgs {
    /// Simulated vehicles flying the formation.
    #[arg(long, default_value_t = 24)]
    pub vehicles: usize,
    /// Clients keeping the coordinator's mailbox busy in the busy phase.
    #[arg(long, default_value_t = 4)]
    pub busy_clients: usize,
    /// Seconds of each phase.
    #[arg(long, default_value_t = 10.0)]
    pub seconds: f64,
}

/// The reads timed, in turn: what the dashboard polls.
const READS: [&str; 6] = [
    "/api/v1/vehicles",
    "/api/v1/vehicles/uav-1",
    "/api/v1/formation",
    "/api/v1/health",
    "/api/v1/supervision",
    "/api/v1/tracks",
];

/// A client of `base` that answers any status (the bench reads statuses itself).
fn client() -> ureq::Agent {
    ureq::Agent::config_builder()
        .http_status_as_error(false)
        .timeout_global(Some(Duration::from_secs(30)))
        .build()
        .into()
}

/// `GET url` to the last byte; the milliseconds it took, or why it failed.
fn timed_get(agent: &ureq::Agent, url: &str) -> Result<f64, String> {
    let t0 = Instant::now();
    let mut r = agent
        .get(url)
        .call()
        .map_err(|e| format!("GET {url}: {e}"))?;
    let status = r.status().as_u16();
    let _ = r.body_mut().read_to_vec();
    if status != 200 {
        return Err(format!("GET {url}: {status}"));
    }
    Ok(t0.elapsed().as_secs_f64() * 1e3)
}

/// Keeps the coordinator busy until `stop`: `/metrics`, then the line again at 7 or
/// 7.5 m spacing (each a formation change the coordinator checks and plans for every
/// member, as an operator's is); counts the answered requests in `done`.
fn busy_client(base: String, stop: Arc<AtomicBool>, done: Arc<AtomicU64>) {
    let agent = client();
    let mut spacing_m = 7.0;
    while !stop.load(Ordering::Relaxed) {
        let metrics = agent.get(format!("{base}/metrics")).call();
        spacing_m = if spacing_m > 7.2 { 7.0 } else { 7.5 };
        let line = json!({"shape": "line", "spacing_m": spacing_m, "leader": "virtual",
            "altitude_m": 12.0});
        let write = agent
            .put(format!("{base}/api/v1/formation"))
            .send_json(&line);
        done.fetch_add(
            u64::from(metrics.is_ok()) + u64::from(write.is_ok()),
            Ordering::Relaxed,
        );
    }
}

/// p50, p99, max and count of `ms`, in milliseconds to 0.01.
fn summary(ms: &mut [f64]) -> Value {
    ms.sort_by(f64::total_cmp);
    let at = |q: f64| {
        ms.get(((ms.len() as f64 - 1.0) * q).round() as usize)
            .copied()
            .map_or(Value::Null, |v| json!(round(v, 2)))
    };
    json!({"p50": at(0.5), "p99": at(0.99), "max": at(1.0), "samples": ms.len()})
}

/// One phase: the reads for `seconds` with `busy` clients meanwhile.
fn phase(up: &UpProcess, seconds: f64, busy: usize) -> Result<Value, String> {
    let stop = Arc::new(AtomicBool::new(false));
    let done = Arc::new(AtomicU64::new(0));
    let clients: Vec<_> = (0..busy)
        .map(|_| {
            let (base, stop, done) = (up.base.clone(), stop.clone(), done.clone());
            std::thread::spawn(move || busy_client(base, stop, done))
        })
        .collect();
    let cpu0 = cpu_seconds(Some(up.pid()));
    let t0 = Instant::now();
    let agent = client();
    let mut by_route: Vec<Vec<f64>> = vec![Vec::new(); READS.len()];
    let mut result = Ok(());
    'reads: while t0.elapsed().as_secs_f64() < seconds {
        for (i, path) in READS.iter().enumerate() {
            match timed_get(&agent, &format!("{}{path}", up.base)) {
                Ok(ms) => by_route[i].push(ms),
                Err(e) => {
                    result = Err(e);
                    break 'reads;
                }
            }
        }
    }
    let dt = t0.elapsed().as_secs_f64();
    let cpu1 = cpu_seconds(Some(up.pid()));
    stop.store(true, Ordering::Relaxed);
    for c in clients {
        let _ = c.join();
    }
    result?;
    let mut all: Vec<f64> = by_route.iter().flatten().copied().collect();
    let routes: serde_json::Map<String, Value> = READS
        .iter()
        .zip(&mut by_route)
        .map(|(p, ms)| {
            let s = summary(ms);
            (p.to_string(), json!({"p50": s["p50"], "p99": s["p99"]}))
        })
        .collect();
    Ok(json!({
        "read_latency_ms": summary(&mut all),
        "by_route": routes,
        "busy_requests_per_s": round(done.load(Ordering::Relaxed) as f64 / dt, 1),
        "coordinator_cpu_cores": cpu0.zip(cpu1).map(|(a, b)| round((b - a) / dt, 3)),
    }))
}

/// Runs `skein bench api` (see the module docs); the report.
///
/// # Errors
/// `skein up` did not start or fly, or a read failed.
pub fn api(args: &ApiBenchArgs) -> Result<Value, String> {
    let n = args.vehicles.to_string();
    let up = UpProcess::start(&[
        "--sim",
        &n,
        "--sim-model",
        "generic",
        "--sim-base-port",
        "0",
    ])?;
    crate::distributed::fly(&up, args.vehicles)?;
    eprintln!(
        "bench api: {} vehicles cruising; quiet phase",
        args.vehicles
    );
    let quiet = phase(&up, args.seconds, 0)?;
    eprintln!("bench api: busy phase, {} clients", args.busy_clients);
    let busy = phase(&up, args.seconds, args.busy_clients)?;
    Ok(json!({
        "vehicles": args.vehicles,
        "seconds": args.seconds,
        "busy_clients": args.busy_clients,
        "quiet": quiet,
        "busy": busy,
    }))
}
