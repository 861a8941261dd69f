//! The endpoint over real sockets: a shared `udpin:` endpoint (demultiplexing by sysid,
//! discovery, malformed datagrams, refusals), and the byte-stream transports, `tcpout:`
//! (with reconnection) and `serial:` (over a pseudo-terminal pair), each discovering a
//! vehicle and carrying frames both ways.

mod common;

use common::{eventually, heartbeat, serial_endpoint};
use skein_link::endpoint::SendError;
use skein_link::{ConnectionAddress, Endpoint, Identity};
use skein_mavlink::dialect::*;
use skein_mavlink::{Decoder, Encoder, Frame};
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::UdpSocket;

/// How long a condition may take to hold.
const WAIT: Duration = Duration::from_secs(10);

/// A `udpin:` endpoint on a free port of the loopback interface.
async fn udpin_endpoint() -> Arc<Endpoint> {
    Endpoint::open(
        ConnectionAddress::UdpIn("127.0.0.1:0".parse().unwrap()),
        Identity::default(),
    )
    .await
    .unwrap()
}

/// Sends the next HEARTBEAT of a PX4 vehicle (`enc`'s sysid) from `sock` to `to`.
async fn vehicle_heartbeat(sock: &UdpSocket, enc: &mut Encoder, to: SocketAddr) {
    let frame = enc.encode(&heartbeat(MavAutopilot::MAV_AUTOPILOT_PX4));
    sock.send_to(frame.as_bytes(), to).await.unwrap();
}

/// The frames in `bytes`.
fn frames(bytes: &[u8]) -> Vec<Frame> {
    let mut d = Decoder::default();
    d.push(bytes);
    std::iter::from_fn(|| d.next_frame()).collect()
}

#[tokio::test]
async fn tcpout_discovers_carries_frames_and_reconnects() {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let ep = Endpoint::open(ConnectionAddress::TcpOut(addr), Identity::default())
        .await
        .unwrap();
    let found = Arc::new(Mutex::new(Vec::new()));
    let f = found.clone();
    ep.set_discovery(Arc::new(move |d| f.lock().unwrap().push(d.sysid)));
    let mut vehicle = Encoder::new(7, 1);
    for round in 0..2 {
        let (mut sock, _) = tokio::time::timeout(Duration::from_secs(10), listener.accept())
            .await
            .expect("endpoint (re)connects")
            .unwrap();
        sock.write_all(
            vehicle
                .encode(&heartbeat(MavAutopilot::MAV_AUTOPILOT_PX4))
                .as_bytes(),
        )
        .await
        .unwrap();
        eventually("vehicle seen", WAIT, || ep.last_seen(7).map(|_| ())).await;
        if round == 0 {
            eventually("discovery", WAIT, || {
                (found.lock().unwrap().as_slice() == [7]).then_some(())
            })
            .await;
        }
        ep.send(7, &heartbeat(MavAutopilot::MAV_AUTOPILOT_INVALID))
            .unwrap();
        let mut buf = vec![0u8; 512];
        let n = tokio::time::timeout(Duration::from_secs(10), sock.read(&mut buf))
            .await
            .unwrap()
            .unwrap();
        let got = frames(&buf[..n]);
        assert_eq!(got[0].sysid, 255, "our identity");
        // Drop the connection: the endpoint must come back by itself.
        drop(sock);
    }
}

#[tokio::test]
async fn serial_over_a_pseudo_terminal() {
    let (ep, master, slave) = serial_endpoint().await;
    let found = Arc::new(Mutex::new(Vec::new()));
    let f = found.clone();
    ep.set_discovery(Arc::new(move |d| f.lock().unwrap().push(d.sysid)));
    // The test plays the flight controller on the pty's master side.
    let frame = Encoder::new(3, 1).encode(&heartbeat(MavAutopilot::MAV_AUTOPILOT_PX4));
    let written = nix::unistd::write(&master, frame.as_bytes()).unwrap();
    assert_eq!(written, frame.as_bytes().len());
    eventually("discovery over serial", WAIT, || {
        (found.lock().unwrap().as_slice() == [3]).then_some(())
    })
    .await;
    ep.send(3, &heartbeat(MavAutopilot::MAV_AUTOPILOT_INVALID))
        .unwrap();
    let reader = tokio::task::spawn_blocking(move || {
        let mut buf = vec![0u8; 512];
        let n = nix::unistd::read(&master, &mut buf).unwrap();
        (frames(&buf[..n]), master)
    });
    let (got, master) = tokio::time::timeout(Duration::from_secs(10), reader)
        .await
        .expect("frame written to the serial port")
        .unwrap();
    assert_eq!((got[0].sysid, got[0].compid), (255, 190));
    assert_eq!(ep.decode_counts().errors(), 0);
    drop((slave, master));
}

#[tokio::test]
async fn shared_udpin_endpoint_demultiplexes_by_sysid_and_discovers() {
    let ep = udpin_endpoint().await;
    let addr = ep.local_addr().unwrap();
    let found = Arc::new(Mutex::new(Vec::new()));
    let f2 = found.clone();
    ep.set_discovery(Arc::new(move |d| f2.lock().unwrap().push(d.sysid)));
    // Three "vehicles" on their own sockets, all sending to the one endpoint.
    let mut vehicles = Vec::new();
    for sysid in [1u8, 2, 3] {
        let s = UdpSocket::bind("127.0.0.1:0").await.unwrap();
        let mut enc = Encoder::new(sysid, 1);
        vehicle_heartbeat(&s, &mut enc, addr).await;
        vehicles.push((s, enc));
    }
    eventually("three discoveries", WAIT, || {
        (found.lock().unwrap().len() == 3).then_some(())
    })
    .await;
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
        vehicle_heartbeat(s, enc, addr).await;
    }
    eventually("sysid 2 routed", WAIT, || {
        (!got.lock().unwrap().is_empty()).then_some(())
    })
    .await;
    eventually("gcs seen", WAIT, || ep.last_seen(200).map(|_| ())).await;
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
    assert_eq!(frames(&buf[..n])[0].sysid, 255);
}

#[tokio::test]
async fn malformed_datagrams_are_counted_and_dropped() {
    let ep = udpin_endpoint().await;
    let s = UdpSocket::bind("127.0.0.1:0").await.unwrap();
    s.send_to(
        b"\xfd\x09garbage that is not mavlink",
        ep.local_addr().unwrap(),
    )
    .await
    .unwrap();
    eventually("rejected datagram counted", WAIT, || {
        (ep.decode_counts().rejected_datagrams == 1).then_some(())
    })
    .await;
    assert_eq!(ep.decode_counts().frames_ok, 0);
}

#[tokio::test]
async fn send_before_the_vehicle_spoke_is_refused() {
    let ep = udpin_endpoint().await;
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
