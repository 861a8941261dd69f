//! The flight log and MAVLink's log protocol as PX4 v1.16 serves them
//! (`mavlink_log_handler`): one ULog per armed flight in PX4's formats, listed with
//! LOG_REQUEST_LIST and downloaded with LOG_REQUEST_DATA. The log's content, the
//! protocol's corner cases and its pacing on the virtual clock ([`VirtualClient`]). Over
//! real UDP, through a link cut, skein's own download drives it (`tests/e2e_swarm.rs`).
#![allow(deprecated)]

mod common;

use common::*;
use skein_mavlink::dialect::*;
use skein_mavlink::{CommandPosition, CommandTarget, MavMessage, command_int};
use skein_model::geo::{Ned, NedFrame};
use skein_model::px4::Px4Mode;
use skein_sim::{FLIGHT_LOGS_KEPT, PX4_FLIGHT_SW_VERSION};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

const SECS: fn(u64) -> Duration = Duration::from_secs;
/// Take-off and land at PX4's defaults (MIS_TAKEOFF_ALT, here).
const AT_DEFAULTS: [f32; 7] = [0.0, 0.0, 0.0, f32::NAN, f32::NAN, f32::NAN, f32::NAN];
/// LOG_REQUEST_DATA's `count` for "to the end".
const ALL: u32 = u32::MAX;

fn list_request(sysid: u8, start: u16, end: u16) -> MavMessage {
    MavMessage::LOG_REQUEST_LIST(LOG_REQUEST_LIST_DATA {
        start,
        end,
        target_system: sysid,
        target_component: 1,
    })
}

fn data_request(sysid: u8, id: u16, ofs: u32, count: u32) -> MavMessage {
    MavMessage::LOG_REQUEST_DATA(LOG_REQUEST_DATA_DATA {
        ofs,
        count,
        id,
        target_system: sysid,
        target_component: 1,
    })
}

/// Sends a LOG_REQUEST_LIST from `start` to `end`; the LOG_ENTRYs that answer within
/// 2 s (until one for every log from `start`, as `num_logs` says).
async fn list(c: &mut impl GroundStation, start: u16, end: u16) -> Vec<LOG_ENTRY_DATA> {
    let sysid = c.sysid();
    c.send(&list_request(sysid, start, end)).await;
    let mut entries: Vec<LOG_ENTRY_DATA> = Vec::new();
    let deadline = c.now() + SECS(2);
    while let Some(f) = c.next(deadline).await {
        if let MavMessage::LOG_ENTRY(e) = f.msg {
            let expected = usize::from(e.num_logs.saturating_sub(start));
            entries.push(e);
            if entries.len() >= expected {
                break;
            }
        }
    }
    entries
}

/// The LOG_DATA chunks that arrive until `bytes` bytes came or `quiet` passed without
/// one; other frames are dropped.
async fn chunks(c: &mut impl GroundStation, bytes: usize, quiet: Duration) -> Vec<LOG_DATA_DATA> {
    let mut got: Vec<LOG_DATA_DATA> = Vec::new();
    let mut n = 0;
    while n < bytes {
        let deadline = c.now() + quiet;
        let Some(chunk) = c
            .wait_for(deadline.duration_since(c.now()), |f| match &f.msg {
                MavMessage::LOG_DATA(d) => Some(d.clone()),
                _ => None,
            })
            .await
        else {
            break;
        };
        n += usize::from(chunk.count);
        got.push(chunk);
    }
    got
}

/// Sends LOG_REQUEST_DATA and returns the bytes of the chunks that answer: contiguous
/// from `ofs`, 90 bytes each but the last.
async fn download(
    c: &mut impl GroundStation,
    id: u16,
    ofs: u32,
    count: u32,
    size: usize,
) -> Vec<u8> {
    let sysid = c.sysid();
    c.send(&data_request(sysid, id, ofs, count)).await;
    let want = (size - ofs as usize).min(count as usize);
    let got = chunks(c, want, SECS(2)).await;
    reassemble(&got, id, ofs)
}

