//! Endpoint tests over real sockets: demultiplexing, discovery, malformed input, refusals.

use super::*;
use skein_mavlink::dialect::*;
use std::time::Duration;

fn heartbeat(autopilot: MavAutopilot) -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_STANDBY,
        mavlink_version: 3,
    })
}

async fn eventually(what: &str, mut f: impl FnMut() -> bool) {
    let deadline = Instant::now() + Duration::from_secs(5);
    while !f() {
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

#[tokio::test]
async fn shared_udpin_endpoint_demultiplexes_by_sysid_and_discovers() {
    let ep = Endpoint::open(
        ConnectionAddress::UdpIn("127.0.0.1:0".parse().unwrap()),
        Identity::default(),
    )
    .await
    .unwrap();
    let addr = ep.local_addr().unwrap();
    let found = Arc::new(Mutex::new(Vec::new()));
    let f2 = found.clone();
    ep.set_discovery(Arc::new(move |d| f2.lock().unwrap().push(d.sysid)));
    // Three "vehicles" on their own sockets, all sending to the one endpoint.
    let mut vehicles = Vec::new();
    for sysid in [1u8, 2, 3] {
        let s = UdpSocket::bind("127.0.0.1:0").await.unwrap();
        let mut enc = Encoder::new(sysid, 1);
        s.send_to(
            enc.encode(&heartbeat(MavAutopilot::MAV_AUTOPILOT_PX4))
                .as_bytes(),
            addr,
        )
        .await
        .unwrap();
        vehicles.push((s, enc));
    }
    eventually("three discoveries", || found.lock().unwrap().len() == 3).await;
    // A GCS heartbeat (autopilot INVALID) is not a vehicle.
    let gcs = UdpSocket::bind("127.0.0.1:0").await.unwrap();
    gcs.send_to(
        Encoder::new(200, 190)
            .encode(&heartbeat(MavAutopilot::MAV_AUTOPILOT_INVALID))
            .as_bytes(),
        addr,
    )
    .await
    .unwrap();
    // Route sysid 2 and check only its frames arrive there.
    let got = Arc::new(Mutex::new(Vec::new()));
    let g2 = got.clone();
    ep.route(
        2,
        Arc::new(move |f: Frame| g2.lock().unwrap().push(f.sysid)),
    );
    for (s, enc) in vehicles.iter_mut() {
        s.send_to(
            enc.encode(&heartbeat(MavAutopilot::MAV_AUTOPILOT_PX4))
                .as_bytes(),
            addr,
        )
        .await
        .unwrap();
    }
    eventually("sysid 2 routed", || !got.lock().unwrap().is_empty()).await;
    eventually("gcs seen", || ep.last_seen(200).is_some()).await;
    assert!(got.lock().unwrap().iter().all(|&s| s == 2));
    assert_eq!(found.lock().unwrap().len(), 3, "GCS not discovered");
    // Replies go back to each vehicle's own address.
    ep.send(3, &heartbeat(MavAutopilot::MAV_AUTOPILOT_INVALID))
        .unwrap();
    let mut buf = [0u8; 300];
    let n = tokio::time::timeout(Duration::from_secs(5), vehicles[2].0.recv(&mut buf))
        .await
        .unwrap()
        .unwrap();
    let mut dec = Decoder::default();
    let mut frames = Vec::new();
    dec.decode_datagram(&buf[..n], |f| frames.push(f));
    assert_eq!(frames[0].sysid, 255);
}

#[tokio::test]
async fn malformed_datagrams_are_counted_and_dropped() {
    let ep = Endpoint::open(
        ConnectionAddress::UdpIn("127.0.0.1:0".parse().unwrap()),
        Identity::default(),
    )
    .await
    .unwrap();
    let s = UdpSocket::bind("127.0.0.1:0").await.unwrap();
    s.send_to(
        b"\xfd\x09garbage that is not mavlink",
        ep.local_addr().unwrap(),
    )
    .await
    .unwrap();
    eventually("rejected datagram counted", || {
        ep.decode_counts().rejected_datagrams == 1
    })
    .await;
    assert_eq!(ep.decode_counts().frames_ok, 0);
}

#[tokio::test]
async fn send_before_the_vehicle_spoke_is_refused() {
    let ep = Endpoint::open(
        ConnectionAddress::UdpIn("127.0.0.1:0".parse().unwrap()),
        Identity::default(),
    )
    .await
    .unwrap();
    assert_eq!(
        ep.send(7, &heartbeat(MavAutopilot::MAV_AUTOPILOT_INVALID)),
        Err(SendError::NoAddress(7))
    );
    assert_eq!(ep.send_counts().no_route, 1);
}

#[tokio::test]
async fn a_missing_serial_device_is_refused_naming_it() {
    let e = Endpoint::open(
        "serial:/dev/skein-no-such-tty:57600".parse().unwrap(),
        Identity::default(),
    )
    .await
    .unwrap_err();
    assert!(
        e.to_string()
            .contains("serial:/dev/skein-no-such-tty:57600"),
        "{e}"
    );
}
