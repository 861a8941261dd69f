//! `skein bench dds --distributed`: the distributed roles against the single process.
//!
//! 1. `skein up --sim N --sim-model generic` (this binary, free ports): take off, a line
//!    behind a virtual leader, the leader north at 5 m/s; once it has cruised for 2 s,
//!    samples the formation's RMS slot error every 100 ms and the process's CPU over
//!    `--seconds`;
//! 2. the same flight with `skein coordinator` and N `skein agent --sim 1` (one generic
//!    vehicle each, sysids 1 to N) on DDS over loopback, a domain of its own: the same
//!    samples, each agent's CPU and the coordinator's, the swarm's assembly (all agents
//!    started at once, until the coordinator lists every vehicle with a home: the
//!    seconds, and the agents' mean CPU meanwhile), and the latency of every slot
//!    target from the coordinator's write to its arrival at a subscriber in this process
//!    (a RustDDS participant reading `/skein/swarm/target` as an agent does; its header
//!    stamp against the same host's clock);
//! 3. the same flight again under DDS Security, on a domain of its own: a keystore made
//!    for the run (`skein_dds::security::keystore`), the coordinator, each agent and the
//!    probe presenting an enclave of their role (`coordinator`, `agent`, `viewer`);
//! 4. prints one JSON object: `vehicles`, `seconds`, `single_process` (`rms_slot_error_m`
//!    mean and max; CPU in cores, simulators included, per vehicle), `distributed` and
//!    `distributed_secured` side by side (each: `assembly_s`,
//!    `assembly_agent_cpu_cores`, `rms_slot_error_m`, `agent_cpu_cores_per_vehicle`,
//!    `coordinator_cpu_cores`, `target_latency_ms` with `p50`, `p99`, `max`, `samples`), `rms_difference_m` (open distributed mean minus
//!    single-process mean) and `secured_over_open` (the ratios of agent CPU,
//!    coordinator CPU and target latency p50).

