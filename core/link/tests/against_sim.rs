//! The link against the simulator over real UDP: shared-endpoint demultiplexing, loss and
//! recovery, reboots, the command, parameter and mission protocols (the fence on the
//! autopilot), telemetry profiles, MAVLink 2 signing.

mod common;

use common::vehicle::{Vehicle, attach};
use common::{eventually, heartbeat};
use skein_link::endpoint::Discovery;
use skein_link::{
    ConnectionAddress, Endpoint, Identity, LinkCommand, LinkError, LinkEvent, LinkSetup,
    Px4LinkMsg, TelemetryProfile,
};
use skein_mavlink::param::ParamValue;
use skein_mavlink::signing::SigningKey;
use skein_mavlink::{CommandTarget, Encoder, MavMessage, command_long, dialect as d};
use skein_model::px4::Px4Mode;
use skein_sim::{SimConfig, SimVehicleConfig, Simulator};
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// `n` simulated vehicles all sending to one `udpin` endpoint; links attached as they are
/// discovered.
async fn swarm_on_one_port(n: u8, setup: LinkSetup) -> (Simulator, Arc<Endpoint>, Vec<Vehicle>) {
    swarm_on_one_port_signed(n, setup, None).await
}

/// [`swarm_on_one_port`] with MAVLink 2 signing on both sides when given a key (the
/// simulator requiring it, `MAV_SIGN_CFG` 2).
async fn swarm_on_one_port_signed(
    n: u8,
    setup: LinkSetup,
    key: Option<SigningKey>,
) -> (Simulator, Arc<Endpoint>, Vec<Vehicle>) {
    let endpoint = Endpoint::open(
        ConnectionAddress::UdpIn("127.0.0.1:0".parse().unwrap()),
        Identity::default(),
    )
    .await
    .unwrap();
    if let Some(k) = &key {
        let spec = skein_link::SigningSpec {
            key: k.clone(),
            link_id: 7,
        };
        endpoint.set_signing(None, spec.signing());
    }
    let found: Arc<Mutex<Vec<Discovery>>> = Arc::default();
    let f = found.clone();
    endpoint.set_discovery(Arc::new(move |d| f.lock().unwrap().push(d)));
    let target = endpoint.local_addr().unwrap();
    let bind: SocketAddr = "127.0.0.1:0".parse().unwrap();
    let mut cfg = SimConfig::with_vehicles(
        (1..=n)
            .map(|sysid| SimVehicleConfig {
                sysid,
                bind,
                target,
            })
            .collect(),
    );
    // A global position at once (the simulator's default waits 1 s, as an EKF does):
    // these tests are about the link, not about the EKF.
    cfg.ekf_fix_delay_s = 0.2;
    if key.is_some() {
        cfg.signing_key = key;
        cfg.params.push(("MAV_SIGN_CFG".into(), 2.0));
    }
    let sim = Simulator::start(cfg).await.unwrap();
    let discoveries = eventually("every vehicle discovered", Duration::from_secs(20), || {
        let f = found.lock().unwrap();
        (f.len() == usize::from(n)).then(|| f.clone())
    })
    .await;
    let mut vehicles = Vec::new();
    for d in discoveries {
        vehicles.push(attach(&endpoint, &d, setup.clone()).await);
    }
    vehicles.sort_by_key(|v| v.link.sysid);
    (sim, endpoint, vehicles)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn twelve_vehicles_on_one_port_keep_their_identities() {
    let (sim, endpoint, vehicles) = swarm_on_one_port(12, LinkSetup::default()).await;
    let sysids: Vec<u8> = vehicles.iter().map(|v| v.link.sysid).collect();
    assert_eq!(sysids, (1..=12).collect::<Vec<u8>>());
    for v in &vehicles {
        eventually(
            "telemetry of every vehicle",
            Duration::from_secs(20),
            || {
                v.link
                    .with_telemetry(|t| t.home.is_some() && t.heartbeat.is_some())
                    .then_some(())
            },
        )
        .await;
    }
    // Each vehicle's own position: they spawn at different places, so no two agree.
    let homes: Vec<_> = vehicles
        .iter()
        .map(|v| v.link.with_telemetry(|t| t.home.unwrap().geo))
        .collect();
    for (i, a) in homes.iter().enumerate() {
        for b in &homes[i + 1..] {
            assert!(
                a != b,
                "two vehicles reported the same home: frames crossed"
            );
        }
    }
    // A command to vehicle 11 reaches vehicle 11 only (the target_system pain point).
    vehicles[10].command(LinkCommand::Arm).await.unwrap();
    eventually("sysid 11 armed", Duration::from_secs(10), || {
        sim.truth(11).unwrap().armed.then_some(())
    })
    .await;
    for sysid in (1..=12).filter(|s| *s != 11) {
        assert!(!sim.truth(sysid).unwrap().armed, "sysid {sysid} armed too");
    }
    assert_eq!(
        endpoint.decode_counts().errors(),
        0,
        "{:?}",
        endpoint.decode_counts()
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_silent_vehicle_is_lost_after_3_s_and_rejoins_with_its_identity() {
    let (sim, _endpoint, vehicles) = swarm_on_one_port(2, LinkSetup::default()).await;
    let v = &vehicles[0];
    eventually("connected", Duration::from_secs(10), || {
        v.link
            .with_telemetry(|t| t.heartbeat.is_some())
            .then_some(())
    })
    .await;
    let t0 = Instant::now();
    sim.set_silent(1, true);
    eventually("Lost", Duration::from_secs(10), || {
        v.saw(|e| *e == LinkEvent::Lost).then_some(())
    })
    .await;
    let lost_after = t0.elapsed();
    assert!(
        lost_after >= Duration::from_millis(2900),
        "lost after {lost_after:?}"
    );
    assert!(v.link.is_lost());
    // Commands to a lost vehicle fail at once with NoLink.
    assert_eq!(v.command(LinkCommand::Arm).await, Err(LinkError::NoLink));
    // The other vehicle on the same port is unaffected.
    assert!(!vehicles[1].link.is_lost());
    sim.set_silent(1, false);
    eventually("Restored", Duration::from_secs(10), || {
        v.saw(|e| matches!(e, LinkEvent::Restored(_))).then_some(())
    })
    .await;
    assert!(!v.link.is_lost());
    v.command(LinkCommand::SetMode(Px4Mode::Hold))
        .await
        .unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_rebooted_vehicle_is_detected_and_readopted() {
    let (sim, _endpoint, vehicles) = swarm_on_one_port(1, LinkSetup::default()).await;
    let v = &vehicles[0];
    v.home_known().await;
    // Let the boot clock run a while so a restart is visible: the boot time must go back
    // by more than REBOOT_JUMP_MS (200 ms), and the first frames after a reboot carry a
    // few tens of ms.
    eventually("boot time past 1 s", Duration::from_secs(10), || {
        v.link
            .with_telemetry(|t| t.global.is_some_and(|g| g.time_boot_ms > 1000))
            .then_some(())
    })
    .await;
    sim.reboot(1);
    eventually("Rebooted", Duration::from_secs(10), || {
        v.saw(|e| *e == LinkEvent::Rebooted).then_some(())
    })
    .await;
    // Re-adopted: the home (forgotten on reboot) is requested and comes back.
    v.home_known().await;
    v.command(LinkCommand::Arm).await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn parameters_read_and_write_with_bytewise_integers() {
    let setup = LinkSetup {
        telemetry: TelemetryProfile::Px4Default,
        params: vec![
            ("COM_OBL_RC_ACT".into(), 5.0),
            ("COM_OF_LOSS_T".into(), 0.8),
        ],
        remote_id: None,
        operator_gnss: None,
        metadata_cache_dir: None,
        log_bandwidth: Default::default(),
    };
    let (_sim, _endpoint, vehicles) = swarm_on_one_port(1, setup).await;
    let v = &vehicles[0];
    let get = |name: &'static str| {
        let actor = v.actor.clone();
        async move {
            ractor::call_t!(actor, Px4LinkMsg::ParamGet, 15_000, name.to_string()).expect("answer")
        }
    };
    // Set at connect (once the first heartbeat has been seen), read back.
    let deadline = Instant::now() + Duration::from_secs(10);
    while get("COM_OBL_RC_ACT").await != Ok(ParamValue::Int32(5)) {
        assert!(Instant::now() < deadline, "COM_OBL_RC_ACT never became 5");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert_eq!(get("COM_OF_LOSS_T").await, Ok(ParamValue::Real32(0.8)));
    assert_eq!(get("MIS_TAKEOFF_ALT").await, Ok(ParamValue::Real32(2.5)));
    let set = ractor::call_t!(
        v.actor,
        Px4LinkMsg::ParamSet,
        15_000,
        "MIS_TAKEOFF_ALT".to_string(),
        7.5
    )
    .unwrap();
    assert_eq!(set, Ok(ParamValue::Real32(7.5)));
    assert_eq!(get("MIS_TAKEOFF_ALT").await, Ok(ParamValue::Real32(7.5)));
    let missing = get("NO_SUCH_PARAM").await;
    assert!(
        matches!(missing, Err(LinkError::Timeout { .. })),
        "{missing:?}"
    );
}

/// skein's fence on the autopilot through a link that loses a tenth of its datagrams
/// each way: the mission protocol's resends and the vehicle's re-requests carry the
/// uploads, the read-back agrees, `GF_ACTION` and `GF_MAX_VER_DIST` are set; an autopilot
/// that refuses is named with its `MAV_MISSION_RESULT`.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_fence_reaches_the_autopilot_through_a_lossy_link() {
    use skein_link::fence::FencePlan;
    use skein_model::geo::NedFrame;
    use skein_model::geofence::{BreachAction, FenceArea, FenceSyncState, Geofence, RallyPoint};
    let (sim, _endpoint, vehicles) = swarm_on_one_port(1, LinkSetup::default()).await;
    let v = &vehicles[0];
    v.home_known().await;
    let home = v.link.with_telemetry(|t| t.home.unwrap().geo);
    let fence = Geofence {
        polygon: vec![[-30.0, -30.0], [30.0, -30.0], [30.0, 30.0], [-30.0, 30.0]],
        exclusions: vec![FenceArea::Circle {
            north_m: 10.0,
            east_m: 10.0,
            radius_m: 4.0,
        }],
        rally_points: vec![RallyPoint {
            north_m: -20.0,
            east_m: 0.0,
            altitude_m: 15.0,
        }],
        breach_action: BreachAction::Rtl,
        ..Geofence::default()
    };
    let plan = |version| Arc::new(FencePlan::new(&fence, &NedFrame::new(home), version));
    assert!(sim.set_link_quality(1, 0.1, 0.0));
    let status = ractor::call_t!(v.actor, Px4LinkMsg::TryFence, 120_000, plan(7)).unwrap();
    assert_eq!(status.state, FenceSyncState::Synced, "{status:?}");
    assert_eq!(
        (status.version, status.fence_items, status.rally_items),
        (7, 5, 1)
    );
    sim.set_link_quality(1, 0.0, 0.0);
    let held = &sim.stats()[0];
    assert_eq!((held.fence_items, held.rally_items), (5, 1));
    let get = |name: &'static str| {
        let actor = v.actor.clone();
        async move {
            ractor::call_t!(actor, Px4LinkMsg::ParamGet, 15_000, name.to_string()).expect("answer")
        }
    };
    assert_eq!(get("GF_ACTION").await, Ok(ParamValue::Int32(3)));
    // The ceiling (120 m above the swarm origin, here the home) above the home.
    assert_eq!(get("GF_MAX_VER_DIST").await, Ok(ParamValue::Real32(120.0)));
    assert!(sim.set_mission_fault(1, Some(d::MavMissionResult::MAV_MISSION_NO_SPACE)));
    let status = ractor::call_t!(v.actor, Px4LinkMsg::TryFence, 60_000, plan(8)).unwrap();
    assert_eq!(status.state, FenceSyncState::Failed, "{status:?}");
    let why = status.reason.clone().unwrap_or_default();
    assert!(
        why.contains("fence upload") && why.contains("MAV_MISSION_NO_SPACE"),
        "{why}"
    );
    assert_eq!(
        v.link.fence().status(),
        status,
        "the vehicle's status says so"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn command_results_map_to_errors_and_silence_times_out() {
    let (sim, _endpoint, vehicles) = swarm_on_one_port(1, LinkSetup::default()).await;
    let v = &vehicles[0];
    v.home_known().await;
    // OFFBOARD without a setpoint stream: PX4's second ACK refuses it.
    let r = v.command(LinkCommand::SetMode(Px4Mode::Offboard)).await;
    assert!(matches!(r, Err(LinkError::Rejected { .. })), "{r:?}");
    // Arming is refused in LAND, with PX4's reason.
    v.command(LinkCommand::SetMode(Px4Mode::Land))
        .await
        .unwrap();
    let r = v.command(LinkCommand::Arm).await;
    let Err(LinkError::Rejected { statustexts, .. }) = &r else {
        panic!("{r:?}");
    };
    assert_eq!(
        statustexts,
        &["Arming denied: Land mode does not allow arming"],
        "{r:?}"
    );
    // Mode changes are confirmed from the heartbeat.
    v.command(LinkCommand::SetMode(Px4Mode::Hold))
        .await
        .unwrap();
    assert_eq!(
        v.link.with_telemetry(|t| t.heartbeat.unwrap().mode),
        Px4Mode::Hold
    );
    // No ACK at all: every resend, then a timeout.
    sim.set_silent(1, true);
    let t0 = Instant::now();
    let r = v.command(LinkCommand::Arm).await;
    assert_eq!(
        r,
        Err(LinkError::Timeout {
            command: "arm".into(),
            attempts: skein_link::px4link::MAX_ATTEMPTS
        })
    );
    assert!(t0.elapsed() >= skein_link::px4link::ACK_TIMEOUT * 4);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_swarm_profile_cuts_telemetry_to_what_skein_uses() {
    let count = |v: &Vehicle| v.link.with_telemetry(|t| t.messages);
    let rate = |v: &Vehicle| {
        let v = v.link.clone();
        async move {
            let a = v.with_telemetry(|t| t.messages);
            let t0 = Instant::now();
            tokio::time::sleep(Duration::from_millis(1000)).await; // measurement window
            (v.with_telemetry(|t| t.messages) - a) as f64 / t0.elapsed().as_secs_f64()
        }
    };
    let (_sim, _e, full) = swarm_on_one_port(1, LinkSetup::default()).await;
    eventually("streaming", Duration::from_secs(10), || {
        (count(&full[0]) > 100).then_some(())
    })
    .await;
    let full_rate = rate(&full[0]).await;
    let setup = LinkSetup {
        telemetry: TelemetryProfile::Swarm,
        params: vec![],
        remote_id: None,
        operator_gnss: None,
        metadata_cache_dir: None,
        log_bandwidth: Default::default(),
    };
    let (_sim2, _e2, reduced) = swarm_on_one_port(1, setup).await;
    eventually("streaming", Duration::from_secs(10), || {
        (count(&reduced[0]) > 50).then_some(())
    })
    .await;
    assert!(full_rate > 250.0, "PX4 default profile: {full_rate} msg/s");
    // The SET_MESSAGE_INTERVAL commands go one at a time: measure until they have landed.
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let reduced_rate = rate(&reduced[0]).await;
        if reduced_rate < 60.0 {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "swarm profile still at {reduced_rate} msg/s"
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_signed_link_flies_the_signed_simulator_and_unsigned_frames_are_dropped() {
    let key = SigningKey::from_bytes([0x5a; 32]);
    let (sim, endpoint, vehicles) =
        swarm_on_one_port_signed(1, LinkSetup::default(), Some(key)).await;
    let v = &vehicles[0];
    let home_alt = eventually("home position", Duration::from_secs(20), || {
        v.link.with_telemetry(|t| t.home.map(|h| h.geo.alt_amsl_m))
    })
    .await;
    v.command(LinkCommand::Takeoff {
        altitude_amsl_m: Some(home_alt + 5.0),
    })
    .await
    .unwrap();
    v.command(LinkCommand::Arm).await.unwrap();
    eventually("climbing above 3 m", Duration::from_secs(30), || {
        let t = sim.truth(1).unwrap();
        (t.armed && t.local_ned_m.down_m < -3.0).then_some(())
    })
    .await;
    // Both directions were signed, and nothing was refused.
    let ours = endpoint.signing_counts().unwrap();
    let theirs = sim.stats()[0].signing;
    assert!(ours.signed_ok > 50 && ours.frames_signed > 5, "{ours:?}");
    assert!(
        theirs.signed_ok > 5 && theirs.frames_signed > 50,
        "{theirs:?}"
    );
    assert_eq!((ours.dropped(), theirs.dropped()), (0, 0));

    // An intruder without the key, straight to the vehicle: counted and ignored.
    let intruder = tokio::net::UdpSocket::bind("127.0.0.1:0").await.unwrap();
    let mut enc = Encoder::new(255, 190);
    // A forced disarm (MAV_CMD_COMPONENT_ARM_DISARM, 21196).
    let disarm_force = command_long(
        CommandTarget::new(1, 1),
        d::MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        [0.0, 21196.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        0,
    );
    for _ in 0..3 {
        intruder
            .send_to(
                enc.encode(&disarm_force).as_bytes(),
                sim.vehicles()[0].bound,
            )
            .await
            .unwrap();
    }
    eventually(
        "the simulator counted 3 unsigned frames",
        Duration::from_secs(5),
        || (sim.stats()[0].signing.unsigned >= 3).then_some(()),
    )
    .await;
    assert!(
        sim.truth(1).unwrap().armed,
        "an unsigned disarm got through"
    );

    // Frames claiming to be the vehicle, unsigned, to skein: counted and dropped.
    let heartbeat = heartbeat(d::MavAutopilot::MAV_AUTOPILOT_PX4);
    let to_skein = endpoint.local_addr().unwrap();
    let mut spoof = Encoder::new(1, 1);
    let frame = spoof.encode(&heartbeat);
    intruder.send_to(frame.as_bytes(), to_skein).await.unwrap();
    // Signed with another key: a bad signature.
    let other = skein_link::SigningSpec {
        key: SigningKey::from_bytes([0x11; 32]),
        link_id: 0,
    };
    spoof.set_signing(Some(other.signing()));
    let frame = spoof.encode(&heartbeat);
    intruder.send_to(frame.as_bytes(), to_skein).await.unwrap();
    eventually("skein counted both", Duration::from_secs(5), || {
        let c = endpoint.signing_counts().unwrap();
        (c.unsigned >= 1 && c.bad_signature >= 1).then_some(())
    })
    .await;
    assert_eq!(
        endpoint.peer_addr(1),
        Some(sim.vehicles()[0].bound),
        "a spoofed frame moved the vehicle's address"
    );
}

/// DO_SET_MODE to POSCTL (custom main mode 3) for `target_system`, every component.
fn set_mode_posctl(target_system: u8) -> MavMessage {
    command_long(
        CommandTarget::new(target_system, 0),
        d::MavCmd::MAV_CMD_DO_SET_MODE,
        [1.0, 3.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        0,
    )
}

/// A ground station on a `udpin` forward: it hears the vehicles once it spoke, a
/// broadcast reaches both, a frame for an unknown sysid and a setpoint are counted.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_ground_station_on_a_udpin_forward_broadcasts_and_is_refused_setpoints() {
    let (sim, endpoint, vehicles) = swarm_on_one_port(2, LinkSetup::default()).await;
    let fwd = skein_link::GcsForwarder::start(
        ConnectionAddress::UdpIn("127.0.0.1:0".parse().unwrap()),
        vec![endpoint.clone()],
    )
    .await
    .unwrap();
    let gcs = tokio::net::UdpSocket::bind("127.0.0.1:0").await.unwrap();
    let mut enc = Encoder::new(255, 190);
    let to = fwd.local_addr();
    for v in &vehicles {
        // A global position first: POSCTL needs it.
        v.home_known().await;
    }
    // Nothing reaches a udpin ground station before it spoke.
    assert_eq!(fwd.counts().to_gcs, 0);
    gcs.send_to(enc.encode(&set_mode_posctl(0)).as_bytes(), to)
        .await
        .unwrap();
    eventually("both vehicles in POSCTL", Duration::from_secs(10), || {
        (1..=2)
            .all(|s| sim.truth(s).unwrap().mode == Px4Mode::Posctl)
            .then_some(())
    })
    .await;
    let mut buf = [0u8; 2048];
    let (n, _) = tokio::time::timeout(Duration::from_secs(5), gcs.recv_from(&mut buf))
        .await
        .expect("vehicle frames forwarded")
        .unwrap();
    let mut sysids = std::collections::BTreeSet::new();
    skein_mavlink::Decoder::default().decode_datagram(&buf[..n], |f| {
        sysids.insert(f.sysid);
    });
    assert!(sysids.iter().all(|s| (1..=2).contains(s)), "{sysids:?}");
    gcs.send_to(enc.encode(&set_mode_posctl(9)).as_bytes(), to)
        .await
        .unwrap();
    let attitude = MavMessage::SET_ATTITUDE_TARGET(d::SET_ATTITUDE_TARGET_DATA {
        target_system: 1,
        target_component: 1,
        ..Default::default()
    });
    gcs.send_to(enc.encode(&attitude).as_bytes(), to)
        .await
        .unwrap();
    let c = eventually(
        "no route and setpoint counted",
        Duration::from_secs(5),
        || {
            let c = fwd.counts();
            (c.no_route == 1 && c.setpoints_dropped == 1).then_some(c)
        },
    )
    .await;
    assert_eq!(c.from_gcs, 2, "the broadcast, once per vehicle: {c:?}");
    assert!(c.to_gcs > 0, "{c:?}");
}
