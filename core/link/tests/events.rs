//! PX4's events against the simulator over real UDP: the component metadata read over
//! MAVLink FTP and cached (a second link reads the cache, no FTP request), a refused
//! arm named by PX4's check and the arming report in the telemetry, a lost `EVENT`
//! asked for again by its sequence.

mod common;

use common::eventually;
use common::vehicle::Vehicle;
use skein_link::endpoint::Discovery;
use skein_link::events::MetadataInfo;
use skein_link::{
    ConnectionAddress, Endpoint, Identity, LinkCommand, LinkError, LinkEvent, LinkSetup,
};
use skein_sim::{SimConfig, SimVehicleConfig, Simulator};
use std::net::SocketAddr;
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

impl Vehicle {
    async fn metadata(&self) -> MetadataInfo {
        eventually("events metadata", Duration::from_secs(20), || {
            self.link.with_telemetry(|t| {
                assert_eq!(t.px4_events.metadata_error, None);
                t.px4_events.metadata.clone()
            })
        })
        .await
    }

    fn texts(&self, wanted: &str) -> usize {
        let events = self.events.lock().unwrap();
        events
            .iter()
            .filter(|e| matches!(e, LinkEvent::StatusText { text, .. } if text == wanted))
            .count()
    }
}

async fn attach(endpoint: &Arc<Endpoint>, d: &Discovery, cache: &Path) -> Vehicle {
    let setup = LinkSetup {
        metadata_cache_dir: Some(cache.to_path_buf()),
        ..LinkSetup::default()
    };
    common::vehicle::attach(endpoint, d, setup).await
}

/// One simulated vehicle on a `udpin` endpoint; its discovery.
async fn one_vehicle(params: Vec<(String, f64)>) -> (Simulator, Arc<Endpoint>, Discovery) {
    let endpoint = Endpoint::open(
        ConnectionAddress::UdpIn("127.0.0.1:0".parse().unwrap()),
        Identity::default(),
    )
    .await
    .unwrap();
    let found: Arc<Mutex<Vec<Discovery>>> = Arc::default();
    let f = found.clone();
    endpoint.set_discovery(Arc::new(move |d| f.lock().unwrap().push(d)));
    let bind: SocketAddr = "127.0.0.1:0".parse().unwrap();
    let target = endpoint.local_addr().unwrap();
    let mut cfg = SimConfig::with_vehicles(vec![SimVehicleConfig {
        sysid: 1,
        bind,
        target,
    }]);
    cfg.ekf_fix_delay_s = 0.2;
    cfg.params = params;
    let sim = Simulator::start(cfg).await.unwrap();
    let d = eventually("discovered", Duration::from_secs(20), || {
        found.lock().unwrap().first().cloned()
    })
    .await;
    (sim, endpoint, d)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_metadata_is_read_over_ftp_once_then_from_the_cache() {
    let cache = tempfile::tempdir().unwrap();
    let (sim, endpoint, d) = one_vehicle(vec![]).await;
    let first = attach(&endpoint, &d, cache.path()).await;
    let t0 = Instant::now();
    let info = first.metadata().await;
    println!(
        "metadata over UDP: {info:?}, {:?} after the link started",
        t0.elapsed()
    );
    assert_eq!(info.source, "vehicle");
    assert!(info.ftp_bytes > 1000 && info.events >= 13, "{info:?}");
    // Every request reaches the simulator (the last, a TerminateSession, unanswered).
    let requests = u64::from(info.ftp_requests);
    eventually("every FTP request handled", Duration::from_secs(5), || {
        (sim.ftp_requests(1) == requests).then_some(())
    })
    .await;
    assert!(
        requests >= 6,
        "open, burst, terminate for each file: {requests}"
    );
    let files: Vec<_> = std::fs::read_dir(cache.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(files.len(), 2, "{files:?}");
    // A second link (a restarted skein, or another vehicle of the same firmware).
    first.actor.stop(None);
    let second = attach(&endpoint, &d, cache.path()).await;
    let again = second.metadata().await;
    assert_eq!(
        (again.source, again.ftp_requests, again.events_crc),
        ("cache", 0, info.events_crc)
    );
    assert_eq!(sim.ftp_requests(1), requests, "nothing read over the link");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_refused_arm_names_px4s_check_and_the_report_lists_it() {
    let cache = tempfile::tempdir().unwrap();
    let (_sim, endpoint, d) = one_vehicle(vec![("COM_ARM_ODID".into(), 2.0)]).await;
    let v = attach(&endpoint, &d, cache.path()).await;
    v.metadata().await;
    eventually("home", Duration::from_secs(10), || {
        v.link.with_telemetry(|t| t.home.is_some()).then_some(())
    })
    .await;
    let r = v.command(LinkCommand::Arm).await;
    let Err(LinkError::Rejected { statustexts, .. }) = &r else {
        panic!("{r:?}")
    };
    assert_eq!(
        statustexts.first().map(String::as_str),
        Some("Open Drone ID system missing"),
        "{r:?}"
    );
    assert!(
        statustexts.contains(&"Arming denied: Resolve system health failures first".to_string()),
        "{r:?}"
    );
    let checks = v.link.with_telemetry(|t| t.px4_arming_checks());
    assert_eq!(checks.len(), 1, "{checks:?}");
    assert_eq!(
        (checks[0].message.as_str(), checks[0].severity.as_str()),
        ("Open Drone ID system missing", "error")
    );
    assert!(checks[0].prevents_arming);
    assert!(
        checks[0]
            .description
            .starts_with("Open Drone ID system failed to report"),
        "{checks:?}"
    );
    // PX4's texts marked as events ("…\t") are shown once: from the event.
    assert_eq!(
        v.texts("Arming denied: Resolve system health failures first"),
        1
    );
    assert_eq!(
        v.texts("Preflight Fail: Open Drone ID system missing"),
        1,
        "a text without its event"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_lost_event_is_asked_for_by_its_sequence() {
    let cache = tempfile::tempdir().unwrap();
    let (sim, endpoint, d) = one_vehicle(vec![]).await;
    let v = attach(&endpoint, &d, cache.path()).await;
    v.metadata().await;
    eventually("home", Duration::from_secs(10), || {
        v.link.with_telemetry(|t| t.home.is_some()).then_some(())
    })
    .await;
    // The arm's report (summary, health summary) is lost; "Armed by" shows the gap.
    sim.drop_next_events(1, 2);
    v.command(LinkCommand::Arm).await.unwrap();
    eventually("Armed by external command", Duration::from_secs(10), || {
        (v.texts("Armed by external command") == 1).then_some(())
    })
    .await;
    let status = v.link.with_telemetry(|t| t.px4_events.clone());
    assert!(status.requested >= 2 && status.lost == 0, "{status:?}");
    assert!(
        v.link.with_telemetry(|t| t.arming_report.is_some()),
        "the report, completed from the buffer"
    );
}