use crate::dds::{DdsBenchArgs, percentile};
use crate::procfs::cpu_seconds;
use crate::up_process::UpProcess;
use serde_json::{Value, json};
use std::net::{IpAddr, Ipv4Addr};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Takes `c`'s `n` vehicles off and flies them in a line north at 5 m/s; returns once the
/// reference has cruised for 2 s.
pub(crate) fn fly(c: &UpProcess, n: usize) -> Result<(), String> {
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
        Some(json!({"shape": "line", "spacing_m": 7.0, "leader": "virtual", "altitude_m": 12.0})),
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

/// The CPU seconds process `pid` has used.
fn process_cpu_s(pid: u32) -> Result<f64, String> {
    cpu_seconds(Some(pid)).ok_or_else(|| "no /proc CPU figures".to_string())
}

/// Waits until `c` lists its `n` vehicles with a home (120 s at most); returns the seconds
/// since `started` and the mean CPU (cores) of the agents `pids` since they started.
fn assemble(c: &UpProcess, n: usize, started: Instant, pids: &[u32]) -> Result<(f64, f64), String> {
    c.wait_vehicles(
        n,
        "every vehicle with a home",
        Duration::from_secs(120),
        |v| v["home"].is_object(),
    )?;
    let seconds = started.elapsed().as_secs_f64();
    let cpu = pids
        .iter()
        .map(|p| process_cpu_s(*p))
        .sum::<Result<f64, _>>()?;
    Ok((seconds, cpu / seconds / pids.len().max(1) as f64))
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

/// Polls `GET /api/v1/coordinator` until `c` is the active coordinator (30 s at most: a
/// secured candidate listens 5 s before it claims).
fn active(c: &UpProcess) -> Result<(), String> {
    let deadline = Instant::now() + Duration::from_secs(30);
    while c.get("/api/v1/coordinator")?["role"] != "active" {
        if Instant::now() > deadline {
            return Err("the coordinator was not elected within 30 s".into());
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    Ok(())
}

/// The RMS slot error every 100 ms for `seconds`, and the CPU seconds of `pids` per
/// second meanwhile, each.
fn sample(c: &UpProcess, seconds: f64, pids: &[u32]) -> Result<(Vec<f64>, Vec<f64>), String> {
    let c0: Vec<f64> = pids
        .iter()
        .map(|p| process_cpu_s(*p))
        .collect::<Result<_, _>>()?;
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
    let c1: Vec<f64> = pids
        .iter()
        .map(|p| process_cpu_s(*p))
        .collect::<Result<_, _>>()?;
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

/// What one distributed flight measured.
struct Flight {
    /// Seconds from the agents' start to every vehicle listed with a home.
    assembly_s: f64,
    /// Each agent's CPU during the assembly, cores, mean over the agents.
    assembly_agent_cpu: f64,
    rms: Vec<f64>,
    agents_cpu_per_vehicle: f64,
    coordinator_cpu: f64,
    latencies_ms: Vec<f64>,
}

impl Flight {
    fn json(&self) -> Value {
        json!({
            "assembly_s": self.assembly_s,
            "assembly_agent_cpu_cores": self.assembly_agent_cpu,
            "rms_slot_error_m": stats(&self.rms),
            "agent_cpu_cores_per_vehicle": self.agents_cpu_per_vehicle,
            "coordinator_cpu_cores": self.coordinator_cpu,
            "target_latency_ms": {
                "p50": percentile(&self.latencies_ms, 0.5),
                "p99": percentile(&self.latencies_ms, 0.99),
                "max": self.latencies_ms.last(),
                "samples": self.latencies_ms.len(),
            },
        })
    }
}

/// The enclaves of a secured flight: the coordinator's, agent `k`'s (1-based) and the
/// probe's.
const COORDINATOR_ENCLAVE: &str = "/skein/coordinator/bench";
const PROBE_ENCLAVE: &str = "/skein/viewer/probe";
fn agent_enclave(k: usize) -> String {
    format!("/skein/agent/a{k}")
}

/// A keystore in `dir` with the enclaves of a flight of `n` agents (30 days).
fn keystore(dir: &std::path::Path, n: usize) -> Result<PathBuf, String> {
    use skein_dds::security::Role;
    use skein_dds::security::keystore::{Validity, create_enclave, create_keystore};
    let ks = dir.join("keystore");
    create_keystore(&ks, Validity::days(30))?;
    create_enclave(
        &ks,
        COORDINATOR_ENCLAVE,
        Role::Coordinator,
        Validity::days(30),
    )?;
    create_enclave(&ks, PROBE_ENCLAVE, Role::Viewer, Validity::days(30))?;
    for k in 1..=n {
        create_enclave(&ks, &agent_enclave(k), Role::Agent, Validity::days(30))?;
    }
    Ok(ks)
}

/// How a flight's processes are started: its domain and, when secured, its keystore.
struct Roles<'a> {
    domain: &'a str,
    keystore: Option<String>,
}

impl Roles<'_> {
    /// `--dds-keystore K --dds-enclave E` when secured, else nothing.
    fn security(&self, enclave: &str) -> Vec<String> {
        self.keystore
            .iter()
            .flat_map(|k| {
                [
                    "--dds-keystore".into(),
                    k.clone(),
                    "--dds-enclave".into(),
                    enclave.into(),
                ]
            })
            .collect()
    }

    /// `skein <role> <base> <security for enclave>` on the flight's domain, over loopback.
    fn start(&self, role: &[&str], base: &[&str], enclave: &str) -> Result<UpProcess, String> {
        let args: Vec<String> = base
            .iter()
            .map(|s| s.to_string())
            .chain(["--domain-id", self.domain, "--dds-network", "127.0.0.1"].map(String::from))
            .chain(self.security(enclave))
            .collect();
        UpProcess::start_role(role, &args.iter().map(String::as_str).collect::<Vec<_>>())
    }

    /// `skein coordinator` with its API on a free port.
    fn coordinator(&self) -> Result<UpProcess, String> {
        self.start(
            &["coordinator", "--http", "127.0.0.1:0"],
            &["--id", "bench"],
            COORDINATOR_ENCLAVE,
        )
    }

    /// `n` `skein agent --sim 1`, sysids 1 to `n`, started one after another.
    fn agents(&self, n: usize) -> Result<Vec<UpProcess>, String> {
        (1..=n)
            .map(|k| {
                let first = k.to_string();
                let base = [
                    "--sim",
                    "1",
                    "--first-sysid",
                    &first,
                    "--sim-model",
                    "generic",
                    "--sim-base-port",
                    "0",
                ];
                self.start(&["agent"], &base, &agent_enclave(k))
            })
            .collect()
    }
}

/// A coordinator and `n` agents on `domain` (with `keystore`, each presenting its
/// enclave), flown as [`fly`] does; samples as [`sample`] does, and the targets'
/// latency to a probe (a viewer with `keystore`).
fn flight(n: usize, domain: &str, seconds: f64, keystore: Option<&Path>) -> Result<Flight, String> {
    let roles = Roles {
        domain,
        keystore: keystore.map(|k| k.to_string_lossy().into_owned()),
    };
    let coordinator = roles.coordinator()?;
    let started = Instant::now();
    let agents = roles.agents(n)?;
    let probe_security = keystore
        .map(|k| skein_dds::security::DdsSecurity::new(k, PROBE_ENCLAVE))
        .transpose()?;
    let probe = skein_dds::probe::PoseProbe::start(
        domain.parse().map_err(|_| "domain")?,
        &[IpAddr::V4(Ipv4Addr::LOCALHOST)],
        &[],
        true,
        probe_security.as_ref(),
    )
    .map_err(|e| e.to_string())?;
    let mut pids: Vec<u32> = agents.iter().map(UpProcess::pid).collect();
    pids.push(coordinator.pid());
    let (assembly, rms, cpu) = tokio::task::block_in_place(|| {
        active(&coordinator)?;
        let assembly = assemble(&coordinator, n, started, &pids[..n])?;
        // Said at once: a flight that fails later (a saturated machine) still tells it.
        eprintln!(
            "bench dds --distributed: {n} vehicles listed with a home {:.1} s after the agents started",
            assembly.0
        );
        fly(&coordinator, n)?;
        probe.take();
        let (rms, cpu) = sample(&coordinator, seconds, &pids)?;
        Ok::<_, String>((assembly, rms, cpu))
    })?;
    let mut latencies_ms: Vec<f64> = probe.take().iter().map(|(_, l)| l * 1e3).collect();
    latencies_ms.sort_by(f64::total_cmp);
    Ok(Flight {
        assembly_s: assembly.0,
        assembly_agent_cpu: assembly.1,
        rms,
        agents_cpu_per_vehicle: cpu[..n].iter().sum::<f64>() / n as f64,
        coordinator_cpu: cpu[n],
        latencies_ms,
    })
}

/// Runs the benchmark (see the module docs).
///
/// # Errors
/// A process that does not start, a flight that does not happen, the keystore, the
/// probe's participant, or no `/proc`.
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
        .unwrap_or(150 + (std::process::id() % 50) as u16);
    eprintln!("bench dds --distributed: a coordinator and {n} agents on domain {domain}");
    let open = flight(n, &domain.to_string(), args.seconds, None)?;
    // The secured flight on a domain of its own: the open one's participants may still
    // be announced there for a while.
    let secured_domain = if domain < 232 { domain + 1 } else { domain - 1 };
    eprintln!("bench dds --distributed: the same under DDS Security, on domain {secured_domain}");
    let dir = tempfile::tempdir().map_err(|e| format!("a keystore directory: {e}"))?;
    let ks = keystore(dir.path(), n)?;
    let secured = flight(n, &secured_domain.to_string(), args.seconds, Some(&ks))?;
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let ratio = |a: f64, b: f64| if b > 0.0 { a / b } else { f64::NAN };
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
        "distributed": open.json(),
        "distributed_secured": secured.json(),
        "rms_difference_m": mean(&open.rms) - mean(&single_rms),
        "secured_over_open": {
            "agent_cpu": ratio(secured.agents_cpu_per_vehicle, open.agents_cpu_per_vehicle),
            "coordinator_cpu": ratio(secured.coordinator_cpu, open.coordinator_cpu),
            "target_latency_p50": percentile(&secured.latencies_ms, 0.5)
                .zip(percentile(&open.latencies_ms, 0.5))
                .map(|(s, o)| ratio(s, o)),
        },
    }))
}
