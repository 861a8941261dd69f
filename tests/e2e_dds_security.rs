//! DDS Security through the `skein` binary, on loopback (`--dds-network 127.0.0.1`, a
//! domain of this test process's own): a keystore and enclaves made by `skein dds
//! keystore|enclave create`; a coordinator and an agent presenting their enclaves
//! (`--dds-keystore`, `--dds-enclave`) fly the agent's vehicle; an intruder coordinator
//! without a certificate, of a higher priority on the same domain, is heard by neither:
//! the enrolled coordinator stays active (an unsecured lease of higher priority would
//! make it stand by, `tests/e2e_failover.rs`), the intruder sees no vehicle, and the
//! vehicle obeys only the enrolled coordinator, whose `GET /api/v1/coordinator` names the
//! agent's enclave and whose `/metrics` count the intruder refused.

mod support;

use serde_json::json;
use std::time::Duration;
use support::distributed::{AgentOptions, agent_on, candidate_on, keystore, role, vehicle};
use support::{Skein, eventually};

/// A DDS domain (231 or 232). Every range is taken by another test, so this one may be
/// shared: the enrolled participants hear no one else whatever the domain, and the
/// checks on the intruder look for this test's vehicle only (sysid 77, `uav-77`).
fn domain() -> String {
    (232 - std::process::id() % 2).to_string()
}

const VEHICLE: &str = "uav-77";

fn coordinator(id: &str, priority: &str, d: &str, security: Option<(&str, &str)>) -> Skein {
    candidate_on(None, id, priority, d, security, &[])
}

#[test]
fn enrolled_participants_fly_and_an_unenrolled_coordinator_is_heard_by_none() {
    let dir = tempfile::tempdir().unwrap();
    let ks = keystore(
        dir.path(),
        &[
            ("/skein/coordinator/c1", "coordinator"),
            ("/skein/agent/a1", "agent"),
        ],
    );
    let ks = ks.as_str();
    let d = domain();

    let c1 = coordinator("c1", "1", &d, Some((ks, "/skein/coordinator/c1")));
    let o = AgentOptions {
        dds_security: Some((ks.to_string(), "/skein/agent/a1".to_string())),
        ..AgentOptions::default()
    };
    let _agent = agent_on(None, 77, &d, &o);
    let intruder = coordinator("intruder", "9", &d, None);

    // The enrolled coordinator claims the role (after listening 5 s, as a secured
    // candidate does), sees the agent's vehicle and flies it.
    eventually("c1 active", Duration::from_secs(30), || {
        match role(&c1).as_str() {
            Some("active") => Ok(()),
            other => Err(format!("{other:?}")),
        }
    });
    c1.take_off(1, 8.0);
    // The intruder runs (as a coordinator of its own) but is heard by no one: the
    // enrolled coordinator never stands down for its higher priority, and it never
    // reads the enrolled agent's vehicle.
    eventually(
        "the intruder elected",
        Duration::from_secs(20),
        || match role(&intruder).as_str() {
            Some("active" | "standby") => Ok(()),
            other => Err(format!("{other:?}")),
        },
    );
    for _ in 0..10 {
        assert_eq!(role(&c1), "active", "the enrolled coordinator stood down");
        let seen = vehicle(&intruder, VEHICLE);
        assert!(seen.is_null(), "the intruder read {VEHICLE}: {seen}");
        std::thread::sleep(Duration::from_millis(300));
    }
    // The operator sees the link secured, and which enclave reported the vehicle.
    let (_, status) = c1.get("/api/v1/coordinator");
    let sec = &status["dds_security"];
    assert_eq!(sec["enclave"], "/skein/coordinator/c1", "{status}");
    assert_eq!(
        sec["vehicles"][VEHICLE],
        json!({"agent": "agent-77", "identity": sec["vehicles"][VEHICLE]["identity"],
               "enclave": "/skein/agent/a1"}),
        "{status}"
    );
    let (_, open) = intruder.get("/api/v1/coordinator");
    assert!(open["dds_security"].is_null(), "{open}");
    // The refusals are counted: the intruder, a participant without DDS Security, by the
    // enrolled coordinator (none of the enrolled participants is refused by another).
    let unauthenticated = "skein_dds_security_refusals{reason=\"unauthenticated\"}";
    eventually(
        "the intruder counted",
        Duration::from_secs(10),
        || match c1.metric(unauthenticated) {
            0 => Err("0".into()),
            _ => Ok(()),
        },
    );
    for reason in ["identity", "handshake", "permissions", "access_control"] {
        let series = format!("skein_dds_security_refusals{{reason=\"{reason}\"}}");
        assert_eq!(c1.metric(&series), 0, "{series}");
    }
    // The vehicle obeys the enrolled coordinator.
    let (status, body) = c1.post(
        &format!("/api/v1/vehicles/{VEHICLE}/commands"),
        json!({"command": "land"}),
    );
    assert_eq!(status, 202, "{body}");
    eventually("landed", Duration::from_secs(60), || {
        let v = vehicle(&c1, VEHICLE);
        if v["state"] == "Landed" {
            Ok(())
        } else {
            Err(format!("{}", v["state"]))
        }
    });
}

/// The shipped companion presets secure the swarm's link: `skein agent` on them does not
/// start without this computer's enclave, and says which and how to make it.
#[test]
fn the_shipped_companion_configs_do_not_join_the_swarm_without_their_enclave() {
    for preset in ["companion.toml", "observation-rtsp.toml"] {
        let config = support::workspace().join("deploy/config").join(preset);
        let mut p = support::Process::start(&["agent", "--config", config.to_str().unwrap()]);
        let code = p.wait_exit(Duration::from_secs(30));
        assert!(code.is_some_and(|c| c != 0), "{preset}: exit {code:?}");
        let err = p.stderr_text();
        assert!(
            err.contains("enclave /skein/agent/uav_1 of keystore /etc/skein/dds")
                && err.contains("skein dds enclave create"),
            "{preset}: {err}"
        );
    }
}
