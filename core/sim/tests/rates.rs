//! Telemetry rates: every message of px4.md's table at its rate (±20 %), the swarm
//! profile, and MAV_CMD_SET_MESSAGE_INTERVAL at run time. The tests of this file take a
//! lock so that their measurements do not compete for the CPU.
#![allow(deprecated)]

mod common;

use common::*;
use skein_mavlink::MavMessage;
use skein_mavlink::dialect::*;
use skein_sim::{TelemetryProfile, telemetry_streams};
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

static SERIAL: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

/// Rates (Hz) of every message received for `window`, from arrival times:
/// (count − 1) / (last − first).
async fn measure(c: &mut Client, window: Duration) -> BTreeMap<u32, f64> {
    let deadline = Instant::now() + window;
    let mut times: BTreeMap<u32, Vec<Instant>> = BTreeMap::new();
    while let Some(f) = c.next(deadline).await {
        times
            .entry(skein_mavlink::message_id(&f.msg))
            .or_default()
            .push(Instant::now());
    }
    times
        .into_iter()
        .map(|(id, t)| {
            let rate = if t.len() >= 2 {
                (t.len() - 1) as f64 / t[t.len() - 1].duration_since(t[0]).as_secs_f64()
            } else {
                0.0
            };
            (id, rate)
        })
        .collect()
}

fn within(rate: f64, expected: f64, tolerance: f64) -> bool {
    (rate - expected).abs() <= tolerance * expected
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_message_of_the_px4_table_at_its_rate() {
    let _serial = SERIAL.lock().await;
    let (sim, mut clients) = start(1, |_| {}).await;
    let c = &mut clients[0];
    c.wait_home().await;
    let rates = measure(c, Duration::from_secs(8)).await;
    let mut failures = Vec::new();
    for s in telemetry_streams() {
        let got = rates.get(&s.message_id).copied().unwrap_or(0.0);
        println!(
            "{:<26} expected {:>6.1} Hz, got {:>6.2} Hz",
            s.name, s.px4_rate_hz, got
        );
        if !within(got, s.px4_rate_hz, 0.2) {
            failures.push(format!(
                "{} {got:.2} Hz (expected {})",
                s.name, s.px4_rate_hz
            ));
        }
    }
    assert!(failures.is_empty(), "rates off: {failures:?}");
    // The streams' total (events and answers come in bursts: no rate of their own).
    let total: f64 = telemetry_streams()
        .iter()
        .filter_map(|s| rates.get(&s.message_id))
        .sum();
    assert!(total > 350.0 && total < 450.0, "{total} msg/s");
    sim.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn swarm_profile_rates() {
    let _serial = SERIAL.lock().await;
    let (sim, mut clients) = start(1, |cfg| cfg.telemetry = TelemetryProfile::Swarm).await;
    let c = &mut clients[0];
    c.wait_home().await;
    let rates = measure(c, Duration::from_secs(5)).await;
    for s in telemetry_streams() {
        let got = rates.get(&s.message_id).copied().unwrap_or(0.0);
        if s.swarm_rate_hz > 0.0 {
            // 0.5 Hz streams have too few samples in 5 s to measure; they must be there.
            if s.swarm_rate_hz >= 1.0 {
                assert!(within(got, s.swarm_rate_hz, 0.2), "{} at {got} Hz", s.name);
            } else {
                assert!(rates.contains_key(&s.message_id), "{} missing", s.name);
            }
        } else {
            assert!(
                !rates.contains_key(&s.message_id),
                "{} should be off",
                s.name
            );
        }
    }
    sim.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn set_message_interval_changes_rates_at_run_time() {
    let _serial = SERIAL.lock().await;
    let (sim, mut clients) = start(1, |_| {}).await;
    let c = &mut clients[0];
    c.wait_home().await;
    let set = |id: f32, us: f32| {
        (
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
            [id, us, 0.0, 0.0, 0.0, 0.0, 0.0],
        )
    };

    // ATTITUDE 100 Hz → 5 Hz; LOCAL_POSITION_NED 30 Hz → 50 Hz; GPS_RAW_INT off.
    for (id, us) in [(30.0, 200_000.0), (32.0, 20_000.0), (24.0, -1.0)] {
        let (cmd, p) = set(id, us);
        assert_eq!(c.command(cmd, p).await, MavResult::MAV_RESULT_ACCEPTED);
    }
    let rates = measure(c, Duration::from_secs(4)).await;
    assert!(within(rates[&30], 5.0, 0.2), "ATTITUDE at {}", rates[&30]);
    assert!(
        within(rates[&32], 50.0, 0.2),
        "LOCAL_POSITION_NED at {}",
        rates[&32]
    );
    assert!(!rates.contains_key(&24), "GPS_RAW_INT still sent");

    // GET_MESSAGE_INTERVAL reports it.
    let msg = c.command_long_msg(
        MavCmd::MAV_CMD_GET_MESSAGE_INTERVAL,
        [30.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        0,
    );
    c.send(&msg).await;
    let interval = c
        .wait_for(Duration::from_secs(2), |f| match &f.msg {
            MavMessage::MESSAGE_INTERVAL(m) if m.message_id == 30 => Some(m.interval_us),
            _ => None,
        })
        .await
        .expect("MESSAGE_INTERVAL");
    assert_eq!(interval, 200_000);

    // 0 restores the default; an unknown message is refused.
    let (cmd, p) = set(30.0, 0.0);
    assert_eq!(c.command(cmd, p).await, MavResult::MAV_RESULT_ACCEPTED);
    let (cmd, p) = set(9999.0, 1000.0);
    assert_eq!(c.command(cmd, p).await, MavResult::MAV_RESULT_DENIED);
    let rates = measure(c, Duration::from_secs(3)).await;
    assert!(within(rates[&30], 100.0, 0.2), "ATTITUDE at {}", rates[&30]);
    sim.shutdown().await;
}
