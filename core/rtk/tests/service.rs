//! The corrections service over real sockets: a caster speaking NTRIP 2.0 (chunked),
//! a vehicle on a real UDP MAVLink endpoint that reassembles `GPS_RTCM_DATA` as MAVLink's
//! fragmentation rules say, a stalled caster reconnected, a caster without the mountpoint
//! refused with its source table, a UDP source, an NTRIP 1.0 caster told where the fleet
//! is (GGA) from a vehicle's own `GLOBAL_POSITION_INT`; frames relayed from another
//! process reach the vehicle as a source's do, and a source of its own takes precedence.

use skein_link::{ConnectionAddress, Endpoint, Identity, LinkSetup, VehicleLink};
use skein_mavlink::dialect::*;
use skein_mavlink::{Decoder, Encoder, MavMessage};
use skein_model::geo::GeoPoint;
use skein_rtk::testing::{frame_1005, frame_of};
use skein_rtk::{RelayRole, Relayed, RtkConfig, RtkService, SourceState, Vehicles};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream, UdpSocket};

const WAIT: Duration = Duration::from_secs(10);

async fn eventually<T>(what: &str, mut f: impl FnMut() -> Option<T>) -> T {
    let deadline = Instant::now() + WAIT;
    loop {
        if let Some(v) = f() {
            return v;
        }
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
}

/// A PX4 vehicle (sysid 1) on a real UDP endpoint: its link, and the RTCM messages it
/// reassembled from the `GPS_RTCM_DATA` it received.
struct Vehicle {
    link: Arc<VehicleLink>,
    received: Arc<Mutex<Vec<Vec<u8>>>>,
}

async fn vehicle() -> Vehicle {
    vehicle_with(None).await
}

/// [`vehicle`], also reporting `GLOBAL_POSITION_INT` at `position` (lat, lon degE7) to
/// a `Px4Link` actor, which folds it into the link's telemetry.
async fn vehicle_with(position: Option<(i32, i32)>) -> Vehicle {
    let endpoint = Endpoint::open(
        ConnectionAddress::UdpIn("127.0.0.1:0".parse().unwrap()),
        Identity::default(),
    )
    .await
    .unwrap();
    let sock = UdpSocket::bind("127.0.0.1:0").await.unwrap();
    let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_STANDBY,
        mavlink_version: 3,
    });
    let mut enc = Encoder::new(1, 1);
    let to = endpoint.local_addr().unwrap();
    sock.send_to(enc.encode(&hb).as_bytes(), to).await.unwrap();
    let ep = endpoint.clone();
    eventually("the endpoint hears the vehicle", || ep.last_seen(1)).await;
    let link = VehicleLink::new(endpoint, 1, 1, 20.0, LinkSetup::default());
    if let Some((lat, lon)) = position {
        let sink: skein_link::EventSink = Arc::new(|_| {});
        let (actor, _) = ractor::Actor::spawn(
            None,
            skein_link::Px4Link,
            skein_link::Px4LinkArgs {
                link: link.clone(),
                events: sink,
                components: None,
            },
        )
        .await
        .unwrap();
        // The actor runs on (a dropped reference does not stop it) until the test ends.
        drop(actor);
        let gpi = MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
            lat,
            lon,
            alt: 500_000,
            ..Default::default()
        });
        let l = link.clone();
        eventually("the link knows the position", || {
            let _ = sock.try_send_to(enc.encode(&gpi).as_bytes(), to);
            l.with_telemetry(|t| t.global.map(|_| ()))
        })
        .await;
    }
    let received = Arc::new(Mutex::new(Vec::new()));
    tokio::spawn(reassemble(sock, received.clone()));
    Vehicle { link, received }
}