/// The bytes of `got`, checked contiguous from `ofs`, of log `id`, 90 bytes a chunk but
/// the last.
fn reassemble(got: &[LOG_DATA_DATA], id: u16, ofs: u32) -> Vec<u8> {
    let mut bytes = Vec::new();
    for (i, d) in got.iter().enumerate() {
        assert_eq!(d.id, id);
        assert_eq!(
            d.ofs as usize,
            ofs as usize + bytes.len(),
            "chunk {i} not contiguous"
        );
        if i + 1 < got.len() {
            assert_eq!(d.count, 90, "chunk {i} short");
        }
        bytes.extend_from_slice(&d.data[..usize::from(d.count)]);
    }
    bytes
}

/// True when no LOG_DATA arrives within `window`.
async fn no_log_data(c: &mut impl GroundStation, window: Duration) -> bool {
    c.wait_for(window, |f| {
        matches!(f.msg, MavMessage::LOG_DATA(_)).then_some(())
    })
    .await
    .is_none()
}

/// DO_REPOSITION to `north_m`, `east_m` of the vehicle's origin, `alt_m` above home.
fn reposition(
    c: &impl GroundStation,
    origin: skein_model::geo::GeoPoint,
    north_m: f64,
    east_m: f64,
    alt_m: f32,
) -> MavMessage {
    let (lat, lon, _) = NedFrame::new(origin)
        .to_geo(Ned::new(north_m, east_m, 0.0))
        .to_mavlink();
    command_int(
        CommandTarget::new(c.sysid(), 1),
        MavCmd::MAV_CMD_DO_REPOSITION,
        [-1.0, 1.0, 0.0, f32::NAN],
        CommandPosition {
            frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            x: lat,
            y: lon,
            z: alt_m,
        },
    )
}

