//! Free local ports for the processes a test starts.

use std::net::{SocketAddr, TcpListener, UdpSocket};

/// A free TCP port on 127.0.0.1 (released before returning: a small race is possible).
pub fn free_tcp_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("free port")
}

/// `n` consecutive free UDP ports on 127.0.0.1 (checked by binding each).
pub fn free_udp_range(n: u16) -> u16 {
    for _ in 0..200 {
        let probe = UdpSocket::bind("127.0.0.1:0").expect("bind");
        let base = probe.local_addr().expect("addr").port();
        drop(probe);
        if base.checked_add(n).is_none() || base < 20_000 {
            continue;
        }
        let socks: Vec<_> = (0..n)
            .map(|i| UdpSocket::bind(SocketAddr::from(([127, 0, 0, 1], base + i))))
            .collect();
        if socks.iter().all(Result::is_ok) {
            return base;
        }
    }
    panic!("no {n} consecutive free UDP ports");
}
