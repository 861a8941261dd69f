//! Coordinator failover (`skein coordinator --priority P`): two candidates, each its own
//! process, elect over DDS on loopback (`--dds-network 127.0.0.1`, a domain of this test
//! process's own). Only through their HTTP APIs:
//!
//! - the higher priority is active, the other a standby whose writes answer 409 naming
//!   the active one, and whose dashboard (real Chromium, `coordinator_selenium.py`)
//!   shows it as standby with a banner linking to the active one's;
//! - killing the active one (SIGKILL, no goodbye) makes the standby active within 2 s,
//!   in the next epoch;
//! - the killed one started again takes the role back only by handover: at every poll
//!   on the way, at most one of the two is active.
//!
//! Then the same two candidates as two hosts, each in a network namespace of its own on
//! a bridge the test makes (DDS discovery by plain multicast, as on a WLAN): cutting the
//! active one's link for 3 s partitions them, the standby claims the next epoch, and
//! when the link is back the older epoch steps down, so exactly one stays active; the
//! higher priority then gets the role back by handover. The same again with DDS Security
//! enforced, each candidate presenting its own enclave.

mod support;

use serde_json::{Value, json};
use std::time::{Duration, Instant};
use support::distributed::{self, keystore};
use support::netns::Lan;
use support::{EventLog, Skein, eventually, run_peer};

/// A DDS domain of this test process's own, apart from `e2e_dds`' 100–179 and
/// `e2e_ros2`'s 180–218.
fn domain() -> String {
    (220 + std::process::id() % 12).to_string()
}

fn candidate(id: &str, priority: u32, d: &str, recordings: &std::path::Path) -> Skein {
    candidate_on(None, id, priority, d, recordings, None)
}

/// A candidate on loopback (`host` `None`), or on a host of a [`Lan`]
/// ([`distributed::candidate_on`]), recording into `recordings`.
fn candidate_on(
    host: Option<&support::netns::Host>,
    id: &str,
    priority: u32,
    d: &str,
    recordings: &std::path::Path,
    security: Option<(&str, &str)>,
) -> Skein {
    let config = recordings.join(format!("{id}.toml"));
    std::fs::write(
        &config,
        format!("[recording]\ndir = \"{}\"\n", recordings.display()),
    )
    .unwrap();
    distributed::candidate_on(
        host,
        id,
        &priority.to_string(),
        d,
        security,
        &["--config", config.to_str().unwrap()],
    )
}

fn election(s: &Skein) -> Value {
    let (code, v) = s.get("/api/v1/coordinator");
    assert_eq!(code, 200, "{v}");
    v
}

fn role(s: &Skein) -> String {
    election(s)["role"].as_str().unwrap_or_default().to_string()
}

/// Waits until `who` is active and `other` a standby that names it.
fn settled(who: &Skein, other: &Skein, id: &str, within: Duration) -> Value {
    eventually(
        &format!("`{id}` active, the other its standby"),
        within,
        || {
            let (a, b) = (election(who), election(other));
            if a["role"] == "active"
                && b["role"] == "standby"
                && b["active"]["coordinator_id"] == id
            {
                Ok(a)
            } else {
                Err(format!("{a}\n{b}"))
            }
        },
    )
}

#[test]
fn the_standby_takes_over_within_two_seconds_and_a_returning_one_only_by_handover() {
    let d = domain();
    let dir = support::plugins::scratch("failover");
    let mut a = candidate("gcs-a", 2, &d, &dir);
    let b = candidate("gcs-b", 1, &d, &dir);

    let a_status = settled(&a, &b, "gcs-a", Duration::from_secs(20));
    assert_eq!(a_status["this"]["epoch"], 1, "{a_status}");
    assert_eq!(a_status["this"]["api_url"], a.base.as_str());

    // The standby refuses a write, naming the active one and its API.
    let (code, body) = b.post("/api/v1/recording/start", json!({"name": "on-b"}));
    assert_eq!(code, 409, "{body}");
    let err = body["error"].as_str().unwrap();
    assert!(
        err.contains("`gcs-a`") && err.contains(&a.base) && err.contains("standby"),
        "{err}"
    );
    assert!(!dir.join("on-b.mcap").exists());
    // Reads still answer on the standby.
    assert_eq!(b.get("/api/v1/vehicles").0, 200);
    // The active one takes the same write.
    let (code, body) = a.post("/api/v1/recording/start", json!({"name": "on-a"}));
    assert_eq!(code, 201, "{body}");
    let (code, body) = a.post("/api/v1/recording/stop", json!({}));
    assert_eq!(code, 200, "{body}");

    // Both dashboards show the roles.
    let (code, out, err) = run_peer(
        "coordinator_selenium.py",
        &[
            "--standby",
            &format!("{}/", b.base),
            "--active",
            &format!("{}/", a.base),
            "--active-id",
            "gcs-a",
        ],
        Duration::from_secs(120),
    );
    assert_eq!(
        code,
        Some(0),
        "coordinator_selenium.py failed\n--- stdout\n{out}\n--- stderr\n{err}"
    );
    assert_eq!(b.get("/api/v1/health").1["coordinator_role"], "standby");

    // Kill the active one: the standby claims the next epoch within 2 s.
    let b_log = EventLog::connect(&b.base);
    let killed = Instant::now();
    a.kill_hard();
    let took = eventually("gcs-b active", Duration::from_secs(10), || {
        let s = election(&b);
        if s["role"] == "active" {
            Ok(killed.elapsed())
        } else {
            Err(s.to_string())
        }
    });
    println!("failover took {:.2} s", took.as_secs_f64());
    assert!(took <= Duration::from_secs(2), "failover took {took:?}");
    let s = election(&b);
    assert_eq!(s["this"]["epoch"], 2, "{s}");
    assert!(s["peers"].as_array().unwrap().is_empty(), "{s}");
    let (code, body) = b.post("/api/v1/recording/start", json!({"name": "on-b"}));
    assert_eq!(code, 201, "the new active one takes writes: {body}");
    b.post("/api/v1/recording/stop", json!({}));

    // The old one returns: never two active, and it gets the role only by handover
    // (5 s after it is first heard), in epoch 3.
    let a = candidate("gcs-a", 2, &d, &dir);
    let back = Instant::now();
    let a_status = eventually("gcs-a active again", Duration::from_secs(30), || {
        let (ra, rb) = (role(&a), role(&b));
        assert!(
            !(ra == "active" && rb == "active"),
            "two active coordinators: {}\n{}",
            election(&a),
            election(&b)
        );
        if ra == "active" {
            Ok(election(&a))
        } else {
            Err(format!("a {ra}, b {rb}"))
        }
    });
    assert!(
        back.elapsed() >= Duration::from_secs(5),
        "pre-empted before the handover time: {:?}",
        back.elapsed()
    );
    assert_eq!(a_status["this"]["epoch"], 3, "{a_status}");
    settled(&a, &b, "gcs-a", Duration::from_secs(5));
    // gcs-b's event stream told both changes of its role, the handover naming gcs-a.
    let changes = eventually("gcs-b's two role events", Duration::from_secs(5), || {
        let v = b_log.of_type("coordinator_role_changed");
        if v.len() >= 2 {
            Ok(v)
        } else {
            Err(format!("{v:?}"))
        }
    });
    assert_eq!(changes[0]["role"], "active", "{changes:?}");
    assert_eq!(changes[0]["epoch"], 2, "{changes:?}");
    assert_eq!(changes[1]["role"], "standby", "{changes:?}");
    let reason = changes[1]["reason"].as_str().unwrap_or_default();
    assert!(reason.contains("handing over to `gcs-a`"), "{reason}");
}

