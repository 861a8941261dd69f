//! When a datagram reached the simulated vehicle: the kernel's receive timestamp
//! (`SO_TIMESTAMP`, microseconds), not when the simulator's task got round to reading it.
//!
//! The simulator stands in for a PX4 on its own flight controller, whose MAVLink receiver
//! is never kept off its CPU by the companion computer's load. Embedded in a busy process
//! (`skein up --sim`, an agent on a loaded test machine), the simulator's receive task may
//! wake tens of milliseconds late; stamping a setpoint then would record a gap on the wire
//! that skein never opened (and a burst of tiny intervals after it). The kernel stamps each
//! datagram as it arrives on the socket, so the gaps, the setpoint intervals and the
//! offboard stream's age are those of the wire.
//!
//! `SO_TIMESTAMP` rather than `SO_TIMESTAMPNS`: a microsecond is far below anything the
//! stream's 20 ms intervals need, and qemu-user (the arm64 image's smoke test, Debian 12's
//! qemu 7.2) translates `SO_TIMESTAMP` but refuses `SO_TIMESTAMPNS` (`ENOPROTOOPT`). Where
//! the option is refused all the same, the simulator says so and stamps a datagram when it
//! reads it.

use nix::sys::socket::{
    ControlMessageOwned, MsgFlags, SockaddrStorage, recvmsg, setsockopt, sockopt,
};
use nix::sys::time::TimeVal;
use std::io::{self, IoSliceMut};
use std::net::{SocketAddr, SocketAddrV4, SocketAddrV6};
use std::os::fd::AsRawFd;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};
use tokio::io::Interest;
use tokio::net::UdpSocket;

/// Asks the kernel to stamp every datagram `socket` receives.
///
/// # Errors
/// The socket option was refused.
pub(crate) fn stamp_arrivals(socket: &std::net::UdpSocket) -> io::Result<()> {
    setsockopt(socket, sockopt::ReceiveTimestamp, &true).map_err(io::Error::from)
}

/// The next datagram of `socket` into `buf`: its length, sender, and arrival (the kernel's
/// stamp as an [`Instant`]; now if the datagram carries none).
///
/// # Errors
/// The receive failed (an ICMP error reported on the socket, for one).
pub(crate) async fn recv_stamped(
    socket: &UdpSocket,
    buf: &mut [u8],
) -> io::Result<(usize, SocketAddr, Instant)> {
    let fd = socket.as_raw_fd();
    loop {
        socket.readable().await?;
        let got = socket.try_io(Interest::READABLE, || {
            let mut iov = [IoSliceMut::new(buf)];
            let mut cmsg = nix::cmsg_space!(TimeVal);
            let msg = recvmsg::<SockaddrStorage>(fd, &mut iov, Some(&mut cmsg), MsgFlags::empty())
                .map_err(io::Error::from)?;
            // A control message that does not parse is no stamp: the read time stands in.
            let stamp = msg.cmsgs().ok().and_then(|mut c| {
                c.find_map(|c| match c {
                    ControlMessageOwned::ScmTimestamp(tv) => Some(tv),
                    _ => None,
                })
            });
            let from = msg
                .address
                .as_ref()
                .and_then(socket_addr)
                .ok_or_else(|| io::Error::other("a datagram without a sender address"))?;
            Ok((msg.bytes, from, stamp))
        });
        match got {
            Ok((n, from, stamp)) => return Ok((n, from, arrival(stamp))),
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => continue,
            Err(e) => return Err(e),
        }
    }
}

fn socket_addr(a: &SockaddrStorage) -> Option<SocketAddr> {
    if let Some(v4) = a.as_sockaddr_in() {
        return Some(SocketAddr::V4(SocketAddrV4::new(v4.ip(), v4.port())));
    }
    let v6 = a.as_sockaddr_in6()?;
    Some(SocketAddr::V6(SocketAddrV6::new(
        v6.ip(),
        v6.port(),
        v6.flowinfo(),
        v6.scope_id(),
    )))
}

/// The kernel's wall-clock stamp as an [`Instant`] (now without one, or for a stamp from
/// the future).
fn arrival(stamp: Option<TimeVal>) -> Instant {
    let Some(tv) = stamp else {
        return Instant::now();
    };
    let (now, wall) = clocks_now();
    let at = UNIX_EPOCH
        + Duration::from_secs(tv.tv_sec().max(0) as u64)
        + Duration::from_micros(tv.tv_usec().max(0) as u64);
    let age = wall.duration_since(at).unwrap_or_default();
    now.checked_sub(age).unwrap_or(now)
}

/// The monotonic and the wall clock read together: of up to three tries, the one whose
/// two monotonic reads bracket the wall-clock read closest (a thread preempted between
/// them would make every stamp look that much older).
fn clocks_now() -> (Instant, SystemTime) {
    let mut best: Option<(Duration, Instant, SystemTime)> = None;
    for _ in 0..3 {
        let a = Instant::now();
        let wall = SystemTime::now();
        let width = a.elapsed();
        if best.is_none_or(|(w, _, _)| width < w) {
            best = Some((width, a + width / 2, wall));
        }
        if width < Duration::from_micros(50) {
            break;
        }
    }
    let (_, now, wall) = best.expect("one try at least");
    (now, wall)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn a_datagram_read_late_carries_the_time_it_arrived() {
        let rx = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        stamp_arrivals(&rx).unwrap();
        rx.set_nonblocking(true).unwrap();
        let addr = rx.local_addr().unwrap();
        let rx = UdpSocket::from_std(rx).unwrap();
        let tx = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let mut buf = [0u8; 64];
        // The kernel turns receive stamping on for the whole machine a moment after the
        // first socket asks (a deferred static key); until then a datagram is stamped when
        // it is read. Wait for stamps that predate the read, as the simulator's first
        // datagrams do.
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            let sent = Instant::now();
            tx.send_to(b"warm-up", addr).unwrap();
            std::thread::sleep(Duration::from_millis(20));
            let (_, _, at) = recv_stamped(&rx, &mut buf).await.unwrap();
            if at.saturating_duration_since(sent) < Duration::from_millis(10) {
                break;
            }
            assert!(
                Instant::now() < deadline,
                "the kernel never stamped a datagram"
            );
        }
        let sent = Instant::now();
        tx.send_to(b"setpoint", addr).unwrap();
        // Read 150 ms later, as a starved task would.
        std::thread::sleep(Duration::from_millis(150));
        let (n, from, at) = recv_stamped(&rx, &mut buf).await.unwrap();
        assert_eq!(&buf[..n], b"setpoint");
        assert_eq!(from, tx.local_addr().unwrap());
        let late = at.saturating_duration_since(sent);
        assert!(
            late < Duration::from_millis(50),
            "stamped {late:?} after sending"
        );
    }
}
