//! The reader against sources on local TCP ports: NMEA over `tcp://` (a bad sentence
//! dropped and counted, the connection closed and reopened) and a scripted gpsd
//! (`gpsd://`: the `?WATCH` command asked, `TPV` reports read, a lost fix reported).
//! gpsd itself is driven end to end by `tests/e2e_swarm.rs`.

use skein_gnss::nmea0183::sentence;
use skein_gnss::{GnssReader, GnssState};
use std::time::{Duration, Instant};
use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpListener;

/// Polls `reader` until `done` holds, failing with the last state after `within`.
async fn until(
    reader: &GnssReader,
    within: Duration,
    done: impl Fn(&GnssState) -> bool,
) -> GnssState {
    let deadline = Instant::now() + within;
    loop {
        let s = reader.state();
        if done(&s) {
            return s;
        }
        assert!(Instant::now() < deadline, "not within {within:?}: {s:?}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

#[tokio::test]
async fn nmea_over_tcp_gives_the_fix_counts_bad_lines_and_reconnects() {
    let server = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let port = server.local_addr().unwrap().port();
    let reader = GnssReader::start(format!("tcp://127.0.0.1:{port}").parse().unwrap());
    let gga = sentence("GNGGA,120000.00,6010.27404,N,02456.74068,E,1,12,0.8,25.0,M,17.5,M,,");
    let (mut conn, _) = server.accept().await.unwrap();
    let text = format!("{gga}\r\n$GNGGA,120001.00,6010.27404,N*00\r\n$GPGSV,1,1,00*79\r\n");
    conn.write_all(text.as_bytes()).await.unwrap();
    let s = until(&reader, Duration::from_secs(10), |s| s.malformed == 1).await;
    let (fix, _) = s.last_fix.expect("a fix");
    assert_eq!((fix.lat_deg * 1e6).round(), 60_171_234.0, "{fix:?}");
    assert_eq!((fix.lon_deg * 1e6).round(), 24_945_678.0, "{fix:?}");
    assert_eq!(fix.alt_hae_m, Some(42.5));
    assert_eq!((s.reports, s.connects, s.connected), (1, 1, true));

    // The source closes: the reader says why and opens it again after its backoff.
    drop(conn);
    let s = until(&reader, Duration::from_secs(10), |s| !s.connected).await;
    assert!(s.error.as_deref().unwrap().contains("closed"), "{s:?}");
    let (mut conn, _) = server.accept().await.unwrap();
    let no_fix = sentence("GNRMC,120002.00,V,,,,,,,010126,,,N");
    conn.write_all(format!("{no_fix}\r\n").as_bytes())
        .await
        .unwrap();
    let s = until(&reader, Duration::from_secs(10), |s| {
        s.no_fix_since.is_some()
    })
    .await;
    assert_eq!((s.connects, s.reports, s.error.as_deref()), (2, 2, None));
    assert!(s.last_fix.is_some(), "the last fix is kept: {s:?}");
}

#[tokio::test]
async fn gpsd_is_asked_for_json_and_its_tpv_read() {
    let server = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let port = server.local_addr().unwrap().port();
    let reader = GnssReader::start(format!("gpsd://127.0.0.1:{port}").parse().unwrap());
    let (conn, _) = server.accept().await.unwrap();
    let (rx, mut tx) = conn.into_split();
    tx.write_all(
        b"{\"class\":\"VERSION\",\"release\":\"3.22\",\"proto_major\":3,\"proto_minor\":14}\n",
    )
    .await
    .unwrap();
    let mut asked = String::new();
    BufReader::new(rx).read_line(&mut asked).await.unwrap();
    assert_eq!(asked, "?WATCH={\"enable\":true,\"json\":true}\n");
    let tpv = r#"{"class":"TPV","device":"/dev/ttyACM0","mode":3,"lat":47.397742,"lon":8.545594,"altMSL":488.0,"geoidSep":47.4,"epx":3.0,"epy":4.0}"#;
    tx.write_all(format!("{tpv}\n{{\"class\":\"TPV\",\"mode\":\n").as_bytes())
        .await
        .unwrap();
    let s = until(&reader, Duration::from_secs(10), |s| s.malformed == 1).await;
    let (fix, _) = s.last_fix.expect("a fix");
    assert_eq!((fix.lat_deg, fix.lon_deg), (47.397742, 8.545594));
    assert_eq!((fix.alt_hae_m, fix.eph_m), (Some(535.4), Some(5.0)));
    tx.write_all(b"{\"class\":\"TPV\",\"device\":\"/dev/ttyACM0\",\"mode\":1}\n")
        .await
        .unwrap();
    let s = until(&reader, Duration::from_secs(10), |s| {
        s.no_fix_since.is_some()
    })
    .await;
    assert_eq!((s.reports, s.connects), (2, 1));
}

#[tokio::test]
async fn nmea_on_a_serial_port_gives_the_fix() {
    // The slave side of a pseudo-terminal pair is the port; the test writes on the master.
    let pty = nix::pty::openpty(None, None).unwrap();
    let path = nix::unistd::ttyname(&pty.slave).unwrap();
    let reader = GnssReader::start(format!("serial:{}:9600", path.display()).parse().unwrap());
    until(&reader, Duration::from_secs(10), |s| s.connected).await;
    let mut master = std::fs::File::from(pty.master);
    let rmc = sentence("GPRMC,120000.00,A,6010.27404,N,02456.74068,E,0.0,0.0,010126,,,A");
    std::io::Write::write_all(&mut master, format!("{rmc}\r\n").as_bytes()).unwrap();
    let s = until(&reader, Duration::from_secs(10), |s| s.last_fix.is_some()).await;
    let (fix, _) = s.last_fix.unwrap();
    assert_eq!((fix.lat_deg * 1e6).round(), 60_171_234.0, "{fix:?}");
    assert_eq!((fix.alt_hae_m, s.malformed), (None, 0));
    drop(pty.slave);
}