/// Takes off to MIS_TAKEOFF_ALT, flies to `north_m` north at that height, lands and
/// waits until disarmed; panics if a step fails. `origin` is the vehicle's local origin.
async fn fly(c: &mut impl GroundStation, origin: skein_model::geo::GeoPoint, north_m: f64) {
    c.heartbeat(MavType::MAV_TYPE_GCS).await;
    assert_eq!(
        c.command(MavCmd::MAV_CMD_NAV_TAKEOFF, AT_DEFAULTS).await,
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert_eq!(c.arm(true).await, MavResult::MAV_RESULT_ACCEPTED);
    assert!(
        c.wait_mode(Px4Mode::Hold, SECS(10)).await,
        "take-off never completed"
    );
    let msg = reposition(&*c, origin, north_m, 0.0, 2.5);
    c.send(&msg).await;
    assert_eq!(
        c.wait_ack(MavCmd::MAV_CMD_DO_REPOSITION, SECS(3)).await,
        Some(MavResult::MAV_RESULT_ACCEPTED)
    );
    let there = c
        .wait_local(SECS(20), |p| {
            (f64::from(p.x) - north_m).abs() < 0.3 && p.vx.abs() < 0.2
        })
        .await;
    assert!(there.is_some(), "never reached {north_m} m north");
    c.heartbeat(MavType::MAV_TYPE_GCS).await;
    assert_eq!(
        c.command(MavCmd::MAV_CMD_NAV_LAND, AT_DEFAULTS).await,
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert!(
        c.wait_armed(false, SECS(30)).await,
        "never landed and disarmed"
    );
}

/// Checks the flight in `log` went up to the take-off altitude (2.5 m), `north_m` north
/// (the overshoot of PX4's position control allowed) and landed where the vehicle truly
/// is (`landed`, local NED, m).
fn assert_flew(log: &ULog, north_m: f64, landed: Ned) {
    let z = log.series("vehicle_local_position", "z");
    let x = log.series("vehicle_local_position", "x");
    assert!(z.len() > 20, "{} samples", z.len());
    let top = z.iter().fold(f64::INFINITY, |a, b| a.min(*b));
    assert!((-top - 2.5).abs() < 0.3, "highest {:.2} m", -top);
    let far = x.iter().fold(f64::NEG_INFINITY, |a, b| a.max(*b));
    assert!(
        far > north_m - 0.3 && far < north_m + 1.0,
        "furthest north {far:.2} m"
    );
    let end = x.last().expect("samples");
    assert!(
        (end - landed.north_m).abs() < 0.05,
        "logged {end:.2} m north, landed {:.2}",
        landed.north_m
    );
    assert!(
        z.last().expect("samples").abs() < 0.1,
        "not landed at the end"
    );
    assert!(z[0].abs() < 0.1, "not on the ground at the start");
}

/// Bytes of the one log of a virtual vehicle.
fn only_log(c: &VirtualClient) -> Vec<u8> {
    let logs = c.vehicle.flight_logs();
    assert_eq!(logs.len(), 1);
    logs[0].bytes.to_vec()
}

#[tokio::test]
async fn a_flight_is_logged_from_arming_to_disarming_in_px4_formats() {
    let mut c = start_virtual(|_| {});
    let origin = c.vehicle.truth().local_origin;
    c.wait_home().await;
    assert!(c.vehicle.flight_logs().is_empty(), "a log before arming");
    let armed_at_us = (c.vehicle.time_s() * 1e6).round();
    // `fly` arms right after the take-off command, in the same instant.
    fly(&mut c, origin, 8.0).await;
    let logs = c.vehicle.flight_logs();
    assert_eq!(logs.len(), 1, "one log per flight");
    let wall = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .expect("clock")
        .as_secs();
    assert!(
        u64::from(logs[0].time_utc).abs_diff(wall) < 60,
        "time_utc {}",
        logs[0].time_utc
    );
    let log = ULog::parse(&logs[0].bytes);

    assert!(
        (log.timestamp_us as f64 - armed_at_us).abs() < 1.0,
        "header timestamp"
    );
    assert_eq!(log.info_str("char[3] sys_name").as_deref(), Some("PX4"));
    let ver_sw = log.info_str("char[40] ver_sw").expect("ver_sw");
    assert!(ver_sw.bytes().all(|b| b.is_ascii_hexdigit()), "{ver_sw}");
    assert_eq!(
        log.infos.get("uint32_t ver_sw_release"),
        Some(&PX4_FLIGHT_SW_VERSION.to_le_bytes().to_vec())
    );
    assert_eq!(
        log.format_texts["vehicle_local_position"],
        "vehicle_local_position:uint64_t timestamp;uint64_t timestamp_sample;float x;float y;\
         float z;float vx;float vy;float vz;float ax;float ay;float az;float heading;\
         bool xy_valid;bool z_valid;bool v_xy_valid;bool v_z_valid;uint8_t[4] _padding0;"
    );
    assert_eq!(
        log.format_texts["vehicle_attitude"],
        "vehicle_attitude:uint64_t timestamp;uint64_t timestamp_sample;float[4] q;\
         float[4] delta_q_reset;uint8_t quat_reset_counter;uint8_t[7] _padding0;"
    );
    assert_eq!(
        log.format_texts["vehicle_local_position_setpoint"],
        "vehicle_local_position_setpoint:uint64_t timestamp;float x;float y;float z;\
         float vx;float vy;float vz;float yaw;uint8_t[4] _padding0;"
    );
    // Definitions, then the subscriptions, then the data.
    let types = String::from_utf8(log.message_types.clone()).expect("ascii");
    assert!(types.starts_with("BIIIIFFFAAAD"), "{}", &types[..20]);
    assert!(types[11..].bytes().all(|t| t == b'D'));

    // Fixed rates on the 100 Hz step, from arming to disarming.
    let disarmed_at_us = c.vehicle.time_s() * 1e6;
    for (topic, interval_us) in [
        ("vehicle_local_position", 50_000.0),
        ("vehicle_attitude", 50_000.0),
        ("vehicle_local_position_setpoint", 100_000.0),
    ] {
        let t = log.series(topic, "timestamp");
        assert!(t[0] - armed_at_us <= 10_000.0, "{topic} starts at {}", t[0]);
        assert!(
            t.windows(2).all(|w| w[1] - w[0] == interval_us),
            "{topic} rate"
        );
        assert!(*t.last().expect("samples") < disarmed_at_us);
    }
    assert!(disarmed_at_us - log.series("vehicle_attitude", "timestamp").last().unwrap() < 1.5e6);
    for q in log.data["vehicle_attitude"].iter() {
        let n: f64 = (0..4).map(|i| q[&format!("q[{i}]")].powi(2)).sum();
        assert!((n - 1.0).abs() < 1e-4);
    }
    assert_flew(&log, 8.0, c.vehicle.truth().local_ned_m);
    let sp_z = log.series("vehicle_local_position_setpoint", "z");
    assert!(
        sp_z.iter().any(|z| (z + 2.5).abs() < 0.05),
        "no setpoint at 2.5 m"
    );
}

#[tokio::test]
async fn one_log_per_armed_flight_kept_across_reboots_bounded_and_erased() {
    let mut c = start_virtual(|_| {});
    c.wait_home().await;
    let mut arm_times_us = Vec::new();
    for _ in 0..3 {
        arm_times_us.push((c.vehicle.time_s() * 1e6).round());
        assert_eq!(c.arm(true).await, MavResult::MAV_RESULT_ACCEPTED);
        c.run_for(Duration::from_millis(300));
        assert_eq!(c.arm(false).await, MavResult::MAV_RESULT_ACCEPTED);
        c.run_for(Duration::from_millis(100));
    }
    assert_eq!(c.vehicle.flight_logs().len(), 3);
    c.vehicle.reboot();
    let rebooted_at = c.vehicle.time_s();
    c.clear();
    let logs = c.vehicle.flight_logs();
    assert_eq!(logs.len(), 3, "logs lost in the reboot");
    for (log, t) in logs.iter().zip(&arm_times_us) {
        assert_eq!(ULog::parse(&log.bytes).timestamp_us as f64, *t);
    }
    let entries = list(&mut c, 0, 0xFFFF).await;
    assert_eq!(entries.len(), 3);
    for (i, (e, log)) in entries.iter().zip(&logs).enumerate() {
        assert_eq!(
            (e.id, e.num_logs, e.last_log_num, e.size, e.time_utc),
            (i as u16, 3, 3, log.bytes.len() as u32, log.time_utc)
        );
    }

    // Only the newest FLIGHT_LOGS_KEPT stay: the ten flights after the reboot (their
    // headers on the new boot clock).
    c.wait_home().await;
    let mut arm_times_us = Vec::new();
    for _ in 0..FLIGHT_LOGS_KEPT {
        arm_times_us.push(((c.vehicle.time_s() - rebooted_at) * 1e6).round());
        assert_eq!(c.arm(true).await, MavResult::MAV_RESULT_ACCEPTED);
        c.run_for(Duration::from_millis(100));
        assert_eq!(c.arm(false).await, MavResult::MAV_RESULT_ACCEPTED);
    }
    let logs = c.vehicle.flight_logs();
    assert_eq!(logs.len(), FLIGHT_LOGS_KEPT);
    for (log, t) in logs.iter().zip(&arm_times_us) {
        assert_eq!(ULog::parse(&log.bytes).timestamp_us as f64, *t);
    }

    // LOG_ERASE: no log; PX4 v1.16 then answers a listing with no entry at all.
    c.send(&MavMessage::LOG_ERASE(LOG_ERASE_DATA {
        target_system: 1,
        target_component: 1,
    }))
    .await;
    assert!(c.vehicle.flight_logs().is_empty());
    let entries = list(&mut c, 0, 0xFFFF).await;
    assert!(entries.is_empty(), "{entries:?}");
}

#[tokio::test]
async fn log_protocol_follows_px4_mavlink_log_handler() {
    let mut c = start_virtual(|_| {});
    c.wait_home().await;
    assert_eq!(c.arm(true).await, MavResult::MAV_RESULT_ACCEPTED);
    c.run_for(SECS(3));
    assert_eq!(c.arm(false).await, MavResult::MAV_RESULT_ACCEPTED);
    let bytes = only_log(&c);
    let size = bytes.len();
    assert!(size > 2000, "{size} bytes");

    // No data before a listing; nothing for another vehicle.
    c.send(&data_request(1, 0, 0, ALL)).await;
    assert!(no_log_data(&mut c, SECS(1)).await, "data without a listing");
    c.send(&list_request(7, 0, 0xFFFF)).await;
    let entry = c
        .wait_for(SECS(1), |f| {
            matches!(f.msg, MavMessage::LOG_ENTRY(_)).then_some(())
        })
        .await;
    assert!(entry.is_none(), "answered a listing for another vehicle");
    let entries = list(&mut c, 0, 0xFFFF).await;
    assert_eq!(entries.len(), 1);
    assert_eq!((entries[0].size as usize, entries[0].num_logs), (size, 1));

    // The whole log, paced: 8 chunks a 10 ms step, 90 bytes each but the last.
    c.clear();
    c.send(&data_request(1, 0, 0, ALL)).await;
    let mut got = Vec::new();
    let mut per_step = Vec::new();
    while got
        .iter()
        .map(|d: &LOG_DATA_DATA| usize::from(d.count))
        .sum::<usize>()
        < size
    {
        let step: Vec<LOG_DATA_DATA> = c
            .vehicle
            .step_frames()
            .into_iter()
            .filter_map(|f| match f.msg {
                MavMessage::LOG_DATA(d) => Some(d),
                _ => None,
            })
            .collect();
        per_step.push(step.len());
        got.extend(step);
        assert!(per_step.len() < 10_000, "download never ended");
    }
    assert_eq!(reassemble(&got, 0, 0), bytes);
    let full_steps = &per_step[..per_step.len() - 1];
    assert!(full_steps.iter().all(|n| *n == 8), "{per_step:?}");
    assert!(no_log_data(&mut c, SECS(1)).await, "data after the end");

    // A middle range in whole chunks: 500 bytes from 1000 are six chunks, to 1540.
    assert_eq!(
        download(&mut c, 0, 1000, 540, size).await,
        bytes[1000..1540]
    );
    c.send(&data_request(1, 0, 1000, 500)).await;
    let got = chunks(&mut c, size, SECS(1)).await;
    assert_eq!(reassemble(&got, 0, 1000), bytes[1000..1540]);
    // `count` 0 still sends one chunk.
    c.send(&data_request(1, 0, 5000, 0)).await;
    let got = chunks(&mut c, size, SECS(1)).await;
    assert_eq!(reassemble(&got, 0, 5000), bytes[5000..5090]);
    // The end of the log: a short last chunk.
    let tail = download(&mut c, 0, size as u32 - 100, ALL, size).await;
    assert_eq!(tail, bytes[size - 100..]);
    // Nothing past the end, nothing for an unknown id.
    for (id, ofs, count) in [(0, size as u32, ALL), (1, 0, ALL)] {
        c.send(&data_request(1, id, ofs, count)).await;
        assert!(
            no_log_data(&mut c, SECS(1)).await,
            "data for {id} {ofs} {count}"
        );
    }
    // A new request replaces the one in progress.
    c.send(&data_request(1, 0, 0, ALL)).await;
    c.step();
    c.clear();
    assert_eq!(
        download(&mut c, 0, 5000, 180, size).await,
        bytes[5000..5180]
    );
    assert!(no_log_data(&mut c, SECS(1)).await);
    // So does a listing.
    c.send(&data_request(1, 0, 0, ALL)).await;
    c.step();
    assert_eq!(list(&mut c, 0, 0xFFFF).await.len(), 1);
    assert!(
        no_log_data(&mut c, SECS(1)).await,
        "the listing did not stop the data"
    );

    // Every listing lists anew, from `start` to the last log (PX4 ignores `end`).
    assert_eq!(c.arm(true).await, MavResult::MAV_RESULT_ACCEPTED);
    c.run_for(SECS(1));
    assert_eq!(c.arm(false).await, MavResult::MAV_RESULT_ACCEPTED);
    let later = list(&mut c, 1, 0xFFFF).await;
    assert_eq!(
        later
            .iter()
            .map(|e| (e.id, e.num_logs, e.last_log_num))
            .collect::<Vec<_>>(),
        [(1, 2, 2)]
    );
    let all = list(&mut c, 0, 0).await;
    assert_eq!(
        all.iter()
            .map(|e| (e.id, e.last_log_num))
            .collect::<Vec<_>>(),
        [(0, 0), (1, 0)]
    );

    // LOG_REQUEST_END stops the data; the listing stays, a new request is served.
    c.send(&data_request(1, 0, 0, ALL)).await;
    c.step();
    c.send(&MavMessage::LOG_REQUEST_END(LOG_REQUEST_END_DATA {
        target_system: 1,
        target_component: 1,
    }))
    .await;
    c.clear();
    assert!(
        no_log_data(&mut c, SECS(1)).await,
        "data after LOG_REQUEST_END"
    );
    assert_eq!(download(&mut c, 0, 180, 180, size).await, bytes[180..360]);
}