/// Reassembles as an autopilot that follows MAVLink's rule does (ArduPilot).
async fn reassemble(sock: UdpSocket, out: Arc<Mutex<Vec<Vec<u8>>>>) {
    let mut buf = vec![0u8; 2048];
    let mut decoder = Decoder::default();
    let mut parts: Vec<Vec<u8>> = Vec::new();
    while let Ok(n) = sock.recv(&mut buf).await {
        decoder.push(&buf[..n]);
        while let Some(f) = decoder.next_frame() {
            let MavMessage::GPS_RTCM_DATA(d) = f.msg else {
                continue;
            };
            let data = d.data[..usize::from(d.len)].to_vec();
            if d.flags & 1 == 0 {
                out.lock().unwrap().push(data);
                continue;
            }
            let id = usize::from((d.flags >> 1) & 3);
            assert_eq!(id, parts.len(), "fragments arrive in order");
            let short = data.len() < 180;
            parts.push(data);
            if short || parts.len() == 4 {
                out.lock().unwrap().push(parts.concat());
                parts.clear();
            }
        }
    }
}

fn vehicles(links: &[&Vehicle]) -> Vehicles {
    let links: Vec<_> = links
        .iter()
        .enumerate()
        .map(|(i, v)| (format!("uav-{}", i + 1), v.link.clone()))
        .collect();
    Arc::new(move || links.clone())
}

fn config(source: String, stall_timeout_s: f64) -> RtkConfig {
    RtkConfig {
        source,
        max_bytes_s: 100_000.0,
        stall_timeout_s,
        send_gga: true,
    }
}

/// Reads a request head; answers NTRIP 2.0's `200` with chunked coding.
async fn answer_v2(sock: &mut TcpStream) -> String {
    let mut head = Vec::new();
    let mut b = [0u8; 1];
    while !head.ends_with(b"\r\n\r\n") {
        sock.read_exact(&mut b).await.unwrap();
        head.push(b[0]);
    }
    sock.write_all(
        b"HTTP/1.1 200 OK\r\nNtrip-Version: Ntrip/2.0\r\nContent-Type: gnss/data\r\nTransfer-Encoding: chunked\r\n\r\n",
    )
    .await
    .unwrap();
    String::from_utf8(head).unwrap()
}

/// Sends `bytes` as chunks of 100 bytes (so chunks cut frames).
async fn send_chunked(sock: &mut TcpStream, bytes: &[u8]) {
    for c in bytes.chunks(100) {
        let mut chunk = format!("{:x}\r\n", c.len()).into_bytes();
        chunk.extend_from_slice(c);
        chunk.extend_from_slice(b"\r\n");
        sock.write_all(&chunk).await.unwrap();
    }
}

#[tokio::test]
async fn an_ntrip_2_caster_reaches_the_vehicle_and_a_stall_reconnects() {
    let v = vehicle().await;
    let caster = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let port = caster.local_addr().unwrap().port();
    let rtk = RtkService::start(vehicles(&[&v]));
    rtk.configure(Some(&config(
        format!("ntrip://crew:secret@127.0.0.1:{port}/MNT"),
        1.0,
    )))
    .unwrap();
    let base = GeoPoint::new(47.397_742, 8.545_594, 535.0);
    let frames = [
        frame_1005(12, base),
        frame_of(1077, 400),
        frame_of(1230, 180),
    ];
    let (mut sock, _) = caster.accept().await.unwrap();
    let request = answer_v2(&mut sock).await;
    assert!(request.starts_with("GET /MNT HTTP/1.1\r\n"), "{request}");
    assert!(
        request.contains("Authorization: Basic Y3JldzpzZWNyZXQ=\r\n"),
        "{request}"
    );
    let mut wire = b"noise".to_vec();
    for f in &frames {
        wire.extend(f);
    }
    send_chunked(&mut sock, &wire).await;
    eventually("three messages reassembled", || {
        (v.received.lock().unwrap().len() == 3).then_some(())
    })
    .await;
    assert_eq!(*v.received.lock().unwrap(), frames.to_vec());
    let s = rtk.status();
    assert_eq!(s.state, SourceState::Streaming, "{s:?}");
    assert_eq!(
        s.source.as_deref(),
        Some(format!("ntrip://crew:***@127.0.0.1:{port}/MNT").as_str())
    );
    assert_eq!((s.frames, s.message_types.len()), (3, 3), "{s:?}");
    assert_eq!(s.garbage_bytes, 5);
    let b = s.base.expect("the base station");
    assert_eq!(b.station_id, 12);
    assert!((b.position.lat_deg - base.lat_deg).abs() < 1e-7);
    assert_eq!(s.vehicles[0].messages, 3);
    assert!(s.vehicles[0].correction_age_s.is_some());
    // The caster goes quiet with the connection open: stalled after 1 s, reconnected.
    eventually("stalled", || {
        (rtk.status().state == SourceState::Stalled).then_some(())
    })
    .await;
    assert!(
        rtk.status()
            .error
            .unwrap()
            .contains("no RTCM frame for 1 s")
    );
    let (mut again, _) = tokio::time::timeout(WAIT, caster.accept())
        .await
        .unwrap()
        .unwrap();
    answer_v2(&mut again).await;
    send_chunked(&mut again, &frames[1]).await;
    eventually("streaming again", || {
        (rtk.status().state == SourceState::Streaming).then_some(())
    })
    .await;
    assert_eq!(rtk.status().connects, 2);
    drop(sock);
}

