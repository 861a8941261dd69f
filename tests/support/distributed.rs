//! Distributed swarms of the end-to-end tests: `skein agent`s with one simulated vehicle
//! each and `skein coordinator` candidates, on loopback or on the hosts of a private
//! [`Lan`](super::netns::Lan), and what the tests read of them.

use super::netns::Host;
use super::{Process, Skein, eventually};
use serde_json::Value;
use std::time::Duration;

/// What an agent does without a coordinator (`skein agent --coordinator-*`).
#[derive(Debug, Clone)]
pub struct AgentOptions {
    /// `--coordinator-timeout-s`.
    pub timeout_s: f64,
    /// `--coordinator-ride-through-s`.
    pub ride_through_s: f64,
    /// `--coordinator-lost-action` (`hold`, `land`, `rtl`).
    pub lost_action: &'static str,
    /// `--coordinator-lost-action-s`.
    pub lost_action_s: f64,
    /// `--test-clock-skew-ms`: its wall clock this far off.
    pub clock_skew_ms: Option<i64>,
    /// `--dds-keystore`, `--dds-enclave`: DDS Security with this enclave.
    pub dds_security: Option<(String, String)>,
    /// `--config`: a configuration file (its `[swarm]` geofence, say).
    pub config: Option<String>,
    /// `--sim-model`: the simulated vehicle's model (`None`: the agent's default, an
    /// `observation` UAV with its camera for an even sysid).
    pub sim_model: Option<&'static str>,
}

impl Default for AgentOptions {
    /// The agent's own defaults, but holding for a minute before any lost action.
    fn default() -> Self {
        AgentOptions {
            timeout_s: 1.5,
            ride_through_s: 4.0,
            lost_action: "hold",
            lost_action_s: 60.0,
            clock_skew_ms: None,
            dds_security: None,
            config: None,
            sim_model: None,
        }
    }
}

/// Agent `agent-<sysid>` with one simulated vehicle (sysid `sysid`) on DDS domain `d`, on
/// loopback (`host` `None`) or on a host of a LAN (its DDS and its simulator's stats
/// socket on the host's address; its own API stays on the host's loopback).
pub fn agent_on(host: Option<&Host>, sysid: u8, d: &str, o: &AgentOptions) -> Skein {
    let first = sysid.to_string();
    let id = format!("agent-{sysid}");
    let (timeout, action, ride) = (
        o.timeout_s.to_string(),
        o.lost_action_s.to_string(),
        o.ride_through_s.to_string(),
    );
    let network = host.map_or("127.0.0.1".to_string(), |h| h.addr.to_string());
    let stats = format!("{network}:0");
    let skew = o.clock_skew_ms.map(|ms| ms.to_string());
    let mut args = vec![
        "--sim",
        "1",
        "--first-sysid",
        &first,
        "--sim-base-port",
        "0",
        "--sim-stats",
        &stats,
        "--id",
        &id,
        "--domain-id",
        d,
        "--dds-network",
        &network,
        "--coordinator-timeout-s",
        &timeout,
        "--coordinator-lost-action",
        o.lost_action,
        "--coordinator-lost-action-s",
        &action,
        "--coordinator-ride-through-s",
        &ride,
    ];
    if let Some(ms) = &skew {
        args.extend_from_slice(&["--test-clock-skew-ms", ms]);
    }
    if let Some(config) = &o.config {
        args.extend_from_slice(&["--config", config]);
    }
    if let Some(model) = o.sim_model {
        args.extend_from_slice(&["--sim-model", model]);
    }
    args.extend(security_args(
        o.dds_security
            .as_ref()
            .map(|(k, e)| (k.as_str(), e.as_str())),
    ));
    Skein::launch_in(host.map(|h| h.ns.as_str()), "agent", &args)
}

/// A coordinator candidate on loopback (`host` `None`) or on a host of a LAN, its API
/// on the host's address (no tokens on this private LAN: `--insecure-no-auth`); with
/// `security` (keystore, enclave), DDS Security with that enclave; `extra` arguments after.
pub fn candidate_on(
    host: Option<&Host>,
    id: &str,
    priority: &str,
    d: &str,
    security: Option<(&str, &str)>,
    extra: &[&str],
) -> Skein {
    let (http, network) = match host {
        Some(h) => (format!("{}:0", h.addr), h.addr.to_string()),
        None => ("127.0.0.1:0".to_string(), "127.0.0.1".to_string()),
    };
    let mut args = vec![
        "--http",
        &http,
        "--id",
        id,
        "--priority",
        priority,
        "--domain-id",
        d,
        "--dds-network",
        &network,
    ];
    if host.is_some() {
        args.push("--insecure-no-auth");
    }
    args.extend(security_args(security));
    args.extend_from_slice(extra);
    Skein::launch_in(host.map(|h| h.ns.as_str()), "coordinator", &args)
}