/// SIGKILL: the candidate vanishes without a last lease, as a crashed host would.
#[test]
fn a_partition_elects_one_per_side_and_healing_leaves_exactly_one() {
    partition_heals('f', None);
}

/// The same two hosts, each candidate presenting its own DDS Security enclave (made by
/// `skein dds keystore|enclave create`): the election, the partition and the healing go
/// as without it.
#[test]
fn under_dds_security_a_partition_heals_to_exactly_one() {
    let dir = support::plugins::scratch("failover-keystore");
    let ks = keystore(
        &dir,
        &[
            ("/skein/coordinator/gcs_a", "coordinator"),
            ("/skein/coordinator/gcs_b", "coordinator"),
        ],
    );
    partition_heals('g', Some(&ks));
}

/// Two candidates, each a host of a LAN (tag `tag`), with enclaves of `keystore` when
/// given: elected, partitioned, healed (see the module docs).
fn partition_heals(tag: char, keystore: Option<&str>) {
    let lan = Lan::new(tag, 2);
    let d = "7";
    let dir = support::plugins::scratch(&format!("failover-lan-{tag}"));
    let security = |enclave: &'static str| keystore.map(|k| (k, enclave));
    let a = candidate_on(
        Some(&lan.hosts[0]),
        "gcs-a",
        2,
        d,
        &dir,
        security("/skein/coordinator/gcs_a"),
    );
    let b = candidate_on(
        Some(&lan.hosts[1]),
        "gcs-b",
        1,
        d,
        &dir,
        security("/skein/coordinator/gcs_b"),
    );
    // Discovery across the bridge, then the election.
    settled(&a, &b, "gcs-a", Duration::from_secs(30));

    // Partition: gcs-a's host loses its link. gcs-b hears no lease and claims epoch 2
    // (gcs-a, alone on its side, stays active: it is unreachable from here meanwhile).
    let cut = Instant::now();
    lan.cut(0);
    let took = eventually("gcs-b active on its side", Duration::from_secs(10), || {
        let s = election(&b);
        if s["role"] == "active" {
            Ok(cut.elapsed())
        } else {
            Err(s.to_string())
        }
    });
    println!(
        "failover across the partition took {:.2} s",
        took.as_secs_f64()
    );
    assert!(took <= Duration::from_secs(2), "took {took:?}");
    assert_eq!(election(&b)["this"]["epoch"], 2);
    eventually("3 s of partition", Duration::from_secs(10), || {
        if cut.elapsed() >= Duration::from_secs(3) {
            Ok(())
        } else {
            Err(format!("{:?}", cut.elapsed()))
        }
    });

    // Heal: gcs-a hears epoch 2 and steps down (it was active in epoch 1).
    lan.heal(0);
    let healed = Instant::now();
    let s = eventually("gcs-b alone active", Duration::from_secs(10), || {
        let (sa, sb) = (election(&a), election(&b));
        if sa["role"] == "standby" && sb["role"] == "active" {
            Ok(sa)
        } else {
            Err(format!("{sa}\n{sb}"))
        }
    });
    assert_eq!(s["active"]["coordinator_id"], "gcs-b", "{s}");
    println!(
        "two actives resolved {:.2} s after the link came back",
        healed.elapsed().as_secs_f64()
    );
    // From here on never two; the higher priority gets the role by handover, epoch 3.
    let s = eventually("gcs-a active by handover", Duration::from_secs(20), || {
        let (ra, rb) = (role(&a), role(&b));
        assert!(
            !(ra == "active" && rb == "active"),
            "two active after healing"
        );
        if ra == "active" {
            Ok(election(&a))
        } else {
            Err(format!("a {ra}, b {rb}"))
        }
    });
    assert_eq!(s["this"]["epoch"], 3, "{s}");
    settled(&a, &b, "gcs-a", Duration::from_secs(5));
}