#[tokio::test]
async fn an_unknown_mountpoint_fails_with_what_the_caster_lists() {
    let v = vehicle().await;
    let caster = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let port = caster.local_addr().unwrap().port();
    tokio::spawn(async move {
        while let Ok((mut s, _)) = caster.accept().await {
            let mut buf = [0u8; 1024];
            let _ = s.read(&mut buf).await;
            let _ = s
                .write_all(b"SOURCETABLE 200 OK\r\n\r\nSTR;NEAR;Zurich\r\nSTR;FAR;Bern\r\nENDSOURCETABLE\r\n")
                .await;
        }
    });
    let rtk = RtkService::start(vehicles(&[&v]));
    rtk.configure(Some(&config(format!("ntrip://127.0.0.1:{port}/MNT"), 5.0)))
        .unwrap();
    let error = eventually("refused", || {
        let s = rtk.status();
        (s.state == SourceState::Failed).then(|| s.error.unwrap())
    })
    .await;
    assert!(
        error.contains("no mountpoint /MNT") && error.contains("NEAR, FAR"),
        "{error}"
    );
    assert_eq!(v.link.corrections().sent().messages, 0);
}

#[tokio::test]
async fn an_ntrip_1_caster_is_told_where_the_fleet_is() {
    let v = vehicle_with(Some((473_977_420, 85_455_940))).await;
    let caster = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let port = caster.local_addr().unwrap().port();
    let rtk = RtkService::start(vehicles(&[&v]));
    rtk.configure(Some(&config(
        format!("ntrip://127.0.0.1:{port}/MNT?version=1"),
        5.0,
    )))
    .unwrap();
    let (mut sock, _) = caster.accept().await.unwrap();
    let mut head = Vec::new();
    let mut b = [0u8; 1];
    while !head.ends_with(b"\r\n\r\n") {
        sock.read_exact(&mut b).await.unwrap();
        head.push(b[0]);
    }
    let request = String::from_utf8(head).unwrap();
    assert!(request.starts_with("GET /MNT HTTP/1.0\r\n"), "{request}");
    assert!(!request.contains("Authorization"), "{request}");
    sock.write_all(b"ICY 200 OK\r\n").await.unwrap();
    sock.write_all(&frame_of(1077, 100)).await.unwrap();
    let mut line = Vec::new();
    while !line.ends_with(b"\r\n") {
        sock.read_exact(&mut b).await.unwrap();
        line.push(b[0]);
    }
    let gga = String::from_utf8(line).unwrap();
    assert!(gga.starts_with("$GPGGA,"), "{gga}");
    assert!(gga.contains(",4723.86452,N,00832.73564,E,1,"), "{gga}");
    eventually("streaming, the GGA position shown", || {
        let s = rtk.status();
        (s.state == SourceState::Streaming).then_some(s.gga_position?)
    })
    .await;
}

