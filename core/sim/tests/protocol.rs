//! MAVLink protocol behaviour: over real UDP where the wire is the subject (parameters,
//! lock-on, link cut, reboot, decoding, identity, several vehicles on one target), on the
//! virtual clock where PX4's timers are ([`VirtualClient`]: STATUSTEXT gating by the GCS
//! heartbeat, the command protocol with a takeoff, arming before the EKF's fix).
#![allow(deprecated)]

mod common;

use common::*;
use skein_mavlink::dialect::*;
use skein_mavlink::{
    CommandPosition, CommandTarget, Decoder, Encoder, MavMessage, command_int, command_long,
};
use skein_model::px4::Px4Mode;
use skein_sim::client;
use skein_sim::virtual_vehicle::{GCS_COMPID, GCS_SYSID};
use skein_sim::{PX4_FLIGHT_SW_VERSION, SimConfig, SimVehicleConfig, Simulator};
use std::time::{Duration, Instant};

const SECS: fn(u64) -> Duration = Duration::from_secs;

async fn param_read_by_name(c: &mut Client, name: &str) -> PARAM_VALUE_DATA {
    let read = MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
        param_index: -1,
        target_system: c.sysid,
        target_component: 1,
        param_id: name.into(),
    });
    c.request(&read, &format!("PARAM_VALUE for {name}"), |m| match m {
        MavMessage::PARAM_VALUE(v) if v.param_id.to_str().ok() == Some(name) => Some(v.clone()),
        _ => None,
    })
    .await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn parameters_get_set_bytewise_and_list() {
    let (sim, mut clients) = start(1, |_| {}).await;
    let c = &mut clients[0];

    let v = param_read_by_name(c, "MIS_TAKEOFF_ALT").await;
    assert_eq!(v.param_value, 2.5);
    assert_eq!(v.param_type, MavParamType::MAV_PARAM_TYPE_REAL32);
    let count = v.param_count;

    // Integer parameter: bytewise int32 in the float field.
    let v = param_read_by_name(c, "COM_OBL_RC_ACT").await;
    assert_eq!(v.param_type, MavParamType::MAV_PARAM_TYPE_INT32);
    assert_eq!(v.param_value.to_bits(), 0);
    let v = param_read_by_name(c, "SYSID_THISMAV").await;
    assert_eq!(v.param_value.to_bits(), 1);
    let index = v.param_index;

    // Read by index.
    c.send(&MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
        param_index: index as i16,
        target_system: c.sysid,
        target_component: 1,
        param_id: "".into(),
    }))
    .await;
    let by_index = c
        .wait_for(SECS(2), |f| match &f.msg {
            MavMessage::PARAM_VALUE(v) if v.param_index == index => Some(v.clone()),
            _ => None,
        })
        .await
        .expect("PARAM_VALUE by index");
    assert_eq!(by_index.param_id.to_str().ok(), Some("SYSID_THISMAV"));

    // PARAM_SET is answered by PARAM_VALUE twice.
    let got = c
        .param_set("MIS_TAKEOFF_ALT", 4.0, MavParamType::MAV_PARAM_TYPE_REAL32)
        .await;
    assert_eq!(got.len(), 2, "{got:?}");
    assert!(got.iter().all(|v| v.param_value == 4.0));
    let got = c
        .param_set(
            "COM_OBL_RC_ACT",
            f32::from_bits(5),
            MavParamType::MAV_PARAM_TYPE_INT32,
        )
        .await;
    assert_eq!(got.len(), 2, "{got:?}");
    assert!(got.iter().all(
        |v| v.param_value.to_bits() == 5 && v.param_type == MavParamType::MAV_PARAM_TYPE_INT32
    ));
    assert_eq!(
        param_read_by_name(c, "COM_OBL_RC_ACT")
            .await
            .param_value
            .to_bits(),
        5
    );

    // The whole list, every index once.
    c.clear();
    c.send(&MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA {
        target_system: c.sysid,
        target_component: 1,
    }))
    .await;
    let mut seen = vec![false; usize::from(count)];
    let deadline = Instant::now() + SECS(3);
    while seen.iter().any(|s| !s) {
        let Some(f) = c.next(deadline).await else {
            break;
        };
        if let MavMessage::PARAM_VALUE(v) = f.msg {
            seen[usize::from(v.param_index)] = true;
        }
    }
    assert!(
        seen.iter().all(|s| *s),
        "missing indices in PARAM_REQUEST_LIST"
    );
    sim.shutdown().await;
}

