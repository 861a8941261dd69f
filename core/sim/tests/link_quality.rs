//! Simulated link quality (`Simulator::set_link_quality`, the stats socket's `link`):
//! real loss and real latency on the wire, in both directions, and the setpoint-interval
//! histogram the benchmark reads. The tests of this file take a lock so that their
//! measurements do not compete for the CPU.
#![allow(deprecated)]

mod common;

use common::*;
use skein_mavlink::MavMessage;
use skein_mavlink::dialect::*;
use std::time::{Duration, Instant};

static SERIAL: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

/// Frames received per second over `window`.
async fn frame_rate(c: &mut Client, window: Duration) -> f64 {
    let start = Instant::now();
    let deadline = start + window;
    let mut frames = 0u64;
    while c.next(deadline).await.is_some() {
        frames += 1;
    }
    frames as f64 / start.elapsed().as_secs_f64()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn half_loss_halves_the_telemetry_the_client_sees() {
    let _serial = SERIAL.lock().await;
    let (sim, mut clients) = start(1, |cfg| cfg.seed = 42).await;
    let c = &mut clients[0];
    c.wait_home().await;
    let clean = frame_rate(c, Duration::from_secs(3)).await;
    assert!(clean > 300.0, "PX4 onboard set: {clean} msg/s");

    assert!(sim.set_link_quality(1, 0.5, 0.0));
    assert!(!sim.set_link_quality(99, 0.5, 0.0), "no such vehicle");
    sim.reset_stats();
    c.clear();
    let lossy = frame_rate(c, Duration::from_secs(4)).await;
    let ratio = lossy / clean;
    println!("clean {clean:.0} msg/s, 50 % loss {lossy:.0} msg/s, ratio {ratio:.3}");
    assert!((0.4..=0.6).contains(&ratio), "ratio {ratio}");

    let st = &sim.stats()[0];
    assert_eq!(st.link_loss_fraction, 0.5);
    assert_eq!(st.link_latency_ms, 0.0);
    assert!(
        st.datagrams_dropped_link > 100,
        "{}",
        st.datagrams_dropped_link
    );
    assert!(
        (0.4..=0.6).contains(&st.link_loss_effective),
        "effective loss {}",
        st.link_loss_effective
    );

    // Inbound too: half of 200 heartbeats reach the vehicle.
    sim.reset_stats();
    for _ in 0..200 {
        c.heartbeat(MavType::MAV_TYPE_GCS).await;
    }
    // Every heartbeat has crossed the link once the loss draws add up to 200.
    assert!(
        eventually(Duration::from_secs(5), || {
            let st = &sim.stats()[0];
            st.frames_received + st.datagrams_dropped_link_inbound >= 200
        })
        .await,
        "heartbeats still in the socket"
    );
    let received = sim.stats()[0].frames_received;
    assert!(
        (60..=140).contains(&received),
        "{received} of 200 heartbeats"
    );

    // Restored: everything again.
    assert!(sim.set_link_quality(1, 0.0, 0.0));
    c.clear();
    let restored = frame_rate(c, Duration::from_secs(2)).await;
    assert!(restored / clean > 0.85, "{restored} vs {clean}");
    sim.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn latency_delays_both_directions() {
    let _serial = SERIAL.lock().await;
    let (sim, mut clients) = start(1, |_| {}).await;
    let c = &mut clients[0];
    c.wait_home().await;
    let interval = |c: &Client| {
        c.command_long_msg(
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
            [30.0, 20_000.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            0,
        )
    };

    // A clean round trip for reference.
    let msg = interval(c);
    let t = Instant::now();
    c.send(&msg).await;
    let ack = c
        .wait_ack(MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL, Duration::from_secs(3))
        .await;
    assert_eq!(ack, Some(MavResult::MAV_RESULT_ACCEPTED));
    let clean_rtt = t.elapsed();

    assert!(sim.set_link_quality(1, 0.0, 200.0));
    sim.reset_stats();
    // Time a command (the ACK is picked out of the telemetry still in flight).
    c.clear();
    let msg = interval(c);
    let t = Instant::now();
    c.send(&msg).await;
    let ack = c
        .wait_ack(MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL, Duration::from_secs(3))
        .await;
    let rtt = t.elapsed();
    println!("round trip: clean {clean_rtt:?}, with 200 ms each way {rtt:?}");
    assert_eq!(ack, Some(MavResult::MAV_RESULT_ACCEPTED));
    assert!(rtt >= Duration::from_millis(400), "{rtt:?}");
    assert!(rtt < Duration::from_secs(2), "{rtt:?}");

    // Telemetry keeps its rate (delayed, not thinned), in order.
    let mut last_ms = 0;
    let deadline = Instant::now() + Duration::from_secs(1);
    let mut seen = 0;
    while let Some(f) = c.next(deadline).await {
        if let MavMessage::ATTITUDE(a) = f.msg {
            assert!(a.time_boot_ms >= last_ms, "reordered");
            last_ms = a.time_boot_ms;
            seen += 1;
        }
    }
    assert!(seen >= 30, "{seen} ATTITUDE in 1 s at 50 Hz");
    let st = &sim.stats()[0];
    assert_eq!(st.link_latency_ms, 200.0);
    assert!(
        (195.0..260.0).contains(&st.link_latency_effective_ms),
        "effective latency {} ms",
        st.link_latency_effective_ms
    );
    assert_eq!(st.datagrams_dropped_link, 0);
    assert!(st.link_in_flight > 0, "telemetry in the delay line");
    sim.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn setpoint_intervals_are_recorded_per_vehicle_and_in_total() {
    let _serial = SERIAL.lock().await;
    let (sim, clients) = start(2, |_| {}).await;
    let streams: Vec<Streamer> = clients
        .iter()
        .map(|c| Streamer::start(c, position_setpoint(c.sysid, 0.0, 0.0, -2.0), 50.0))
        .collect();
    // Both streams arriving, then a fresh window of at least 150 intervals.
    assert!(
        eventually(Duration::from_secs(5), || sim
            .stats()
            .iter()
            .all(|v| v.setpoint_intervals.count > 0))
        .await
    );
    sim.reset_stats();
    assert!(
        eventually(Duration::from_secs(10), || sim.setpoint_intervals().count()
            >= 150)
        .await
    );
    let summary = sim.summary();
    for s in streams {
        s.stop();
    }
    let all = summary.setpoint_intervals;
    println!("{all:?}");
    assert_eq!(summary.vehicles, 2);
    assert!(all.count >= 150, "{all:?}");
    assert!((15.0..=25.0).contains(&all.p50_ms), "{all:?}");
    assert!(
        all.max_ms >= all.p99_ms && all.p99_ms >= all.p50_ms,
        "{all:?}"
    );
    let in_buckets: u64 = summary
        .setpoint_interval_buckets
        .iter()
        .map(|b| b.count)
        .sum();
    assert_eq!(in_buckets, all.count);
    assert!(
        sim.setpoint_intervals().count() >= all.count,
        "counts only grow"
    );
    let per_vehicle: u64 = sim.stats().iter().map(|v| v.setpoint_intervals.count).sum();
    assert!(per_vehicle >= all.count, "counts only grow");
    sim.reset_stats();
    assert_eq!(sim.setpoint_intervals().count(), 0);
    sim.shutdown().await;
}
