//! The byte-stream transports: `tcpout:` (with reconnection) and `serial:` (over a
//! pseudo-terminal pair), each discovering a vehicle and carrying frames both ways.

use skein_link::{ConnectionAddress, Endpoint, Identity};
use skein_mavlink::dialect::*;
use skein_mavlink::{Decoder, Encoder, MavMessage};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::io::{AsyncReadExt, AsyncWriteExt};

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
    let deadline = Instant::now() + Duration::from_secs(10);
    while !f() {
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
}

fn frames(bytes: &[u8]) -> Vec<skein_mavlink::Frame> {
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
        eventually("vehicle seen", || ep.last_seen(7).is_some()).await;
        if round == 0 {
            eventually("discovery", || found.lock().unwrap().as_slice() == [7]).await;
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
    let pty = nix::pty::openpty(None, None).unwrap();
    let path = nix::unistd::ttyname(pty.slave).unwrap();
    let conn: ConnectionAddress = format!("serial:{}:57600", path.display()).parse().unwrap();
    let ep = Endpoint::open(conn, Identity::default()).await.unwrap();
    let found = Arc::new(Mutex::new(Vec::new()));
    let f = found.clone();
    ep.set_discovery(Arc::new(move |d| f.lock().unwrap().push(d.sysid)));
    // The test plays the flight controller on the pty's master side.
    let master = pty.master;
    let frame = Encoder::new(3, 1).encode(&heartbeat(MavAutopilot::MAV_AUTOPILOT_PX4));
    let written = nix::unistd::write(master, frame.as_bytes()).unwrap();
    assert_eq!(written, frame.as_bytes().len());
    eventually("discovery over serial", || {
        found.lock().unwrap().as_slice() == [3]
    })
    .await;
    ep.send(3, &heartbeat(MavAutopilot::MAV_AUTOPILOT_INVALID))
        .unwrap();
    let reader = tokio::task::spawn_blocking(move || {
        let mut buf = vec![0u8; 512];
        let n = nix::unistd::read(master, &mut buf).unwrap();
        frames(&buf[..n])
    });
    let got = tokio::time::timeout(Duration::from_secs(10), reader)
        .await
        .expect("frame written to the serial port")
        .unwrap();
    assert_eq!((got[0].sysid, got[0].compid), (255, 190));
    assert_eq!(ep.decode_counts().errors(), 0);
    let _ = nix::unistd::close(pty.slave);
    let _ = nix::unistd::close(master);
}