/// Sends DO_SET_MODE and collects the ACK results and STATUSTEXTs for `window`.
async fn set_mode_collect(
    c: &mut impl GroundStation,
    mode: Px4Mode,
    window: Duration,
) -> (Vec<MavResult>, Vec<String>) {
    c.send(&set_mode_msg(c.sysid(), mode)).await;
    let deadline = c.now() + window;
    let mut acks = Vec::new();
    let mut texts = Vec::new();
    while let Some(f) = c.next(deadline).await {
        match f.msg {
            MavMessage::STATUSTEXT(t) => texts.push(t.text.to_str().unwrap_or("").to_string()),
            MavMessage::COMMAND_ACK(a) if a.command == MavCmd::MAV_CMD_DO_SET_MODE => {
                acks.push(a.result)
            }
            _ => {}
        }
    }
    (acks, texts)
}

#[tokio::test]
async fn statustext_only_while_a_gcs_heartbeat_is_fresh() {
    let mut c = start_virtual(|_| {});
    c.wait_home().await;
    use MavResult::*;
    // An onboard controller's heartbeat does not count.
    c.heartbeat(MavType::MAV_TYPE_ONBOARD_CONTROLLER).await;
    let (acks, texts) =
        set_mode_collect(&mut c, Px4Mode::Offboard, Duration::from_millis(700)).await;
    assert_eq!(
        acks,
        vec![MAV_RESULT_ACCEPTED, MAV_RESULT_TEMPORARILY_REJECTED]
    );
    assert!(texts.is_empty(), "{texts:?}");
    assert!(c.vehicle.stats().onboard_controller_connected);

    let hb_at = c.now();
    c.heartbeat(MavType::MAV_TYPE_GCS).await;
    let (acks, texts) =
        set_mode_collect(&mut c, Px4Mode::Offboard, Duration::from_millis(700)).await;
    assert_eq!(
        acks,
        vec![MAV_RESULT_ACCEPTED, MAV_RESULT_TEMPORARILY_REJECTED]
    );
    assert!(
        texts.iter().any(|t| t.contains("Offboard")),
        "expected the refusal reason, got {texts:?}"
    );
    assert!(c.vehicle.stats().gcs_connected);

    // 2.5 s after the last GCS heartbeat, STATUSTEXT stops again.
    assert!(
        c.run_until(SECS(5), |v| !v.stats().gcs_connected),
        "GCS never timed out"
    );
    assert!(c.now().duration_since(hb_at) >= Duration::from_millis(1400));
    c.run_for((hb_at + Duration::from_millis(2600)).saturating_duration_since(c.now()));
    c.clear();
    let (acks, texts) =
        set_mode_collect(&mut c, Px4Mode::Offboard, Duration::from_millis(500)).await;
    assert_eq!(
        acks,
        vec![MAV_RESULT_ACCEPTED, MAV_RESULT_TEMPORARILY_REJECTED]
    );
    assert!(texts.is_empty(), "{texts:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn locks_onto_first_sender_and_reboot_unlocks() {
    let (sim, mut clients) = start(1, |_| {}).await;
    let a = &mut clients[0];
    // Before anyone talks, telemetry goes to the configured target (A).
    assert!(a.wait_heartbeat(SECS(3), |_| true).await.is_some());

    // B talks first: the vehicle locks onto B for good.
    let mut b = Client::bind(a.peer, a.sysid, CLIENT_COMPID + 5).await;
    b.heartbeat(MavType::MAV_TYPE_ONBOARD_CONTROLLER).await;
    assert!(b.wait_heartbeat(SECS(3), |_| true).await.is_some());
    assert_eq!(
        sim.stats()[0].peer,
        Some(b.sock.local_addr().expect("addr"))
    );
    // Everything sent before the lock still on its way to A: a cut link stops the
    // vehicle's sending, and then A and B together have received all it sent.
    sim.set_silent(1, true);
    clear_through(&mut [&mut *a, &mut b], sim.stats()[0].datagrams_sent).await;
    sim.set_silent(1, false);
    // A hears nothing more, even when it talks.
    a.heartbeat(MavType::MAV_TYPE_GCS).await;
    assert!(
        a.next(Instant::now() + Duration::from_millis(600))
            .await
            .is_none()
    );
    assert_eq!(
        sim.stats()[0].peer,
        Some(b.sock.local_addr().expect("addr"))
    );

    // Reboot: sequence numbers and boot time restart, the vehicle sends to its target
    // again until someone talks.
    sim.reboot(1);
    let hb = a
        .wait_for(SECS(3), |f| match &f.msg {
            MavMessage::HEARTBEAT(_) => Some(f.seq),
            _ => None,
        })
        .await
        .expect("heartbeat after reboot at the configured target");
    // Before it, in the first step: the health report's three events and the event
    // sequence.
    assert!(hb < 10, "heartbeat sequence did not restart: {hb}");
    let boot_ms = a
        .wait_for(SECS(3), |f| match &f.msg {
            MavMessage::SYSTEM_TIME(t) => Some(t.time_boot_ms),
            _ => None,
        })
        .await
        .expect("SYSTEM_TIME");
    assert!(boot_ms < 1500, "time_boot_ms did not restart: {boot_ms}");
    assert!(sim.truth(1).expect("truth").uptime_s < 3.0);
    // The first sender after the reboot wins again.
    a.heartbeat(MavType::MAV_TYPE_GCS).await;
    assert!(
        eventually(SECS(2), || sim.stats()[0].peer
            == Some(a.sock.local_addr().expect("addr")))
        .await
    );
    sim.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn silent_link_sends_nothing_and_drops_input() {
    let (sim, mut clients) = start(1, |_| {}).await;
    let c = &mut clients[0];
    c.wait_home().await;
    sim.set_silent(1, true);
    clear_through(&mut [&mut *c], sim.stats()[0].datagrams_sent).await;
    assert!(
        c.next(Instant::now() + Duration::from_millis(500))
            .await
            .is_none()
    );
    let msg = c.command_long_msg(
        MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        0,
    );
    c.send(&msg).await;
    assert!(
        c.next(Instant::now() + Duration::from_millis(300))
            .await
            .is_none()
    );
    assert!(
        !sim.truth(1).expect("truth").armed,
        "command executed while silent"
    );
    assert!(sim.stats()[0].silent);
    assert!(sim.stats()[0].datagrams_dropped_silent >= 1);
    sim.set_silent(1, false);
    assert!(
        c.next(Instant::now() + SECS(3)).await.is_some(),
        "never heard again"
    );

    // Timed silence (the stats socket's `silence <sysid> <ms>`): nothing sent in it
    // arrives, the first frame after it is at least its length later.
    let cut = Instant::now();
    sim.silence_for(1, Duration::from_millis(400));
    clear_through(&mut [&mut *c], sim.stats()[0].datagrams_sent).await;
    assert!(c.next(cut + SECS(3)).await.is_some(), "never heard again");
    assert!(cut.elapsed() >= Duration::from_millis(400));

    // Kill: gone for good.
    sim.kill(1);
    clear_through(&mut [&mut *c], sim.stats()[0].datagrams_sent).await;
    assert!(
        c.next(Instant::now() + Duration::from_millis(500))
            .await
            .is_none()
    );
    assert!(sim.stats()[0].killed);
    sim.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn everything_sent_decodes_without_error_and_malformed_input_is_counted() {
    let (sim, mut clients) = start(1, |_| {}).await;
    let c = &mut clients[0];
    c.heartbeat(MavType::MAV_TYPE_GCS).await;
    let deadline = Instant::now() + SECS(3);
    let mut frames = 0u64;
    let mut names = std::collections::BTreeSet::new();
    while let Some(f) = c.next(deadline).await {
        assert_eq!((f.sysid, f.compid, f.version), (1, 1, 2));
        names.insert(skein_mavlink::message_name(&f.msg));
        frames += 1;
    }
    let counts = c.dec.stats().snapshot();
    assert_eq!(counts.errors(), 0, "{counts:?}");
    assert_eq!(counts.garbage_bytes, 0);
    assert!(frames > 800, "only {frames} frames in 3 s");
    assert!(names.len() >= 27, "{names:?}");

    // Garbage, a bad CRC and a truncated frame: counted, dropped, no harm.
    c.send_raw(b"definitely not mavlink").await;
    let mut enc = Encoder::new(CLIENT_SYSID, CLIENT_COMPID);
    let good = enc.encode(&client::gcs_heartbeat()).as_bytes().to_vec();
    let mut bad = good.clone();
    let n = bad.len();
    bad[n - 1] ^= 0x55;
    c.send_raw(&bad).await;
    c.send_raw(&good[..good.len() - 4]).await;
    assert!(
        eventually(SECS(2), || sim.stats()[0].malformed_frames >= 3).await,
        "malformed input not counted: {:?}",
        sim.stats()[0].decode
    );
    assert!(
        c.wait_heartbeat(SECS(2), |_| true).await.is_some(),
        "vehicle died"
    );
    sim.reset_stats();
    assert_eq!(sim.stats()[0].malformed_frames, 0);
    assert_eq!(sim.stats()[0].commands_received, 0);
    sim.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn identity_autopilot_version_home_ping_timesync() {
    let (sim, mut clients) = start(1, |_| {}).await;
    let c = &mut clients[0];
    let hb = c
        .wait_heartbeat(SECS(3), |_| true)
        .await
        .expect("heartbeat");
    assert_eq!(hb.mavtype, MavType::MAV_TYPE_QUADROTOR);
    assert_eq!(hb.autopilot, MavAutopilot::MAV_AUTOPILOT_PX4);
    assert_eq!(hb.custom_mode, 50_593_792, "boot mode is HOLD");
    assert!(
        hb.base_mode
            .contains(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED)
    );
    assert!(
        !hb.base_mode
            .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED)
    );
    assert_eq!(hb.system_status, MavState::MAV_STATE_STANDBY);

    // REQUEST_MESSAGE(AUTOPILOT_VERSION).
    let msg = c.command_long_msg(
        MavCmd::MAV_CMD_REQUEST_MESSAGE,
        [148.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        0,
    );
    let av = c
        .request(&msg, "AUTOPILOT_VERSION", |m| match m {
            MavMessage::AUTOPILOT_VERSION(v) => Some(v.clone()),
            _ => None,
        })
        .await;
    for cap in [
        MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MAVLINK2,
        MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_COMMAND_INT,
        MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED,
        MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE,
        MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_FTP,
    ] {
        assert!(av.capabilities.contains(cap), "{cap:?}");
    }
    // REQUEST_MESSAGE(COMPONENT_METADATA): PX4's general metadata, over MAVLink FTP.
    let msg = c.command_long_msg(
        MavCmd::MAV_CMD_REQUEST_MESSAGE,
        [397.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        0,
    );
    let cm = c
        .request(&msg, "COMPONENT_METADATA", |m| match m {
            MavMessage::COMPONENT_METADATA(v) => Some(v.clone()),
            _ => None,
        })
        .await;
    assert_eq!(
        cm.uri.to_str().unwrap_or_default(),
        "mftp://etc/extras/component_general.json.xz"
    );
    let files = skein_sim::component_metadata::MetadataFiles::get();
    assert_eq!(cm.file_crc, files.general_crc);
    assert_eq!(av.flight_sw_version, PX4_FLIGHT_SW_VERSION);
    assert_eq!(av.flight_sw_version >> 16, 0x0110, "v1.16");

    // GET_HOME_POSITION (410) and REQUEST_MESSAGE(HOME_POSITION).
    c.wait_home().await;
    assert_eq!(
        c.command(MavCmd::MAV_CMD_GET_HOME_POSITION, [0.0; 7]).await,
        MavResult::MAV_RESULT_ACCEPTED
    );
    let home = c.wait_home().await;
    let truth = sim.truth(1).expect("truth");
    let (lat, lon, _) = truth.home.to_mavlink();
    assert_eq!((home.latitude, home.longitude), (lat, lon));
    assert_eq!(home.x, 0.0);

    // Unsupported command.
    assert_eq!(
        c.command(
            MavCmd::MAV_CMD_DO_SET_SERVO,
            [1.0, 1500.0, 0.0, 0.0, 0.0, 0.0, 0.0]
        )
        .await,
        MavResult::MAV_RESULT_UNSUPPORTED
    );

    // TIMESYNC request → tc1 = own time, ts1 echoed, addressed to us.
    let timesync = TIMESYNC_DATA {
        ts1: 123_456_789,
        ..Default::default()
    };
    let ts = c
        .request(
            &MavMessage::TIMESYNC(timesync),
            "TIMESYNC reply",
            |m| match m {
                MavMessage::TIMESYNC(t) if t.ts1 == 123_456_789 => Some(t.clone()),
                _ => None,
            },
        )
        .await;
    assert!(ts.tc1 > 0);
    assert_eq!(ts.target_system, CLIENT_SYSID);

    // PING request (to every system) → echoed with our ids.
    let ping = PING_DATA {
        time_usec: 42,
        seq: 7,
        ..Default::default()
    };
    let ping = c
        .request(&MavMessage::PING(ping), "PING reply", |m| {
            let MavMessage::PING(p) = m else { return None };
            (p.target_system == CLIENT_SYSID).then(|| p.clone())
        })
        .await;
    assert_eq!(
        (ping.seq, ping.time_usec, ping.target_component),
        (7, 42, CLIENT_COMPID)
    );
    sim.shutdown().await;
}

/// MAV_CMD_NAV_TAKEOFF to `altitude_amsl_m` (param 7) for `to`, transmission number
/// `confirmation`.
fn takeoff_to(to: CommandTarget, altitude_amsl_m: f64, confirmation: u8) -> MavMessage {
    let nan = f32::NAN;
    command_long(
        to,
        MavCmd::MAV_CMD_NAV_TAKEOFF,
        [0.0, 0.0, 0.0, nan, nan, nan, altitude_amsl_m as f32],
        confirmation,
    )
}

#[tokio::test]
async fn commands_honour_targets_and_retransmissions_do_not_execute_twice() {
    let mut c = start_virtual(|_| {});
    let home = c.wait_home().await;
    let origin_alt = f64::from(home.altitude) / 1000.0;

    // Addressed to another system: ignored, no ACK.
    let arm = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    let elsewhere = CommandTarget::new(42, 1);
    c.send(&command_long(
        elsewhere,
        MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        arm,
        0,
    ))
    .await;
    assert!(
        c.wait_ack(
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            Duration::from_millis(500)
        )
        .await
        .is_none()
    );
    assert!(!c.vehicle.truth().armed);

    // Broadcast (target 0) works; the ACK is addressed to the sender.
    c.send(&takeoff_to(CommandTarget::new(0, 0), origin_alt + 3.0, 0))
        .await;
    let ack = c
        .wait_for(SECS(2), |f| match &f.msg {
            MavMessage::COMMAND_ACK(a) if a.command == MavCmd::MAV_CMD_NAV_TAKEOFF => {
                Some(a.clone())
            }
            _ => None,
        })
        .await
        .expect("takeoff ACK");
    assert_eq!(ack.result, MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(
        (ack.target_system, ack.target_component),
        (GCS_SYSID, GCS_COMPID)
    );

    // A retransmission (confirmation 1) with another altitude is answered again but not
    // executed again: the vehicle climbs to the first altitude.
    let autopilot = CommandTarget::new(c.sysid(), 1);
    c.send(&takeoff_to(autopilot, origin_alt + 6.0, 1)).await;
    assert_eq!(
        c.wait_ack(MavCmd::MAV_CMD_NAV_TAKEOFF, SECS(2)).await,
        Some(MavResult::MAV_RESULT_ACCEPTED)
    );
    assert_eq!(c.arm(true).await, MavResult::MAV_RESULT_ACCEPTED);
    assert!(
        c.wait_mode(Px4Mode::Hold, SECS(10)).await,
        "takeoff never completed"
    );
    let z = c.vehicle.truth().local_ned_m.down_m;
    assert!(
        (z + 3.0).abs() < 0.4,
        "climbed to {z}, the retransmission was executed"
    );

    // COMMAND_INT works too (NAV_LAND).
    c.send(&command_int(
        autopilot,
        MavCmd::MAV_CMD_NAV_LAND,
        [0.0, 0.0, 0.0, f32::NAN],
        CommandPosition {
            frame: MavFrame::MAV_FRAME_GLOBAL,
            x: 0,
            y: 0,
            z: f32::NAN,
        },
    ))
    .await;
    assert_eq!(
        c.wait_ack(MavCmd::MAV_CMD_NAV_LAND, SECS(2)).await,
        Some(MavResult::MAV_RESULT_ACCEPTED)
    );
    assert!(c.wait_mode(Px4Mode::Land, SECS(2)).await);
    // Disarming in the air is refused unless forced.
    assert_eq!(c.arm(false).await, MavResult::MAV_RESULT_DENIED);
    assert!(c.vehicle.truth().armed);
    assert!(c.vehicle.stats().commands_received >= 5);
}

#[tokio::test]
async fn arming_refused_until_the_ekf_has_a_position() {
    let mut c = start_virtual(|cfg| cfg.ekf_fix_delay_s = 1.5);
    let gps = c
        .wait_for(SECS(2), |f| match &f.msg {
            MavMessage::GPS_RAW_INT(g) => Some(g.fix_type),
            _ => None,
        })
        .await
        .expect("GPS_RAW_INT");
    assert_eq!(gps, GpsFixType::GPS_FIX_TYPE_NO_FIX);
    assert_eq!(
        c.arm(true).await,
        MavResult::MAV_RESULT_TEMPORARILY_REJECTED
    );
    c.wait_home().await;
    let fix = c
        .wait_for(SECS(2), |f| match &f.msg {
            MavMessage::GPS_RAW_INT(g) => Some(g.fix_type),
            _ => None,
        })
        .await
        .expect("GPS_RAW_INT");
    assert_eq!(fix, GpsFixType::GPS_FIX_TYPE_3D_FIX);
    assert_eq!(c.arm(true).await, MavResult::MAV_RESULT_ACCEPTED);
    // Forced disarm works on the ground too.
    assert_eq!(
        c.command(
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            [0.0, 21196.0, 0.0, 0.0, 0.0, 0.0, 0.0]
        )
        .await,
        MavResult::MAV_RESULT_ACCEPTED
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn vehicles_share_one_target_and_have_their_own_origins() {
    let sock = tokio::net::UdpSocket::bind("127.0.0.1:0")
        .await
        .expect("bind");
    let target = sock.local_addr().expect("addr");
    let vehicles = (1..=3)
        .map(|sysid| SimVehicleConfig {
            sysid,
            bind: "127.0.0.1:0".parse().expect("addr"),
            target,
        })
        .collect();
    let mut cfg = SimConfig::with_vehicles(vehicles);
    cfg.ekf_fix_delay_s = 0.0;
    cfg.spacing_m = 5.0;
    let sim = Simulator::start(cfg).await.expect("start");
    let mut dec = Decoder::default();
    let mut seen = std::collections::BTreeMap::new();
    let mut buf = vec![0u8; 65536];
    let deadline = Instant::now() + SECS(3);
    while seen.len() < 3 && Instant::now() < deadline {
        let Ok(Ok((n, _))) =
            tokio::time::timeout(Duration::from_millis(500), sock.recv_from(&mut buf)).await
        else {
            continue;
        };
        dec.decode_datagram(&buf[..n], |f| {
            if let MavMessage::GLOBAL_POSITION_INT(g) = f.msg {
                seen.insert(f.sysid, (g.lat, g.lon));
            }
        });
    }
    assert_eq!(seen.len(), 3, "{seen:?}");
    // Distinct geodetic positions, each vehicle at its own local origin.
    assert_ne!(seen[&1], seen[&2]);
    for sysid in 1..=3 {
        let t = sim.truth(sysid).expect("truth");
        assert_eq!(t.local_ned_m.norm(), 0.0);
    }
    let a = sim.truth(1).expect("truth").position;
    let b = sim.truth(2).expect("truth").position;
    let d = skein_model::geo::NedFrame::new(a).to_ned(&b);
    assert!((d.norm() - 5.0).abs() < 0.01, "spacing {d:?}");
    sim.shutdown().await;
}
