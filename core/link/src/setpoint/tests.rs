//! Unit tests of the setpoint stream and its clock.

use super::*;
use crate::{ConnectionAddress, Identity};

/// Datagrams waiting on `sock` (non-blocking), taken.
fn drain(sock: &std::net::UdpSocket) -> usize {
    let mut buf = [0u8; 512];
    std::iter::from_fn(|| sock.recv(&mut buf).ok()).count()
}

/// The clock's tick allocates nothing once its streams run (see the module docs),
/// whether a stream has an endpoint of its own (one `sendto`) or shares one with
/// others (one `sendmmsg`), to a fixed remote (`udpout`) or to where each vehicle was
/// heard from (`udpin`), or is on a serial port (the frame queued for the endpoint's
/// writer thread). The ticks run on this thread, under a counting allocator.
#[tokio::test]
async fn a_running_tick_allocates_nothing() {
    let px4 = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let to = ConnectionAddress::UdpOut(px4.local_addr().unwrap());
    // Vehicles 31–34 heard by a `udpin` endpoint, from the same socket.
    let heard = Endpoint::open(
        ConnectionAddress::UdpIn("127.0.0.1:0".parse().unwrap()),
        Identity::default(),
    )
    .await
    .unwrap();
    // Any frame gives the endpoint its sender's address.
    let heartbeat = MavMessage::HEARTBEAT(skein_mavlink::dialect::HEARTBEAT_DATA::default());
    let heard_at = heard.local_addr().unwrap();
    for sysid in 31..=34 {
        let hb = skein_mavlink::encode_frame(sysid, 1, 0, &heartbeat, None);
        px4.send_to(hb.as_bytes(), heard_at).unwrap();
    }
    let deadline = Instant::now() + Duration::from_secs(10);
    while (31..=34).any(|s| heard.peer_addr(s).is_none()) {
        assert!(Instant::now() < deadline, "the heartbeats were not heard");
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    px4.set_nonblocking(true).unwrap();
    let clock = Clock {
        joining: Mutex::new(Vec::new()),
    };
    let mut streams = Vec::new();
    for sysid in 1..=4 {
        let own = Endpoint::open(to.clone(), Identity::default())
            .await
            .unwrap();
        streams.push(SetpointStream::idle(own, sysid, 1, 50.0));
    }
    let shared = Endpoint::open(to, Identity::default()).await.unwrap();
    for sysid in 11..=22 {
        streams.push(SetpointStream::idle(shared.clone(), sysid, 1, 50.0));
    }
    for sysid in 31..=34 {
        streams.push(SetpointStream::idle(heard.clone(), sysid, 1, 50.0));
    }
    let setpoint = LocalSetpoint::position(Ned::new(0.0, 0.0, -10.0), 0.0);
    for s in &streams {
        clock.join(&s.stream);
        s.set(Some(setpoint));
    }
    // And one on a serial port (a pseudo-terminal): its frames are queued for the
    // endpoint's writer thread.
    let pty = nix::pty::openpty(None, None).unwrap();
    let tty = nix::unistd::ttyname(&pty.slave).unwrap();
    let serial = format!("serial:{}:57600", tty.display()).parse().unwrap();
    let serial = Endpoint::open(serial, Identity::default()).await.unwrap();
    let on_serial = SetpointStream::idle(serial, 41, 1, 50.0);
    clock.join(&on_serial.stream);
    on_serial.set(Some(setpoint));
    // Two rounds grow every buffer to its size.
    let mut state = Ticks::default();
    for _ in 0..2 * SLICES {
        clock.tick(&mut state);
    }
    assert_eq!(drain(&px4), 2 * streams.len());
    let rounds = 10;
    let info = allocation_counter::measure(|| {
        for _ in 0..rounds * SLICES {
            clock.tick(&mut state);
        }
    });
    assert_eq!(drain(&px4), rounds * streams.len());
    assert_eq!(info.count_total, 0, "{info:?}");
    for s in streams.iter().chain([&on_serial]) {
        assert_eq!(s.counts().send_errors, 0);
    }
    assert_eq!(on_serial.counts().sent, 12);
    drop(pty);
}

#[test]
fn hold_drops_feed_forward() {
    let sp =
        LocalSetpoint::position_velocity(Ned::new(1.0, 2.0, -3.0), Ned::new(4.0, 0.0, 0.0), 0.5);
    let h = sp.as_hold();
    assert_eq!(h.type_mask, type_mask::POSITION_YAW);
    assert_eq!(h.position, sp.position);
    assert_eq!(h.velocity, Ned::ZERO);
    let v = LocalSetpoint::velocity(Ned::new(3.0, 0.0, 0.0), 0.1).as_hold();
    assert_eq!(v.velocity, Ned::ZERO);
    assert_eq!(v.type_mask, type_mask::VELOCITY_YAW_RATE);
}