/// `--dds-keystore K --dds-enclave E` for `security` (K, E), nothing for `None`.
fn security_args<'a>(security: Option<(&'a str, &'a str)>) -> Vec<&'a str> {
    security.map_or_else(Vec::new, |(keystore, enclave)| {
        vec!["--dds-keystore", keystore, "--dds-enclave", enclave]
    })
}

/// A keystore (`skein dds keystore create`) in `dir`, with the enclave of each of
/// `enclaves` (name, role) made by `skein dds enclave create`; returns its path.
pub fn keystore(dir: &std::path::Path, enclaves: &[(&str, &str)]) -> String {
    let ks = dir.join("keystore").to_string_lossy().into_owned();
    let run = |args: &[&str]| {
        let out = std::process::Command::new(super::skein_bin())
            .args(args)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "skein {args:?}: {}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    run(&["dds", "keystore", "create", &ks]);
    for (name, role) in enclaves {
        let made = run(&[
            "dds",
            "enclave",
            "create",
            &ks,
            "--enclave",
            name,
            "--role",
            role,
        ]);
        assert!(made.contains(&format!("--dds-enclave {name}")), "{made}");
    }
    ks
}

/// A candidate's role (`"active"`, `"standby"`) from `GET /api/v1/coordinator`.
pub fn role(c: &Skein) -> Value {
    let (_, s) = c.get("/api/v1/coordinator");
    s["role"].clone()
}

/// Waits until `a` is active and `b` stands by.
pub fn wait_roles(a: &Skein, b: &Skein, within: Duration) {
    eventually("one active coordinator, one standby", within, || {
        let (ra, rb) = (role(a), role(b));
        assert!(
            !(ra == "active" && rb == "active"),
            "two active coordinators"
        );
        if ra == "active" && rb == "standby" {
            Ok(())
        } else {
            Err(format!("{ra} {rb}"))
        }
    });
}

/// The vehicle `id` as coordinator `c` shows it.
pub fn vehicle(c: &Skein, id: &str) -> Value {
    c.vehicles()
        .into_iter()
        .find(|v| v["id"] == id)
        .unwrap_or(Value::Null)
}

/// The `p`-quantile (0 to 1) of `v` (NaN when empty).
pub fn quantile(v: &[f64], p: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s[((s.len() - 1) as f64 * p).round() as usize]
}

/// The mean of `v` (NaN when empty).
pub fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// An on-path attacker on loopback (`tests/peers/dds_onpath.py`: a raw packet socket,
/// so root; no DDS library, no key): it records domain `d`'s secured RTPS datagrams
/// from [`OnPath::start`] until [`OnPath::replay_and_forge`].
pub struct OnPath(Process);

impl OnPath {
    /// Starts recording; returns once it records.
    pub fn start(d: &str) -> OnPath {
        let script = super::workspace().join("tests/peers/dds_onpath.py");
        let python = super::python();
        let mut p = Process::start_command(
            &[
                python.to_str().expect("UTF-8 path"),
                script.to_str().expect("UTF-8 path"),
                "--domain",
                d,
            ],
            &[],
        );
        p.wait_line("recording", Duration::from_secs(30));
        OnPath(p)
    }

    /// Stops recording and sends every recorded datagram again where it went, verbatim
    /// (replays), then each with one protected byte flipped (forgeries). Returns what it
    /// printed: `recorded`, `replayed`, `forged` (datagrams) and `to_ports`.
    pub fn replay_and_forge(mut self) -> Value {
        self.0.signal("USR1");
        let line = self.0.wait_line("\"recorded\"", Duration::from_secs(60));
        serde_json::from_str(&line)
            .unwrap_or_else(|e| panic!("dds_onpath.py printed {line:?}: {e}"))
    }
}

/// Runs `tests/peers/dds_intruder.py` on loopback on domain `d` for `seconds`: a
/// CycloneDDS participant without DDS Security that forges a coordinator lease outbidding
/// `coordinator`'s epoch and, as that rogue coordinator, tells `vehicle` to land, while
/// reading the vehicle's poses and the swarm's reports. Returns what it printed
/// (`published`, `matched`, `read`, each per topic); panics if it did not run.
pub fn cyclone_intruder(d: &str, vehicle: &str, coordinator: &Skein, seconds: f64) -> Value {
    let (_, status) = coordinator.get("/api/v1/coordinator");
    let epoch = status["this"]["epoch"]
        .as_u64()
        .unwrap_or_else(|| panic!("no epoch: {status}"))
        .to_string();
    let seconds = seconds.to_string();
    let (code, out, err) = super::run_peer(
        "dds_intruder.py",
        &[
            "--domain",
            d,
            "--vehicle",
            vehicle,
            "--epoch",
            &epoch,
            "--seconds",
            &seconds,
            "--loopback",
        ],
        Duration::from_secs(60),
    );
    assert_eq!(code, Some(0), "dds_intruder.py: {out}\n{err}");
    serde_json::from_str(out.lines().last().unwrap_or_default())
        .unwrap_or_else(|e| panic!("dds_intruder.py printed {out:?}: {e}\n{err}"))
}
