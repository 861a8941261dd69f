//! The line-based TCP stats socket of `skein sim --stats ADDR`.

mod common;

use common::*;
use skein_mavlink::dialect::MavType;
use std::time::Duration;
use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpStream;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stats_socket_commands() {
    let (sim, mut clients) = start(2, |_| {}).await;
    let c = &mut clients[0];
    c.heartbeat(MavType::MAV_TYPE_GCS).await;
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
        .await
        .expect("bind");
    let addr = listener.local_addr().expect("addr");
    let server = tokio::spawn(skein_sim::cli::serve_stats(sim.clone(), listener));

    let stream = TcpStream::connect(addr).await.expect("connect");
    let (read, mut write) = stream.into_split();
    let mut lines = BufReader::new(read).lines();
    let mut ask = async |cmd: &str| -> serde_json::Value {
        write
            .write_all(format!("{cmd}\n").as_bytes())
            .await
            .expect("write");
        let line = tokio::time::timeout(Duration::from_secs(5), lines.next_line())
            .await
            .expect("reply in time")
            .expect("read")
            .expect("a line");
        serde_json::from_str(&line).expect("one line of JSON")
    };

    // The GCS heartbeat is a UDP datagram: wait until the simulator has taken it.
    assert!(
        eventually(Duration::from_secs(5), || sim.stats()[0].frames_received
            >= 1)
        .await,
        "the heartbeat never arrived"
    );
    let stats = ask("stats").await;
    let vehicles = stats["vehicles"].as_array().expect("vehicles");
    assert_eq!(vehicles.len(), 2);
    let v1 = &vehicles[0];
    assert_eq!(v1["sysid"], 1);
    for key in [
        "setpoints_received",
        "setpoint_max_gap_ms",
        "setpoint_max_gap_offboard_ms",
        "offboard_loss_failsafes",
        "commands_received",
        "malformed_frames",
        "frames_received",
        "datagrams_sent",
        "send_drops",
    ] {
        assert!(v1[key].is_number(), "{key} missing: {v1}");
    }
    assert_eq!(v1["truth"]["mode_name"], "HOLD");
    assert_eq!(v1["truth"]["armed"], false);
    assert!(v1["truth"]["position"]["lat_deg"].is_number());
    assert!(v1["frames_received"].as_u64().expect("n") >= 1);

    assert_eq!(ask("reset").await["ok"], true);
    assert_eq!(ask("stats").await["vehicles"][0]["frames_received"], 0);
    assert_eq!(ask("silence 1 400").await["ok"], true);
    assert_eq!(ask("stats").await["vehicles"][0]["silent"], true);
    assert!(
        eventually(Duration::from_secs(3), || !sim.stats()[0].silent).await,
        "silence did not end"
    );
    assert_eq!(ask("reboot 2").await["ok"], true);
    assert_eq!(ask("kill 2").await["ok"], true);
    assert_eq!(ask("stats").await["vehicles"][1]["killed"], true);
    assert_eq!(ask("vehicles").await["vehicles"][1]["sysid"], 2);
    assert_eq!(ask("link 1 0.25 30").await["ok"], true);
    let v1 = &ask("stats").await["vehicles"][0];
    assert_eq!(v1["link_loss_fraction"], 0.25);
    assert_eq!(v1["link_latency_ms"], 30.0);
    for key in [
        "datagrams_dropped_link",
        "link_loss_effective",
        "link_latency_effective_ms",
        "link_in_flight",
    ] {
        assert!(v1[key].is_number(), "{key} missing: {v1}");
    }
    assert!(v1["setpoint_intervals"]["p99_ms"].is_number(), "{v1}");
    assert_eq!(ask("link all 0 0").await["ok"], true);
    assert_eq!(ask("stats").await["vehicles"][0]["link_latency_ms"], 0.0);
    for bad in [
        "link 1 1.5 0",
        "link 1 0.1 -5",
        "link 77 0 0",
        "link 1",
        "link x 0 0",
    ] {
        assert!(ask(bad).await["error"].is_string(), "{bad}");
    }
    let summary = ask("summary").await;
    assert_eq!(summary["vehicles"], 2, "{summary}");
    assert!(summary["modes"].is_object(), "{summary}");
    assert!(
        summary["setpoint_intervals"]["count"].is_number(),
        "{summary}"
    );
    assert!(summary["setpoint_interval_buckets"].is_array(), "{summary}");
    assert!(ask("fly me to the moon").await["error"].is_string());
    assert!(ask("silence x 1").await["error"].is_string());
    server.abort();
    sim.shutdown().await;
}