#[tokio::test]
async fn a_udp_source_reaches_two_vehicles_and_a_bad_crc_is_dropped() {
    let (a, b) = (vehicle().await, vehicle().await);
    let port = {
        let probe = UdpSocket::bind("127.0.0.1:0").await.unwrap();
        probe.local_addr().unwrap().port()
    };
    let rtk = RtkService::start(vehicles(&[&a, &b]));
    rtk.configure(Some(&config(format!("udp://127.0.0.1:{port}"), 5.0)))
        .unwrap();
    let tx = UdpSocket::bind("127.0.0.1:0").await.unwrap();
    let good = frame_of(1074, 200);
    let mut bad = good.clone();
    bad[40] ^= 1;
    // The service binds asynchronously: send until the good frame arrives.
    eventually("both vehicles got the frame", || {
        let _ = tx.try_send_to(&bad, ([127, 0, 0, 1], port).into());
        let _ = tx.try_send_to(&good, ([127, 0, 0, 1], port).into());
        let done = |v: &Vehicle| !v.received.lock().unwrap().is_empty();
        (done(&a) && done(&b)).then_some(())
    })
    .await;
    assert_eq!(a.received.lock().unwrap()[0], good);
    let s = rtk.status();
    assert!(s.crc_failures >= 1, "{s:?}");
    assert_eq!(s.vehicles.len(), 2);
    assert!(s.vehicles.iter().all(|v| v.messages >= 1));
}

#[tokio::test]
async fn relayed_frames_reach_the_vehicle_as_a_source_s_and_a_source_of_its_own_wins() {
    let v = vehicle().await;
    let rtk = RtkService::start(vehicles(&[&v]));
    rtk.relay_receiver("/skein/rtcm");
    let s = rtk.status();
    assert_eq!(s.source.as_deref(), Some("dds:/skein/rtcm"));
    assert_eq!(s.state, SourceState::Connecting, "{s:?}");
    assert_eq!(s.relay.as_ref().unwrap().role, RelayRole::Receiving);
    let base = GeoPoint::new(47.397_742, 8.545_594, 535.0);
    let frames = [frame_1005(3, base), frame_of(1074, 400)];
    let mut corrupt = frames[1].clone();
    corrupt[30] ^= 0x08;
    let mut tap = rtk.tap();
    for f in &frames {
        assert_eq!(rtk.relayed(f), Relayed::Delivered(1));
    }
    assert_eq!(rtk.relayed(&corrupt), Relayed::Malformed);
    assert_eq!(rtk.relayed(b"not rtcm"), Relayed::Malformed);
    eventually("both messages reassembled", || {
        (v.received.lock().unwrap().len() == 2).then_some(())
    })
    .await;
    assert_eq!(*v.received.lock().unwrap(), frames.to_vec());
    let s = rtk.status();
    assert_eq!(s.state, SourceState::Streaming, "{s:?}");
    assert_eq!((s.frames, s.crc_failures), (2, 1), "{s:?}");
    assert_eq!(s.base.unwrap().station_id, 3);
    assert_eq!(s.vehicles[0].messages, 2);
    assert!(s.vehicles[0].correction_age_s.is_some());
    let relay = s.relay.unwrap();
    assert_eq!((relay.received, relay.malformed), (4, 2), "{relay:?}");
    // Relayed frames are not tapped: an agent publishes nothing.
    assert!(tap.try_recv().is_err());

    // A source of its own: the relay is ignored, and its frames are tapped.
    let port = {
        let probe = UdpSocket::bind("127.0.0.1:0").await.unwrap();
        probe.local_addr().unwrap().port()
    };
    rtk.configure(Some(&config(format!("udp://127.0.0.1:{port}"), 5.0)))
        .unwrap();
    assert_eq!(rtk.relayed(&frames[1]), Relayed::Ignored);
    let s = rtk.status();
    assert_eq!(
        s.source.as_deref(),
        Some(format!("udp://127.0.0.1:{port}").as_str())
    );
    assert_eq!(s.relay.as_ref().unwrap().role, RelayRole::Ignoring);
    assert_eq!(s.relay.unwrap().ignored, 1);
    let tx = UdpSocket::bind("127.0.0.1:0").await.unwrap();
    let own = frame_of(1230, 10);
    let tapped = eventually("the source's frame tapped", || {
        let _ = tx.try_send_to(&own, ([127, 0, 0, 1], port).into());
        tap.try_recv().ok()
    })
    .await;
    assert_eq!(tapped.bytes, own);
    // Without it, the relay is the source again.
    rtk.configure(None).unwrap();
    let s = rtk.status();
    assert_eq!(s.source.as_deref(), Some("dds:/skein/rtcm"));
    assert_eq!(s.relay.unwrap().role, RelayRole::Receiving);
    assert_eq!(rtk.relayed(&frames[1]), Relayed::Delivered(1));
}
